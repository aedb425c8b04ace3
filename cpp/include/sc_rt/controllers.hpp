// One small interface, four laws (docs/MODEL.md section 7):
//   DSC+PPC: (36), (37), corrected (41), anti-windup (42), observer (22)
//   DSC    : the same with e1 = x1, r = I and no chi_dot term
//   PD     : uc = -B+ (beta1 x1 + beta2 x2)
//   RFT    : adaptive boundary-layer sliding mode (docs/CORE.md)
// A controller is pure: it holds its states, takes a Measurement with its
// time and returns a Command. No clocks, no I/O, no allocation in step().
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "sc_rt/guidance.hpp"
#include "sc_rt/neso.hpp"
#include "sc_rt/ppc.hpp"
#include "sc_rt/spacecraft.hpp"
#include "sc_rt/types.hpp"

namespace sc_rt {

enum class Law : int { DscPpc = 0, Dsc = 1, Pd = 2, Rft = 3 };
const char* law_name(Law law);

// Modes and flags share their values with sc_rt_lcm::wheel_cmd_t.
enum Mode : int { MODE_INIT = 0, MODE_NORMAL = 1, MODE_SAFE = 2 };
enum Flags : int {
  FLAG_BOUND_X = 1, FLAG_BOUND_Y = 2, FLAG_BOUND_Z = 4,
  FLAG_SAT_1 = 8, FLAG_SAT_2 = 16, FLAG_SAT_3 = 32, FLAG_SAT_4 = 64,
  FLAG_INVALID_STATE = 128, FLAG_STALE_STATE = 256, FLAG_TIME_NOT_ADVANCING = 512,
};

struct DscGains {
  double k1 = 0.1;   //!< [1/s] (36)
  double k2 = 4.0;   //!< [1/s] (41)
  double k3 = 0.01;  //!< [-] (41) anti-windup coupling
  double k4 = 22.0;  //!< [1/s] (42)
  double k6 = 1.0;   //!< [-] Theorem 1 only
  double tau = 0.1;  //!< [s] filter time constant (37)
};

// Designed by sc_rt.design.default_pd_design (`sc-rt design`, docs/DESIGN.md):
// critically damped, 2 % settling time ln(50)/min(gamma) = 48.9 s of the
// paper's slowest prescribed envelope; beta1 = 4 wn^2, beta2 = 2 wn, 4 digits.
struct PdGains {
  double beta1 = 0.05693;  //!< [1/s^2] on sigma_BD
  double beta2 = 0.2386;   //!< [1/s] on omega_BD_B
};

struct RftGains {
  double c = 0.2;      //!< [1/s] sliding surface s = x2 + c x1
  double k = 0.4;      //!< [1/s] linear reaching gain
  double gain = 0.5;   //!< [1/s] adaptation gain of rho_hat_dot = gain |s| - leak rho_hat
  double leak = 0.01;  //!< [1/s] leakage (sigma-modification)
  double phi = 1e-2;   //!< [rad/s] boundary layer width (wider than s moves in one period)
  double rho0 = 0.0;   //!< [rad/s^2] rho_hat(t0)
};

struct SafetyLimits {
  double max_rate = 10.0;          //!< [rad/s] a measured |omega| beyond this is rejected
  double max_wheel_speed = 1e4;    //!< [rad/s] a measured |wheel speed| beyond this is rejected
  double stale_periods = 5.0;      //!< periods without a fresh state before SAFE (shells)
};

struct ControllerConfig {
  Law law = Law::DscPpc;
  double control_rate_hz = 10.0;  //!< [Hz]
  SpacecraftParams spacecraft;
  GuidanceParams guidance;
  PpcParams ppc;
  NesoParams neso;
  DscGains dsc;
  PdGains pd;
  RftGains rft;
  SafetyLimits safety;
};

// Every problem of the configuration, each naming the key and the value.
std::vector<std::string> validate(const ControllerConfig& c);

struct Measurement {
  double t = 0.0;                     //!< [s]
  Vec3 sigma_BN = Vec3::Zero();       //!< [-]
  Vec3 omega_BN_B = Vec3::Zero();     //!< [rad/s]
  Vec4 wheel_speed = Vec4::Zero();    //!< [rad/s]
};

struct Command {
  double t = 0.0;                  //!< [s] time of the measurement used
  Vec4 u_cmd = Vec4::Zero();       //!< [rad/s^2] before saturation
  Vec4 u_sat = Vec4::Zero();       //!< [rad/s^2] after saturation (15)
  int mode = MODE_INIT;
  int flags = 0;
  Vec3 sigma_DN = Vec3::Zero();    //!< desired attitude
  Vec3 sigma_BD = Vec3::Zero();    //!< x1 (8)
  Vec3 omega_BD_B = Vec3::Zero();  //!< [rad/s] x2 (11)
  Vec3 e1 = Vec3::Zero();          //!< (36); x1 for laws without PPC
  Vec3 e2 = Vec3::Zero();          //!< [rad/s] (27); s for RFT, x2 for PD
  Vec3 z1 = Vec3::Zero();          //!< [rad/s] observer (22)
  Vec3 z2 = Vec3::Zero();          //!< [rad/s^2] observer (22)
  Vec3 chi = Vec3::Zero();         //!< envelope (29)
  Vec3 lam = Vec3::Zero();         //!< x1 / chi after clamping
  Vec3 x2d = Vec3::Zero();         //!< [rad/s] filtered virtual control (37)
  Vec4 vs = Vec4::Zero();          //!< anti-windup state (42)
  double rho_hat = 0.0;            //!< [rad/s^2] RFT adaptive gain
};

// Tracking errors (8)-(11) and the model terms of (21) for one measurement.
struct TrackingErrors {
  Vec3 sigma_BD;     //!< x1, short rotation
  Vec3 omega_BD_B;   //!< [rad/s] x2 = omega - R(x1) omega_d
  Mat3 R_BD;         //!< R(x1) (10)
  Vec3 omega_DN_B;   //!< [rad/s] R(x1) omega_d
  Vec3 A;            //!< [rad/s^2] A of (21)
  Vec3 u_g0;         //!< [N m] nominal gravity gradient
};
TrackingErrors tracking_errors(const SpacecraftModel& sc, const Measurement& m,
                               const Vec3& sigma_DN, const Vec3& omega_DN_D,
                               const Vec3& omega_dot_DN_D);

// True when every field is finite and within the safety limits.
bool measurement_valid(const Measurement& m, const SafetyLimits& lim);

class Controller {
 public:
  explicit Controller(const ControllerConfig& c);
  virtual ~Controller() = default;
  Controller(const Controller&) = default;

  // Engage at m.t: guidance at t0, every internal state from the measurement
  // (or the paper's initial values). A reset mid-run equals a fresh start.
  void reset(const Measurement& m);
  // One control step at m.t >= the previous step's time. An invalid
  // measurement gives a SAFE zero command and re-engages at the next valid one.
  Command step(const Measurement& m);
  // Zero command in SAFE mode (for a shell whose input went stale); the next
  // valid step re-engages the law from its measurement.
  Command safe_command(double t, int flags);

  Law law() const { return cfg_.law; }
  const ControllerConfig& config() const { return cfg_; }
  const SpacecraftModel& model() const { return model_; }
  double t0() const { return t0_; }

  static std::unique_ptr<Controller> create(const ControllerConfig& c);

 protected:
  // Law hooks. e: errors at this step; dt: time since the previous step
  // (0 at engagement); out: fill u_cmd and the law's telemetry.
  virtual void law_reset(const TrackingErrors& e, const Measurement& m) = 0;
  // ppc: the transform of x1 at this step (computed once, for every law).
  virtual void law_step(const TrackingErrors& e, const PpcResult& ppc, double dt, Command& out) = 0;
  virtual void law_after(const Command& out) { (void)out; }

  ControllerConfig cfg_;
  SpacecraftModel model_;
  Guidance guidance_;
  double t0_ = 0.0;
  double t_prev_ = 0.0;
  bool engaged_ = false;
  bool first_ = true;
  Vec4 u_sat_prev_ = Vec4::Zero();  //!< held over the current period (ZOH)

 private:
  TrackingErrors errors_at(const Measurement& m);
  // Guidance to m.t, errors, the PPC transform, and their telemetry in out.
  void observe(const Measurement& m, Command& out, TrackingErrors& e, PpcResult& ppc);
};

}  // namespace sc_rt
