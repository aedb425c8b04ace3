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
//
// Bounded work whatever the times (docs/CORE.md, "The time contract"): one
// call of Guidance moves the Paper reference along its time line with at
// most kGuidanceMaxCatchUp RK4 steps; a longer span (a late joiner, a
// re-engagement after a gap, a step back) evaluates sigma_DN(t) from the
// definition instead: with a constant rate (freq = 0, or no cos/sin
// amplitude) in closed form; else from the monodromy of the periodic rate,
// sigma_DN(k P + tau) = Psi(tau) M^k sigma_d0 (P = 2 pi / |freq|, M = Psi(P),
// Psi the rotation from t = 0), with Psi tabulated once over one period
// (kGuidancePeriodStepsMax RK4 steps at most) and at most
// guidance_period_table(p).stride RK4 steps from the nearest anchor.
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

//! Most RK4 steps (of at most max_step) one Guidance call integrates along
//! its time line; a longer span evaluates the reference at the new time from
//! its definition (Guidance::seek). Normal steps take one.
constexpr int kGuidanceMaxCatchUp = 64;
//! Most RK4 steps of the Paper reference's period table (built once, at the
//! first seek or prepare()): validate() refuses a periodic rate whose period
//! needs more (the rate's bound over its frequency beyond ~1,600).
constexpr long long kGuidancePeriodStepsMax = 1LL << 20;
//! Most anchors of the period table (preallocated at construction).
constexpr int kGuidanceTableAnchorsMax = 4096;
//! The period table's step: at most this many radians of the rate's bound
//! |bias| + |cos_amp| + |sin_amp| (or of |freq|) per RK4 step (error per
//! period ~3e-13 for the paper's reference).
constexpr double kGuidanceTableStepAngle = 0.01;

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

//! How the Paper reference is evaluated far from its time line: kind
//! Constant (omega_DN_D constant: closed form), Periodic (a table over one
//! period P of n_steps RK4 steps of h = P / n_steps, an anchor every stride
//! steps) or ClosedForm (hold, slew, table: sigma_d).
struct GuidancePeriodTable {
  enum Kind { ClosedForm = 0, Constant = 1, Periodic = 2 } kind = ClosedForm;
  Vec3 omega = Vec3::Zero();  //!< [rad/s] the constant rate (Constant)
  double period = 0.0;        //!< [s] P = 2 pi / |freq| (Periodic)
  long long n_steps = 0;      //!< RK4 steps over one period (Periodic)
  int stride = 0;             //!< RK4 steps between anchors (Periodic)
  int anchors = 0;            //!< anchors after t = 0: n_steps / stride (Periodic)
  double h = 0.0;             //!< [s] the table's RK4 step, P / n_steps (Periodic)
};
GuidancePeriodTable guidance_period_table(const GuidanceParams& p);

// The desired attitude propagated along the controller's own time line.
// Every call costs at most max(kGuidanceMaxCatchUp, table stride + 1) RK4 steps,
// plus, once, the period table's n_steps (prepare() builds it ahead).
class Guidance {
 public:
  explicit Guidance(const GuidanceParams& p, double max_step = 0.1);
  // sigma_DN at time t0: continued from the current time when t0 is at or
  // after it, else from sigma_d0 at t = 0 (a new time line); either way by
  // advance(t0). A closed-form kind evaluates sigma_d(t0).
  void reset(double t0);
  // Advance to t >= current time: RK4 steps no longer than max_step when
  // that takes at most kGuidanceMaxCatchUp of them, else seek(t). A
  // closed-form kind: sigma_d(t). Earlier t: nothing.
  void advance(double t);
  // sigma_DN(t) from the reference's definition at any t (the period table
  // or the closed form), the time line moved to t. Bounded work.
  void seek(double t);
  // Build the period table now (else at the first seek): a step then never
  // pays for it. Idempotent; no allocation (the anchors are preallocated).
  void prepare();
  double t() const { return t_; }
  const Vec3& sigma_DN() const { return sigma_; }
  const GuidanceParams& params() const { return p_; }
  const GuidancePeriodTable& period_table() const { return table_; }
  //! RK4 steps taken since construction, the period table's included (the
  //! work of the integrated kind; tests bound a step's cost with it, not
  //! with wall time).
  std::uint64_t rk4_steps() const { return rk4_steps_; }
  //! seek() calls since construction (advances too long for the time line).
  std::uint64_t seeks() const { return seeks_; }
  bool prepared() const { return built_; }

 private:
  void integrate(double t, int n);  // n RK4 steps along the time line to t
  Vec3 periodic_at(double t);       // Periodic: sigma_DN(t) from the table
  GuidancePeriodTable table_;
  GuidanceParams p_;
  double max_step_;
  double t_ = 0.0;
  Vec3 sigma_;
  std::vector<Vec3> anchors_;  //!< Psi(j stride h) as MRPs, j = 0..anchors
  bool built_ = false;
  std::uint64_t rk4_steps_ = 0;
  std::uint64_t seeks_ = 0;
};

}  // namespace sc_rt
