// Desired trajectory (docs/MODEL.md section 3): sigma_DN(t) from
// sigma_DN_dot = G(sigma_DN) omega_DN_D(t), with
//   omega_DN_D(t) = bias + cos_amp cos(freq t) + sin_amp sin(freq t)   [rad/s]
// (the paper's omega_d(t) has bias 0, cos_amp = [0.02, 0, -0.03],
// sin_amp = [0, -0.01, 0], freq = 0.01 rad/s; all zero is a constant attitude).
// omega_DN_D and its derivative are analytic; sigma_DN is integrated with RK4
// inside the controller at its own rate, so a run is exactly reproducible.
#pragma once
#include <string>
#include <vector>

#include "sc_rt/types.hpp"

namespace sc_rt {

struct GuidanceParams {
  Vec3 sigma_d0 = Vec3(0.217, -0.109, -0.163);  //!< [-] sigma_DN at t = 0
  Vec3 omega_bias = Vec3::Zero();               //!< [rad/s]
  Vec3 omega_cos = Vec3(0.02, 0.0, -0.03);      //!< [rad/s]
  Vec3 omega_sin = Vec3(0.0, -0.01, 0.0);       //!< [rad/s]
  double omega_freq = 0.01;                     //!< [rad/s]
};

std::vector<std::string> validate(const GuidanceParams& p);

// omega_DN_D(t) [rad/s] and its time derivative [rad/s^2].
Vec3 omega_d(const GuidanceParams& p, double t);
Vec3 omega_d_dot(const GuidanceParams& p, double t);

// One RK4 step of sigma_dot = G(sigma) omega_d(t) from t to t + h, then the
// short-rotation set.
Vec3 guidance_rk4_step(const GuidanceParams& p, const Vec3& sigma, double t, double h);

// The desired attitude propagated along the controller's own time line.
class Guidance {
 public:
  explicit Guidance(const GuidanceParams& p, double max_step = 0.1);
  // sigma_DN at time t0, integrated from t = 0 (reproducible for any t0).
  void reset(double t0);
  // Advance to t >= current time with RK4 steps no longer than max_step.
  void advance(double t);
  double t() const { return t_; }
  const Vec3& sigma_DN() const { return sigma_; }
  const GuidanceParams& params() const { return p_; }

 private:
  GuidanceParams p_;
  double max_step_;
  double t_ = 0.0;
  Vec3 sigma_;
};

}  // namespace sc_rt
