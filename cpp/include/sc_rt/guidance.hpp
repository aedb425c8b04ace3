// Desired trajectory (docs/MODEL.md section 3 and "Other references"): the
// attitude sigma_DN(t) of the desired frame D, its rate omega_DN_D(t) in D and
// the rate's derivative, for one of four kinds of reference:
//
// Paper: sigma_DN from sigma_DN_dot = G(sigma_DN) omega_DN_D(t), with
//   omega_DN_D(t) = bias + cos_amp cos(freq t) + sin_amp sin(freq t)   [rad/s]
//   (the paper's omega_d(t) has bias 0, cos_amp = [0.02, 0, -0.03],
//   sin_amp = [0, -0.01, 0], freq = 0.01 rad/s). omega_DN_D and its
//   derivative are analytic; sigma_DN is integrated with RK4 inside the
//   controller at its own rate, so a run is exactly reproducible.
// Hold: sigma_DN = sigma_d0 for all t, omega_DN_D = 0.
// Slew: rest to rest from sigma_d0 to slew_target about the eigenaxis e of
//   the short rotation between them (angle Phi in [0, pi]), starting at
//   slew_start over slew_duration T, with the cycloidal angle profile
//   theta(s) = Phi (s - sin(2 pi s) / (2 pi)), s = (t - slew_start) / T:
//   rate Phi/T (1 - cos 2 pi s) (max 2 Phi/T at s = 1/2), acceleration
//   2 pi Phi/T^2 sin 2 pi s (max 2 pi Phi/T^2 at s = 1/4), both zero at the
//   ends. sigma_DN(t) = (tan(theta/4) e) composed with sigma_d0,
//   omega_DN_D = theta_dot e, omega_dot = theta_ddot e, all closed form.
// Table: samples (t_k, sigma_k, omega_k). Attitude by SLERP (constant rate
//   about the eigenaxis of the short rotation sigma_k -> sigma_k+1), rate
//   linear, omega_dot the slope of the linear rate on [t_k, t_k+1).
//   Outside [t_0, t_n-1] the reference rests at the end sample's attitude
//   (rate and acceleration zero).
// Hold, Slew and Table are closed forms of t (sigma_d); only Paper is
// integrated.
#pragma once
#include <string>
#include <cstdint>
#include <vector>

#include "sc_rt/types.hpp"

namespace sc_rt {

// = controller_config_t.GUIDANCE_*
enum class GuidanceKind : int { Paper = 0, Hold = 1, Slew = 2, Table = 3 };
const char* guidance_kind_name(GuidanceKind k);  //!< "paper", "hold", "slew", "table"

//! Most samples of a Table reference. controller_config_t carries them (56 B
//! each): 2000 keep the message near 113 kB, within the 212992-byte default
//! socket receive buffer of Linux, so the config survives LCM UDP multicast
//! (lcm-logger's copy, --config-channel); larger messages were lost.
constexpr int kGuidanceTableMax = 2000;

using MatX3 = Eigen::Matrix<double, Eigen::Dynamic, 3>;

struct GuidanceParams {
  GuidanceKind kind = GuidanceKind::Paper;
  //! [-] sigma_DN at t = 0 (Paper), the held attitude (Hold), the attitude
  //! before the slew (Slew); unused by Table
  Vec3 sigma_d0 = Vec3(0.217, -0.109, -0.163);
  // Paper
  Vec3 omega_bias = Vec3::Zero();               //!< [rad/s]
  Vec3 omega_cos = Vec3(0.02, 0.0, -0.03);      //!< [rad/s]
  Vec3 omega_sin = Vec3(0.0, -0.01, 0.0);       //!< [rad/s]
  double omega_freq = 0.01;                     //!< [rad/s]
  // Slew
  Vec3 slew_target = Vec3::Zero();  //!< [-] sigma_DN after the slew
  double slew_start = 0.0;          //!< [s] the slew starts (rest before)
  double slew_duration = 0.0;       //!< [s] > 0 for a Slew
  // Table: n = 2..kGuidanceTableMax samples
  Eigen::VectorXd table_t;  //!< [s] strictly increasing
  MatX3 table_sigma;        //!< [-] sigma_DN(t_k), |sigma| <= 1 (n x 3)
  MatX3 table_omega;        //!< [rad/s] omega_DN_D(t_k) (n x 3)
};

std::vector<std::string> validate(const GuidanceParams& p);

// omega_DN_D(t) [rad/s] and its time derivative [rad/s^2].
Vec3 omega_d(const GuidanceParams& p, double t);
Vec3 omega_d_dot(const GuidanceParams& p, double t);

// True for the Paper kind (sigma_DN integrated), false for the closed forms.
bool guidance_integrated(const GuidanceParams& p);
// sigma_DN(t) of a closed-form kind (Hold, Slew, Table), short set;
// std::invalid_argument for Paper (integrated: use Guidance).
Vec3 sigma_d(const GuidanceParams& p, double t);
// Slew: the eigenaxis e (zero when the target equals the start) and the
// angle Phi [rad] in [0, pi] of the short rotation from sigma_d0 to slew_target.
Vec3 slew_axis(const GuidanceParams& p);
double slew_angle(const GuidanceParams& p);

// One RK4 step of sigma_dot = G(sigma) omega_d(t) from t to t + h, then the
// short-rotation set.
Vec3 guidance_rk4_step(const GuidanceParams& p, const Vec3& sigma, double t, double h);

// The desired attitude propagated along the controller's own time line.
class Guidance {
 public:
  explicit Guidance(const GuidanceParams& p, double max_step = 0.1);
  // sigma_DN at time t0: integrated on from the current time when t0 is at
  // or after it (O(t0 - t()), whatever t0 is), else from t = 0 (a new time
  // line); a closed-form kind evaluates sigma_d(t0).
  void reset(double t0);
  // Advance to t >= current time with RK4 steps no longer than max_step
  // (a closed-form kind: sigma_d(t)).
  void advance(double t);
  double t() const { return t_; }
  const Vec3& sigma_DN() const { return sigma_; }
  const GuidanceParams& params() const { return p_; }
  //! RK4 steps taken since construction (the work of the integrated kind;
  //! tests bound a re-engagement's cost with it, not with wall time).
  std::uint64_t rk4_steps() const { return rk4_steps_; }

 private:
  GuidanceParams p_;
  double max_step_;
  double t_ = 0.0;
  Vec3 sigma_;
  std::uint64_t rk4_steps_ = 0;
};

}  // namespace sc_rt
