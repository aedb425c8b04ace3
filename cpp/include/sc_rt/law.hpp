// The control-law interface of sc-rt (docs/LAWS.md): the one header a law
// implements, built-in or plugin. Self-contained: Eigen and the standard
// library only, every function inline, so a plugin built out of tree links
// nothing of the core (the CMake package adds -Wl,--no-undefined to prove it).
//
// The common controller (sc_rt::Controller, in the core) owns the guidance,
// the tracking errors, the prescribed-performance transform, saturation,
// the measurement validity check and SAFE mode. At each step it hands the
// law a LawInput and takes back a LawOutput: the wheel command before
// saturation plus telemetry. A law holds only its own states.
//
// The time contract (docs/CORE.md, "The time contract"): the controller
// hands a law the time of each measurement it accepts and
//   - dt = 0 at reset, and on a step whose time did not advance (a repeat);
//   - 0 < dt <= kMaxDtPeriods / control_rate_hz (10 nominal periods,
//     sc_rt/controllers.hpp; LawSetup::control_rate_hz gives the period)
//     on every other step: never more, whatever the stamps;
//   - a state stamped further ahead than that, or before the previous step
//     (a jump), never reaches the law: the controller answers SAFE zeros
//     (FLAG_TIME_JUMP) and the next valid state reset()s the law at its own
//     time; so does any state after SAFE (an invalid or stale state, a law
//     failure), whatever the gap, and the first state of a controller that
//     joins a run late. A law's states are never carried across a gap longer
//     than the cap, and in.t may start anywhere (t_engaged starts at 0).
// The reference (in.ref) is the guidance's at in.t, whatever in.t is, with
// bounded work (the paper's kind from its definition when in.t is far from
// the previous step's). Cores of interface version 2 older than this contract
// handed any dt > 0; the version was kept (a law written for any dt is
// correct under the cap), so a law that relies on the cap needs a core with it.
//
// Bump SC_RT_LAW_API_VERSION whenever any type of this file changes layout
// or meaning; the loader refuses a plugin built against another version.
// tests/test_law_abi.py pins this file's declarations per version: a change
// without a bump fails it.
//
// SC_RT_LAW_API_REVISION counts additive changes within a version: optional
// entry points a plugin may export and the core looks up by name (dlsym), no
// type changed. A plugin of an older revision of the same version still loads
// and means what the revision's defaults say (revision 0: no
// sc_rt_law_command(), so it commands wheel accelerations). The ABI test pins
// each (version, revision).
#pragma once
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "sc_rt/types.hpp"

#define SC_RT_LAW_API_VERSION 3
#define SC_RT_LAW_API_REVISION 1  // 1: SC_RT_LAW_COMMAND (what a law commands)

// The compiler / ABI facts that must match between the core and a plugin
// (the types below cross the boundary by reference). Eigen's static
// alignment changes with -mavx, so it is part of the fingerprint.
#define SC_RT_LAW_STR2(x) #x
#define SC_RT_LAW_STR(x) SC_RT_LAW_STR2(x)
#if defined(__clang__)
#define SC_RT_LAW_COMPILER "clang-" SC_RT_LAW_STR(__clang_major__)
#elif defined(__GNUC__)
#define SC_RT_LAW_COMPILER "gcc-" SC_RT_LAW_STR(__GNUC__)
#else
#define SC_RT_LAW_COMPILER "cc-unknown"
#endif
#if defined(_GLIBCXX_USE_CXX11_ABI)
#define SC_RT_LAW_CXXABI "cxx11abi-" SC_RT_LAW_STR(_GLIBCXX_USE_CXX11_ABI)
#else
#define SC_RT_LAW_CXXABI "cxxabi-other"
#endif
#define SC_RT_LAW_FINGERPRINT                                                      \
  "api-" SC_RT_LAW_STR(SC_RT_LAW_API_VERSION) " " SC_RT_LAW_COMPILER " " SC_RT_LAW_CXXABI \
  " eigen-" SC_RT_LAW_STR(EIGEN_WORLD_VERSION) "." SC_RT_LAW_STR(EIGEN_MAJOR_VERSION)       \
  " align-" SC_RT_LAW_STR(EIGEN_MAX_STATIC_ALIGN_BYTES) " ptr-" SC_RT_LAW_STR(__SIZEOF_POINTER__)

namespace sc_rt {

// One measurement of the plant state at its time.
struct Measurement {
  double t = 0.0;                     //!< [s]
  Vec3 sigma_BN = Vec3::Zero();       //!< [-] MRP of the body B in the inertial frame N
  Vec3 omega_BN_B = Vec3::Zero();     //!< [rad/s] body rate in B
  Vec4 wheel_speed = Vec4::Zero();    //!< [rad/s] wheel speeds relative to the body
};

// Tracking errors (8)-(11) and the model terms of (21) for one measurement
// (docs/MODEL.md), computed by the core for every law.
struct TrackingErrors {
  Vec3 sigma_BD;     //!< x1: MRP of B relative to the desired frame D, short rotation
  Vec3 omega_BD_B;   //!< [rad/s] x2 = omega_BN_B - R(x1) omega_DN_D
  Mat3 R_BD;         //!< R(x1) (10): D components -> B
  Vec3 omega_DN_B;   //!< [rad/s] R(x1) omega_DN_D
  Vec3 A;            //!< [rad/s^2] A of (21): the known part of x2_dot
  Vec3 u_g0;         //!< [N m] nominal gravity-gradient torque
};

// The prescribed-performance transform (29)-(35) of x1 at this step, per
// axis; computed for every law (the bound is reported for every law).
struct PpcResult {
  Vec3 chi;       //!< chi(t) envelope
  Vec3 chi_dot;   //!< [1/s] d chi / dt
  Vec3 lambda;    //!< x1 / chi after clamping
  Vec3 eps;       //!< (31)
  Vec3 e1;        //!< (36) transformed error
  Vec3 r;         //!< diagonal of r (35)
  int violated = 0;  //!< bit i set: axis i outside its bound (lambda clamped)
};

// What the controller knows of the spacecraft (nominal values, never the
// plant's true inertia): fixed for the law's lifetime.
struct LawModel {
  Mat3 J0 = Mat3::Identity();      //!< [kg m^2] nominal inertia of the combined body
  Mat3 J0_inv = Mat3::Identity();  //!< [1/(kg m^2)]
  Mat34 Cbar = Mat34::Zero();      //!< [-] wheel spin axes in B (columns)
  Vec4 Jw = Vec4::Zero();          //!< [kg m^2] wheel spin inertias
  Vec4 umin = Vec4::Zero();        //!< lower wheel command limits ([rad/s^2]; [N m] on torque-commanded wheels)
  Vec4 umax = Vec4::Zero();        //!< upper wheel command limits (the same unit)
  //! What the wheels take (the scenario's [wheels] command): false, a wheel
  //! acceleration [rad/s^2] (what B and wheels_for_torque give); true, a motor
  //! torque [N m] (wheel_command gives it: Jw times the acceleration)
  bool wheel_torque_command = false;
  //! [rad/s] the wheels' speed limits (inf: none): momentum a law can still store
  Vec4 wheel_speed_max = Vec4::Constant(std::numeric_limits<double>::infinity());
  double w0 = 0.0;                 //!< [rad/s] orbit rate (gravity gradient)
  Mat34 B = Mat34::Zero();         //!< [1/s^2 per rad/s^2] B = -J0^-1 Cbar Jw of (21)
  Mat43 B_pinv = Mat43::Zero();    //!< B+ : wheel accelerations for a wanted x2_dot
  //! The wheel accelerations [rad/s^2] that give the body torque tau [N m]:
  //! J0 x2_dot = tau through B, i.e. u = B+ J0^-1 tau.
  Vec4 wheels_for_torque(const Vec3& tau) const { return B_pinv * (J0_inv * tau); }
  //! The wheel command for the wheel accelerations a [rad/s^2], in the unit
  //! the wheels take: a itself on acceleration-commanded wheels, the motor
  //! torques Jw a [N m] on torque-commanded ones (the inverse of what the
  //! drive does with a command: types.hpp wheel_torque_command).
  Vec4 wheel_command(const Vec4& a) const {
    return wheel_torque_command ? Vec4(Jw.cwiseProduct(a)) : a;
  }
};

// The reference: the desired attitude from the guidance at this step.
struct Reference {
  Vec3 sigma_DN = Vec3::Zero();        //!< [-] desired attitude
  Vec3 omega_DN_D = Vec3::Zero();      //!< [rad/s] desired rate in D
  Vec3 omega_dot_DN_D = Vec3::Zero();  //!< [rad/s^2] its derivative in D
};

// Everything a law gets at reset and at every step.
struct LawInput {
  double t = 0.0;          //!< [s] time of the measurement
  double t_engaged = 0.0;  //!< [s] time since the engagement (reset): PPC's time
  //! [s] time since the previous step: 0 at reset and when time did not
  //! advance, else in (0, kMaxDtPeriods / control_rate_hz] (the time contract above)
  double dt = 0.0;
  Measurement m;           //!< the measurement (validated: finite, within the safety limits)
  Reference ref;           //!< guidance at t
  TrackingErrors e;        //!< errors at t
  PpcResult ppc;           //!< PPC transform of e.sigma_BD at t_engaged
  //! the saturated command held over the period that just ended (zero at
  //! reset), in the unit the law commands (LawCommand: [rad/s^2] or [N m])
  Vec4 u_sat_prev = Vec4::Zero();
};

// At most this many named telemetry values per law (no allocation in step).
constexpr int kLawMaxTelemetry = 8;

// What a law returns at each step. The fixed slots are recorded in every run
// (sc-rt sim, the LCM status); leave the ones your law has no use for at zero.
struct LawOutput {
  //! the wheel command before saturation, in the unit the law declares
  //! (LawCommand): [rad/s^2] wheel accelerations by default, [N m] motor
  //! torques for a law that declares LawCommand::Torque. The controller
  //! converts it to the unit the wheels take (Controller::step).
  Vec4 u_cmd = Vec4::Zero();
  Vec3 e1 = Vec3::Zero();     //!< first error the law works on (default slot: x1)
  Vec3 e2 = Vec3::Zero();     //!< second error (a rate error, a sliding variable)
  Vec3 z1 = Vec3::Zero();     //!< [rad/s] observer state 1, if any
  Vec3 z2 = Vec3::Zero();     //!< [rad/s^2] observer state 2 (disturbance estimate), if any: a run reports its error
  Vec3 x2d = Vec3::Zero();    //!< [rad/s] filtered virtual control, if any
  Vec4 vs = Vec4::Zero();     //!< anti-windup state, if any
  double rho_hat = 0.0;       //!< an adaptive gain, if any
  //! Named telemetry: telemetry[i] is named telemetry_names()[i].
  std::array<double, kLawMaxTelemetry> telemetry{};
};

// The error a law throws for a bad parameter: the key is reported with the
// scenario file and line (laws.<law>.<key>).
class LawParamError : public std::invalid_argument {
 public:
  LawParamError(std::string key, const std::string& what)
      : std::invalid_argument(what), key_(std::move(key)) {}
  const std::string& key() const { return key_; }

 private:
  std::string key_;
};

// A law's parameter table (the scenario's [laws.NAME]): numbers and arrays of numbers by key.
// A law reads what it needs; a key it never reads is an error ("unknown
// parameter"), reported by the core after the law's construction.
class LawParams {
 public:
  using Items = std::vector<std::pair<std::string, std::vector<double>>>;
  LawParams() = default;
  explicit LawParams(Items items) : items_(std::move(items)), used_(items_.size(), 0) {}

  bool has(const std::string& key) const { return find(key) >= 0; }
  //! A number; def when the key is absent. Throws LawParamError when the
  //! value is not one finite number.
  double number(const std::string& key, double def) const {
    const int i = find(key);
    if (i < 0) return def;
    return one(i);
  }
  //! A required number.
  double number(const std::string& key) const {
    const int i = find(key);
    if (i < 0) throw LawParamError(key, key + ": required parameter is missing");
    return one(i);
  }
  //! A number > 0 (def when absent).
  double positive(const std::string& key, double def) const {
    const double v = number(key, def);
    if (!(v > 0.0)) fail(key, "must be > 0, got " + text(v));
    return v;
  }
  //! A 3-vector: three numbers, or one number for all three axes.
  Vec3 vec3(const std::string& key, const Vec3& def) const {
    const int i = find(key);
    if (i < 0) return def;
    const std::vector<double>& v = values(i);
    if (v.size() == 1) return Vec3::Constant(v[0]);
    if (v.size() != 3) fail(key, "must be 3 numbers (or one for all axes), got " + std::to_string(v.size()));
    return Vec3(v[0], v[1], v[2]);
  }
  //! Every number of the key (an array or a scalar), def when absent.
  std::vector<double> array(const std::string& key, const std::vector<double>& def = {}) const {
    const int i = find(key);
    return i < 0 ? def : values(i);
  }
  [[noreturn]] static void fail(const std::string& key, const std::string& what) {
    throw LawParamError(key, key + ": " + what);
  }
  //! A number as a message shows it (%.10g).
  static std::string text(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.10g", v);
    return buf;
  }
  const Items& items() const { return items_; }
  //! The keys no read touched (after construction: unknown parameters).
  std::vector<std::string> unused() const {
    std::vector<std::string> out;
    for (std::size_t i = 0; i < items_.size(); ++i)
      if (!used_[i]) out.push_back(items_[i].first);
    return out;
  }

 private:
  int find(const std::string& key) const {
    for (std::size_t i = 0; i < items_.size(); ++i)
      if (items_[i].first == key) {
        used_[i] = 1;
        return static_cast<int>(i);
      }
    return -1;
  }
  const std::vector<double>& values(int i) const {
    const auto& v = items_[static_cast<std::size_t>(i)].second;
    for (double x : v)
      if (!std::isfinite(x)) fail(items_[static_cast<std::size_t>(i)].first, "must be finite");
    return v;
  }
  double one(int i) const {
    const auto& v = values(i);
    if (v.size() != 1)
      fail(items_[static_cast<std::size_t>(i)].first,
           "must be one number, got " + std::to_string(v.size()));
    return v[0];
  }
  Items items_;
  mutable std::vector<char> used_;
};

// What a law's constructor gets, once: the same for a built-in law and a
// plugin (the built-in laws read their gains from params too).
struct LawSetup {
  const LawModel& model;        //!< the spacecraft as the controller knows it
  double control_rate_hz;       //!< [Hz] nominal rate (steps may come at other times: use dt, <= 10 periods)
  const LawParams& params;      //!< the law's own table ([laws.NAME] of the scenario)
};

// The interface. No clocks, no I/O and no allocation in reset() and step().
class ControlLaw {
 public:
  virtual ~ControlLaw() = default;
  //! Engage at in.t (in.dt = 0, in.u_sat_prev = 0): set every state from the
  //! measurement or to its initial value. A reset mid-run equals a fresh start.
  virtual void reset(const LawInput& in) = 0;
  //! One step; fill out.u_cmd (and any telemetry). in.dt > 0 except at the
  //! step right after reset and when the time did not advance; never more
  //! than kMaxDtPeriods nominal periods (a longer gap resets the law instead).
  virtual void step(const LawInput& in, LawOutput& out) = 0;
  //! After saturation, with the command that goes out (anti-windup), both in
  //! the unit the law commands (u_sat converted back when the wheels take the other).
  virtual void after(const Vec4& u_cmd, const Vec4& u_sat) { (void)u_cmd; (void)u_sat; }
  //! Names of LawOutput::telemetry[0..n), n <= kLawMaxTelemetry.
  virtual std::vector<std::string> telemetry_names() const { return {}; }
};

// What a law's u_cmd is (docs/LAWS.md section 1, "What a law commands"). The
// wheels take one or the other (LawModel::wheel_torque_command, the scenario's
// [wheels] command); when they differ the controller converts exactly as the
// drive does (types.hpp wheel_torque_command): torque = Jw a, a = torque / Jw.
enum class LawCommand : int {
  Acceleration = 0,  //!< wheel accelerations [rad/s^2] (the default: every built-in law)
  Torque = 1,        //!< motor torques [N m]
};

// What a plugin library exports (SC_RT_LAW_PLUGIN defines it).
struct LawPluginInfo {
  int api_version;          //!< SC_RT_LAW_API_VERSION the plugin was built with
  const char* fingerprint;  //!< SC_RT_LAW_FINGERPRINT the plugin was built with
  const char* name;         //!< the law's name in the registry (sc-rt sim --law NAME)
  const char* doc;          //!< one line
  ControlLaw* (*create)(const LawSetup& setup);  //!< new law; throws LawParamError on bad params
};

}  // namespace sc_rt

// The plugin's C entry points: sc_rt_law_api_version() is checked first (any
// version can call it), then sc_rt_law_plugin() gives the rest.
#define SC_RT_LAW_ENTRY_VERSION "sc_rt_law_api_version"
#define SC_RT_LAW_ENTRY_INFO "sc_rt_law_plugin"
// Optional (revision 1): int sc_rt_law_command(void), a LawCommand value; a
// plugin without it commands wheel accelerations.
#define SC_RT_LAW_ENTRY_COMMAND "sc_rt_law_command"

// In exactly one source file of a plugin:
//   SC_RT_LAW_PLUGIN("my-law", MyLaw, "what it is")
// where MyLaw derives from sc_rt::ControlLaw and has a constructor
// MyLaw(const sc_rt::LawSetup&).
#define SC_RT_LAW_PLUGIN(NAME, CLASS, DOC)                                                   \
  extern "C" __attribute__((visibility("default"))) int sc_rt_law_api_version(void) {       \
    return SC_RT_LAW_API_VERSION;                                                            \
  }                                                                                          \
  extern "C" __attribute__((visibility("default"))) const ::sc_rt::LawPluginInfo*           \
  sc_rt_law_plugin(void) {                                                                   \
    static const ::sc_rt::LawPluginInfo info{                                                \
        SC_RT_LAW_API_VERSION, SC_RT_LAW_FINGERPRINT, NAME, DOC,                             \
        [](const ::sc_rt::LawSetup& s) -> ::sc_rt::ControlLaw* { return new CLASS(s); }};    \
    return &info;                                                                            \
  }

// Optionally, in the same source file, what the law's u_cmd is (without it:
// wheel accelerations):
//   SC_RT_LAW_COMMAND(sc_rt::LawCommand::Torque)
#define SC_RT_LAW_COMMAND(KIND)                                                              \
  extern "C" __attribute__((visibility("default"))) int sc_rt_law_command(void) {           \
    return static_cast<int>(KIND);                                                           \
  }
