// The common controller (docs/CORE.md, docs/LAWS.md): guidance, tracking
// errors, the PPC transform, saturation, validity and SAFE mode, around one
// control law behind the interface of sc_rt/law.hpp, found by name in the
// law registry (sc_rt/law_registry.hpp). The built-in laws (docs/MODEL.md
// section 7) live in cpp/src/law_*.cpp; plugins are loaded at run time.
// A controller is pure: it holds its states, takes a Measurement with its
// time and returns a Command. No clocks, no I/O, no allocation in step().
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "sc_rt/guidance.hpp"
#include "sc_rt/law.hpp"
#include "sc_rt/law_registry.hpp"
#include "sc_rt/magnetic_control.hpp"
#include "sc_rt/neso.hpp"
#include "sc_rt/ppc.hpp"
#include "sc_rt/spacecraft.hpp"
#include "sc_rt/types.hpp"

namespace sc_rt {

// Modes and flags share their values with sc_rt_lcm::wheel_cmd_t.
enum Mode : int { MODE_INIT = 0, MODE_NORMAL = 1, MODE_SAFE = 2 };
enum Flags : int {
  FLAG_BOUND_X = 1, FLAG_BOUND_Y = 2, FLAG_BOUND_Z = 4,
  FLAG_SAT_1 = 8, FLAG_SAT_2 = 16, FLAG_SAT_3 = 32, FLAG_SAT_4 = 64,
  FLAG_INVALID_STATE = 128, FLAG_STALE_STATE = 256, FLAG_TIME_NOT_ADVANCING = 512,
  FLAG_LAW_INVALID = 1024,  //!< the law returned a non-finite command or threw: SAFE
  //! bit 12 (after mekf.hpp's FLAG_NAV_DEGRADED = 2048): the state's time
  //! stamp went back, or ahead by more than kMaxDtPeriods periods, of the
  //! engaged controller's previous step: SAFE, re-engaged at the next valid state
  FLAG_TIME_JUMP = 4096,
  //! bit 13: the detumble mode (B-dot, magnetic_control.hpp) switched at this
  //! step (Detumble <-> Attitude; the record's detumble_mode says to which)
  FLAG_MODE_SWITCH = 8192,
};

//! The time contract (docs/CORE.md, "The time contract"; law.hpp's LawInput):
//! an engaged controller hands its law dt <= kMaxDtPeriods / control_rate_hz;
//! a state stamped further ahead, or before the previous step, is a time jump
//! (SAFE, FLAG_TIME_JUMP, counted), and the next valid state re-engages the
//! law at its own time, whatever that time is, with bounded work.
constexpr double kMaxDtPeriods = 10.0;

//! What a controller did, counted since construction: its steps, the law's
//! calls (the work a step costs besides the guidance's RK4 steps,
//! Guidance::rk4_steps) and the time jumps it refused.
struct ControllerCounts {
  long long steps = 0;        //!< step() calls
  long long engagements = 0;  //!< (re-)engagements: reset() and each re-engagement in step()
  long long law_resets = 0;   //!< ControlLaw::reset calls
  long long law_steps = 0;    //!< ControlLaw::step calls
  long long law_afters = 0;   //!< ControlLaw::after calls
  long long jumps_ahead = 0;  //!< states stamped more than kMaxDtPeriods periods ahead (SAFE)
  long long steps_back = 0;   //!< states stamped before the previous step (SAFE)
  long long law_calls() const { return law_resets + law_steps + law_afters; }
  long long time_jumps() const { return jumps_ahead + steps_back; }
};

struct SafetyLimits {
  double max_rate = 10.0;          //!< [rad/s] a measured |omega| beyond this is rejected
  double max_wheel_speed = 1e4;    //!< [rad/s] a measured |wheel speed| beyond this is rejected
  double stale_periods = 5.0;      //!< periods without a fresh state before SAFE (shells)
};

struct ControllerConfig {
  //! The law spec: a registered name or "plugin:PATH_OR_NAME" (docs/LAWS.md)
  std::string law = kDefaultLaw;
  //! [controller.params]: handed to the law's constructor (LawParams)
  LawParams::Items law_params;
  double control_rate_hz = 10.0;  //!< [Hz]
  SpacecraftParams spacecraft;
  GuidanceParams guidance;
  PpcParams ppc;
  SafetyLimits safety;
  //! the rods as the controller knows them, the momentum manager and B-dot
  //! (magnetic_control.hpp); nothing enabled: the controller without them
  MagneticConfig magnetic;
};

// Every problem of the configuration, each naming the key and the value.
std::vector<std::string> validate(const ControllerConfig& c);

// Measurement, TrackingErrors and PpcResult: sc_rt/law.hpp.

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
  //! the law's named telemetry (Controller::telemetry_names())
  std::array<double, kLawMaxTelemetry> telemetry{};
  //! the magnetic part's decision (NaN / -1 without magnetic control)
  MagneticOutput magnetic;
};

// Tracking errors (8)-(11) and the model terms of (21) for one measurement.
TrackingErrors tracking_errors(const SpacecraftModel& sc, const Measurement& m,
                               const Vec3& sigma_DN, const Vec3& omega_DN_D,
                               const Vec3& omega_dot_DN_D);

// True when every field is finite and within the safety limits.
bool measurement_valid(const Measurement& m, const SafetyLimits& lim);

// The law model of a spacecraft model (B, B+ and the limits, copied once).
LawModel law_model(const SpacecraftModel& sc);

//! What a law's failures were: how many per call (a throw, or a non-finite
//! or wrong-shaped output, each contained as SAFE + FLAG_LAW_INVALID) and
//! the newest one (which call, at what t, what it said).
struct LawFailures {
  long long reset = 0;  //!< reset threw (at engagement or re-engagement)
  long long step = 0;   //!< step threw or returned a non-finite command
  long long after = 0;  //!< after threw
  const char* last_call = "";   //!< "reset", "step", "after" ("" for none)
  double last_t = 0.0;          //!< [s] the time of the newest failure
  std::string last_what;        //!< its message (the exception's what(), or "non-finite command")
  long long total() const { return reset + step + after; }
};

class Controller {
 public:
  // Resolves cfg.law in the registry (loading a plugin), constructs the law
  // with cfg.law_params and checks that it read every parameter. Throws
  // LawError (naming the plugin / the parameter key) or std::invalid_argument.
  explicit Controller(const ControllerConfig& c);
  Controller(const Controller&) = delete;
  Controller& operator=(const Controller&) = delete;

  // Engage at m.t: guidance at t0, every internal state from the measurement
  // (or the paper's initial values). A law whose reset throws is contained:
  // the controller stays disengaged (the next step tries again and gives
  // SAFE + FLAG_LAW_INVALID while it fails) and the failure is counted.
  void reset(const Measurement& m);
  // One control step. Engaged, at m.t in [t_prev, t_prev + max_dt()]: the
  // law's step with dt = m.t - t_prev (dt = 0: FLAG_TIME_NOT_ADVANCING).
  // Engaged, at m.t before t_prev or beyond t_prev + max_dt(): a time jump,
  // SAFE zeros with FLAG_TIME_JUMP (FLAG_TIME_NOT_ADVANCING too when back),
  // counted. Not engaged (new, or after any SAFE): engage at m.t, whatever
  // it is. An invalid measurement gives a SAFE zero command and re-engages
  // at the next valid one; so does a law that returns a non-finite command
  // (FLAG_LAW_INVALID). Bounded work whatever the stamps: at most three law
  // calls and Guidance's bound of RK4 steps (docs/CORE.md).
  Command step(const Measurement& m);
  // The same with the field in B, B_B [T], measured at m.t (the true field
  // on runs without a magnetometer; NaN: none known). It reaches only the
  // magnetic part (ControllerConfig::magnetic): the law's Measurement is the
  // plugin interface (law.hpp) and stays as it is. Without magnetic control
  // this is step(m) exactly.
  Command step(const Measurement& m, const Vec3& B_B);
  // Zero command in SAFE mode (for a shell whose input went stale); the next
  // valid step re-engages the law from its measurement.
  Command safe_command(double t, int flags);

  //! The law's registry name and code (controller_status_t.law).
  const std::string& law_name() const { return entry_.name; }
  int law_code() const { return entry_.code; }
  const std::vector<std::string>& telemetry_names() const { return telemetry_names_; }
  //! What the law's u_cmd is (its declaration, LawEntry::command).
  LawCommand law_command() const { return entry_.command; }
  //! Whether the law's u_cmd is converted to the wheels' unit: the law
  //! commands accelerations and the wheels take torques, or the reverse.
  bool command_converted() const { return convert_ != 0; }
  const ControllerConfig& config() const { return cfg_; }
  const SpacecraftModel& model() const { return model_; }
  double t0() const { return t0_; }
  const Guidance& guidance() const { return guidance_; }
  //! Every failure of the law so far (contained: the controller goes on).
  const LawFailures& law_failures() const { return failures_; }
  //! Steps, law calls and time jumps so far.
  const ControllerCounts& counts() const { return counts_; }
  //! [s] the most a law's dt may be: kMaxDtPeriods / control_rate_hz.
  double max_dt() const { return max_dt_; }
  //! Build the guidance's period table now (a late joiner's or a
  //! re-engagement's first step then costs only its bounded evaluation). The
  //! controller process calls it at start; without it the first far
  //! evaluation builds it (Guidance::prepare).
  void prepare() { guidance_.prepare(); }

  static std::unique_ptr<Controller> create(const ControllerConfig& c);

 private:
  // The law's reset, contained: false (and counted) when it threw.
  bool engage(const Measurement& m);
  void law_failed(const char* call, double t, const char* what);
  ControllerConfig cfg_;
  LawFailures failures_;
  ControllerCounts counts_;
  double max_dt_ = 1.0;
  SpacecraftModel model_;
  LawModel law_model_;
  Guidance guidance_;
  LawEntry entry_;
  std::unique_ptr<ControlLaw> law_;
  std::vector<std::string> telemetry_names_;
  double t0_ = 0.0;
  double t_prev_ = 0.0;
  bool engaged_ = false;
  bool first_ = true;
  Vec4 u_sat_prev_ = Vec4::Zero();  //!< held over the current period (ZOH), in the law's unit
  //! The law's unit -> the wheels': +1 accelerations to torques (Jw a), -1
  //! torques to accelerations (tau / Jw), 0 the same unit (no arithmetic).
  int convert_ = 0;
  //! A command in the law's unit in the wheels' unit, and back (exact: the
  //! drive's own arithmetic, types.hpp wheel_torque_command).
  Vec4 to_wheels(const Vec4& u) const;
  Vec4 to_law(const Vec4& u) const;

  //! the magnetic part (null: none configured, step(m, B_B) is step(m))
  std::unique_ptr<MagneticControl> mag_;

  LawInput input_at(const Measurement& m, double dt);
  // The law's step (step(m) without magnetic control); extra: the wheel
  // command [wheels' unit] added to the law's before saturation (null: none).
  Command step_law(const Measurement& m, const Vec4* extra);
  // Guidance to m.t, errors, the PPC transform, and their telemetry in out.
  void observe(const Measurement& m, Command& out, LawInput& in);
};

// Construct the configured law once (and probe one step at rest) without
// running: (key, message) per problem; key "law" or "params.<key>".
std::vector<std::pair<std::string, std::string>> check_law(const ControllerConfig& c);

}  // namespace sc_rt
