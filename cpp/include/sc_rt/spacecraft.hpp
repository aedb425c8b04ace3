// Spacecraft parameters the controller knows (J0 only, never dJ (12)) and the
// quantities derived from them once: B and B+ of (21).
#pragma once
#include <limits>
#include <string>
#include <vector>

#include "sc_rt/types.hpp"

namespace sc_rt {

struct SpacecraftParams {
  Mat3 J0 = (Mat3() << 10, 0, 0, 0, 15, 0, 0, 0, 20).finished();  //!< [kg m^2] nominal inertia
  Mat34 Cbar = (Mat34() << -0.9992, -0.0300, -0.0256, -0.6086,
                            -0.0394, 0.7455, 0.6653, 0.7913,
                            0.0009, -0.6658, 0.7461, 0.0469).finished();  //!< [-] wheel axes in B
  Vec4 Jw = Vec4::Constant(0.338);    //!< [kg m^2] wheel spin inertias
  Vec4 umin = Vec4::Constant(-7.0);   //!< [rad/s^2] lower wheel acceleration limits
  Vec4 umax = Vec4::Constant(10.0);   //!< [rad/s^2] upper wheel acceleration limits
  //! the wheels take a motor torque [N m] (umin/umax then in N m), not an acceleration
  bool wheel_torque_command = false;
  //! [rad/s] the wheels' speed limits (inf: none), for the law (LawModel)
  Vec4 wheel_speed_max = Vec4::Constant(std::numeric_limits<double>::infinity());
  double w0 = 0.0011;                 //!< [rad/s] orbit rate (not given by the paper)
  double pinv_damping = 0.0;          //!< [-] damping of B+ (0: exact pseudo-inverse)
};

// Every problem with the parameters, each naming the bad value; empty if valid.
std::vector<std::string> validate(const SpacecraftParams& p);

// Validated parameters plus B = -J0^-1 Cbar Jw (21) and
// B+ = B' (B B' + damping^2 I)^-1, computed once. Throws std::invalid_argument
// listing every problem.
class SpacecraftModel {
 public:
  explicit SpacecraftModel(const SpacecraftParams& p);
  const SpacecraftParams& params() const { return p_; }
  const Mat34& B() const { return B_; }
  const Mat43& B_pinv() const { return Bp_; }
  const Mat3& J0_inverse() const { return J0inv_; }
  // Saturation of (15): min(max(u, umin), umax) per wheel.
  Vec4 saturate(const Vec4& u) const;

 private:
  SpacecraftParams p_;
  Mat3 J0inv_;
  Mat34 B_;
  Mat43 Bp_;
};

// Gravity-gradient torque (5),(6): u_g = 3 w0^2 R3^ J R3, R3 = R(sigma) e3.
Vec3 gravity_gradient(const Mat3& J, const Vec3& sigma_BN, double w0);

}  // namespace sc_rt
