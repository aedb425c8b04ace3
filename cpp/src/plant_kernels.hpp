// The plant's scalar kernels (inv3, Rhs, WheelMap, dist3), shared by the
// plant with the paper's wheels (plant.cpp) and with torque-commanded wheels
// (torque_plant.cpp). Internal to the core: not a public header.
#pragma once
#include <cmath>

#include "sc_rt/geomag.hpp"
#include "sc_rt/orbit.hpp"
#include "sc_rt/plant.hpp"

namespace sc_rt::detail {

// ---------------------------------------------------------------------------
// The hot path, written as plain scalar expressions in EXACTLY the order of
// the Python reference (sc_rt/model/kernels.py: inv3, make_rhs, make_wheel_map,
// make_disturbance; sc_rt/model/plant.py: rk4_step; sc_rt/model/actuators.py: sat4, accel4), so that
// both engines give bit-identical results (IEEE double, -ffp-contract=off,
// the same glibc cos/expm1). Python evaluates a + b + c as (a + b) + c, as
// C++ does; no Eigen products here (their summation order is Eigen's own).
// Changing an expression here means changing its Python twin the same way
// (tests/test_plant.py holds the two to np.array_equal).
// ---------------------------------------------------------------------------

// Inverse of a 3x3 matrix by cofactors: inv = adj(M) / det(M) (kernels.py inv3).
inline void inv3(const Mat3& M, double I[3][3]) {
  const double a = M(0, 0), b = M(0, 1), c = M(0, 2);
  const double d = M(1, 0), e = M(1, 1), f = M(1, 2);
  const double g = M(2, 0), h = M(2, 1), i = M(2, 2);
  const double A = e * i - f * h;
  const double B = f * g - d * i;
  const double C = d * h - e * g;
  const double det = a * A + b * B + c * C;
  I[0][0] = A / det;
  I[0][1] = (c * h - b * i) / det;
  I[0][2] = (b * f - c * e) / det;
  I[1][0] = B / det;
  I[1][1] = (a * i - c * g) / det;
  I[1][2] = (c * d - a * f) / det;
  I[2][0] = C / det;
  I[2][1] = (b * g - a * h) / det;
  I[2][2] = (a * e - b * d) / det;
}

// tau_B = m_B x (C_BN(sigma) B_N) [N m] of mb = (m_B [A m^2], B_N [T])
// (sc_rt/model/magnetic.py mag_torque): magnetic_torque(m_B, B_B) of
// magnetorquer.hpp written out on scalars (Eigen's cross may vectorise),
// B_B = C_BN(sigma) B_N by rotate_to_B (orbit.hpp), as gg_orbit_torque.
inline void mag_torque(const double mb[6], double s1, double s2, double s3, double out[3]) {
  const double m1 = mb[0], m2 = mb[1], m3 = mb[2];
  double b[3];
  rotate_to_B(s1, s2, s3, mb[3], mb[4], mb[5], b);
  const double b1 = b[0], b2 = b[1], b3 = b[2];
  out[0] = m2 * b3 - m3 * b2;
  out[1] = m3 * b1 - m1 * b3;
  out[2] = m1 * b2 - m2 * b1;
}

// One right-hand side of (1),(2),(7) (kernels.py make_rhs): J, its inverse and
// k = 3 w0^2 as plain doubles.
struct Rhs {
  double J[3][3];
  double I[3][3];
  double k;
  Rhs(const Mat3& Jm, double w0) : Rhs(Jm, Jm, w0) {}
  // H and u_g with J, omega_dot solved with M (torque-commanded wheels: M = J -
  // Cbar diag(Jw) Cbar', torque_plant.cpp; torque_plant.py TorquePlant's make_rhs(J, inv3(M), k))
  Rhs(const Mat3& Jm, const Mat3& Mm, double w0) : k(3.0 * w0 * w0) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) J[r][c] = Jm(r, c);
    inv3(Mm, I);
  }
  // out = (sigma_dot (3), omega_dot (3)) of sigma s, rate w, wheel momentum
  // hw = Cbar Jw Omega_w, wheel torque tw = Cbar Jw Omega_w_dot, disturbance d;
  // g: the orbit's gravity-gradient terms at the stage's time (orbit_gg_terms),
  // null: the constant-rate form of (5) with k.
  // mb: the body dipole m_B [A m^2] and the field B_N [T] at the stage's time
  // (MagField), null: no magnetic torque.
  void operator()(const double s[3], const double w[3], const double hw[3], const double tw[3],
                  const double d[3], double out[6], const double* g = nullptr,
                  const double* mb = nullptr) const {
    const double s1 = s[0], s2 = s[1], s3 = s[2], w1 = w[0], w2 = w[1], w3 = w[2];
    const double ss = s1 * s1 + s2 * s2 + s3 * s3;
    const double c = 0.25 * (1.0 - ss);
    const double e = 0.5 * (s1 * w1 + s2 * w2 + s3 * w3);
    const double H1 = J[0][0] * w1 + J[0][1] * w2 + J[0][2] * w3 + hw[0];
    const double H2 = J[1][0] * w1 + J[1][1] * w2 + J[1][2] * w3 + hw[1];
    const double H3 = J[2][0] * w1 + J[2][1] * w2 + J[2][2] * w3 + hw[2];
    double T1 = (w3 * H2 - w2 * H3) - tw[0] + d[0];
    double T2 = (w1 * H3 - w3 * H1) - tw[1] + d[1];
    double T3 = (w2 * H1 - w1 * H2) - tw[2] + d[2];
    if (g != nullptr) {
      // the orbit's u_g = 3 mu / r^3 (n_B x J n_B), n_B = C_BN(sigma) r_N / r (orbit.hpp)
      double u[3];
      gg_orbit_torque(J, s1, s2, s3, g, u);
      T1 += u[0];
      T2 += u[1];
      T3 += u[2];
    } else if (k != 0.0) {
      // (5),(6),(10): u_g = 3 w0^2 R3^ J R3, R3 = R(sigma) e3
      const double q = 1.0 / ((1.0 + ss) * (1.0 + ss));
      const double m4 = 4.0 * (1.0 - ss);
      const double r1 = (8.0 * s1 * s3 - m4 * s2) * q;
      const double r2 = (8.0 * s2 * s3 + m4 * s1) * q;
      const double r3 = 1.0 + 8.0 * (s3 * s3 - ss) * q;
      const double g1 = J[0][0] * r1 + J[0][1] * r2 + J[0][2] * r3;
      const double g2 = J[1][0] * r1 + J[1][1] * r2 + J[1][2] * r3;
      const double g3 = J[2][0] * r1 + J[2][1] * r2 + J[2][2] * r3;
      T1 += k * (r2 * g3 - r3 * g2);
      T2 += k * (r3 * g1 - r1 * g3);
      T3 += k * (r1 * g2 - r2 * g1);
    }
    if (mb != nullptr) {
      // the magnetic torque m_B x C_BN(sigma) B_N (magnetic.py mag_torque)
      double u[3];
      mag_torque(mb, s1, s2, s3, u);
      T1 += u[0];
      T2 += u[1];
      T3 += u[2];
    }
    out[0] = c * w1 + 0.5 * (s2 * w3 - s3 * w2) + e * s1;
    out[1] = c * w2 + 0.5 * (s3 * w1 - s1 * w3) + e * s2;
    out[2] = c * w3 + 0.5 * (s1 * w2 - s2 * w1) + e * s3;
    out[3] = I[0][0] * T1 + I[0][1] * T2 + I[0][2] * T3;
    out[4] = I[1][0] * T1 + I[1][1] * T2 + I[1][2] * T3;
    out[5] = I[2][0] * T1 + I[2][1] * T2 + I[2][2] * T3;
  }
};

// Cbar Jw v (kernels.py make_wheel_map): of wheel speeds the wheels' momentum
// in B, of wheel accelerations their reaction torque with its sign flipped.
struct WheelMap {
  double C[3][4];
  explicit WheelMap(const PlantParams& p) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) C[r][c] = p.Cbar(r, c) * p.Jw(c);
  }
  void operator()(const double v[4], double out[3]) const {
    for (int r = 0; r < 3; ++r)
      out[r] = C[r][0] * v[0] + C[r][1] * v[1] + C[r][2] * v[2] + C[r][3] * v[3];
  }
};

// d(t) (kernels.py make_disturbance): the bias alone when every amplitude is 0.
inline void dist3(const PlantParams& p, double t, double out[3]) {
  if (p.dist_amp(0) == 0.0 && p.dist_amp(1) == 0.0 && p.dist_amp(2) == 0.0) {
    for (int i = 0; i < 3; ++i) out[i] = p.dist_bias(i);
    return;
  }
  for (int i = 0; i < 3; ++i)
    out[i] = p.dist_bias(i) + p.dist_amp(i) * std::cos(p.dist_freq(i) * t);
}

// The orbit's gravity-gradient terms at t into g, or null without an orbit.
struct OrbitGG {
  const OrbitParams* o;
  OrbitRates k;
  explicit OrbitGG(const PlantParams& p)
      : o(p.orbit.enabled && p.orbit_gravity_gradient ? &p.orbit : nullptr), k(orbit_rates(p.orbit)) {}
  const double* operator()(double t, double g[4]) const {
    if (o == nullptr) return nullptr;
    orbit_gg_terms(*o, k, t, g);
    return g;
  }
};

// The body dipole over a step (magnetic.py held_dipole): the residual dipole
// plus the magnetorquers' dipole_B (null: none) into m; false when it is
// exactly zero (no magnetic term at all: bitwise the plant without one).
inline bool held_dipole(const PlantParams& p, const Vec3* dipole_B, double m[3]) {
  for (int i = 0; i < 3; ++i) m[i] = p.residual_dipole(i);
  if (dipole_B != nullptr)
    for (int i = 0; i < 3; ++i) m[i] = m[i] + (*dipole_B)(i);
  return !(m[0] == 0.0 && m[1] == 0.0 && m[2] == 0.0);
}

// (m_B, B_N(t) [T]) for Rhs (magnetic.py make_field_N, _stage_mb): the field
// at the orbit's position and GMST, nT to T; null without a dipole or a field.
struct MagField {
  const PlantParams& p;
  OrbitRates k;
  const double* m;  // the held dipole, null: none
  MagField(const PlantParams& pp, const double* held)
      : p(pp), k(orbit_rates(pp.orbit)), m(pp.field && held != nullptr ? held : nullptr) {}
  const double* operator()(double t, double mb[6]) const {
    if (m == nullptr) return nullptr;
    double r[3];
    orbit_position(p.orbit, k, t, r);
    const Vec3 B = p.field->B_eci(Vec3(r[0], r[1], r[2]), p.orbit.jd_epoch, t);  // [nT]
    for (int i = 0; i < 3; ++i) mb[i] = m[i];
    for (int i = 0; i < 3; ++i) mb[3 + i] = B(i) * 1e-9;
    return mb;
  }
};

}  // namespace sc_rt::detail
