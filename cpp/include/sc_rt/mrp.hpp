// Modified Rodrigues parameters (docs/MODEL.md sections 1 and 3).
//
// Convention: sigma_BN is the attitude of B relative to N; R(sigma_BN) is the
// direction cosine matrix [BN] that maps N components to B components.
#pragma once
#include "sc_rt/types.hpp"

namespace sc_rt {

// x^ : the skew matrix with skew(x) y = x cross y.
Mat3 skew(const Vec3& x);

// G(sigma) of the kinematics (1),(2): sigma_dot = G(sigma) omega,
// G = 1/4 [ (1 - s's) I3 + 2 s^ + 2 s s' ].
Mat3 mrp_G(const Vec3& sigma);

// Inverse of G: G' G = ((1 + s's)/4)^2 I3, so G^-1 = 16 / (1 + s's)^2 G'.
Mat3 mrp_G_inverse(const Vec3& sigma);

// Direction cosine matrix R(sigma) of (10):
// R = I3 + [8 (s^)^2 - 4 (1 - s's) s^] / (1 + s's)^2.
Mat3 mrp_to_dcm(const Vec3& sigma);

// The shadow set -sigma / |sigma|^2 (same attitude). sigma must not be 0.
Vec3 mrp_shadow(const Vec3& sigma);

// The short-rotation representative: the shadow set when |sigma| > 1.
Vec3 mrp_short(const Vec3& sigma);

// Relative attitude sigma_BD from sigma_BN and sigma_DN, composition (8),
// mapped to the short rotation. Degenerate (a 360 deg relative rotation,
// denominator 0) only when both arguments are far from the short set.
Vec3 mrp_subtract(const Vec3& sigma_BN, const Vec3& sigma_DN);

}  // namespace sc_rt
