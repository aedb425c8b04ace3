#include "sc_rt/controllers.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "sc_rt/mrp.hpp"
#include "sc_rt/util.hpp"

namespace sc_rt {

namespace {
void append(std::vector<std::string>& to, const std::vector<std::string>& from) {
  to.insert(to.end(), from.begin(), from.end());
}
void positive(std::vector<std::string>& errs, const char* key, double v, bool allow_zero = false) {
  if (!(std::isfinite(v) && (allow_zero ? v >= 0.0 : v > 0.0)))
    errs.push_back(std::string(key) + (allow_zero ? " must be >= 0" : " must be > 0") +
                   ", got " + format_double(v));
}
}  // namespace

std::vector<std::string> validate(const ControllerConfig& c) {
  std::vector<std::string> errs;
  if (c.law.empty()) errs.push_back("law must be a law name or plugin:PATH_OR_NAME, got \"\"");
  positive(errs, "control_rate_hz", c.control_rate_hz);
  append(errs, validate(c.spacecraft));
  append(errs, validate(c.guidance));
  append(errs, validate(c.ppc));
  positive(errs, "safety.max_rate", c.safety.max_rate);
  positive(errs, "safety.max_wheel_speed", c.safety.max_wheel_speed);
  positive(errs, "safety.stale_periods", c.safety.stale_periods);
  append(errs, validate(c.magnetic, c.spacecraft));
  return errs;
}

TrackingErrors tracking_errors(const SpacecraftModel& sc, const Measurement& m,
                               const Vec3& sigma_DN, const Vec3& omega_d,
                               const Vec3& omega_d_dot) {
  const SpacecraftParams& p = sc.params();
  TrackingErrors e;
  e.sigma_BD = mrp_subtract(m.sigma_BN, sigma_DN);  // (8), short rotation
  e.R_BD = mrp_to_dcm(e.sigma_BD);                  // (10)
  e.omega_DN_B = e.R_BD * omega_d;
  e.omega_BD_B = m.omega_BN_B - e.omega_DN_B;       // (11)
  e.u_g0 = gravity_gradient(p.J0, m.sigma_BN, p.w0);
  // (21): A = -J0^-1 W^ (J0 W + Cbar Jw Omega_w) + x2^ R omega_d - R omega_d_dot + J0^-1 u_g0
  const Vec3& W = m.omega_BN_B;
  const Vec3 h = p.J0 * W + p.Cbar * p.Jw.cwiseProduct(m.wheel_speed);
  e.A = -sc.J0_inverse() * W.cross(h) + e.omega_BD_B.cross(e.omega_DN_B) -
        e.R_BD * omega_d_dot + sc.J0_inverse() * e.u_g0;
  return e;
}

bool measurement_valid(const Measurement& m, const SafetyLimits& lim) {
  if (!(std::isfinite(m.t) && m.sigma_BN.allFinite() && m.omega_BN_B.allFinite() &&
        m.wheel_speed.allFinite()))
    return false;
  // |sigma| <= 1 after the shadow set; a publisher may send either set, but
  // nothing physical is far beyond that.
  if (m.sigma_BN.norm() > 1e3) return false;
  if (m.omega_BN_B.norm() > lim.max_rate) return false;
  if (m.wheel_speed.cwiseAbs().maxCoeff() > lim.max_wheel_speed) return false;
  return true;
}

LawModel law_model(const SpacecraftModel& sc) {
  const SpacecraftParams& p = sc.params();
  LawModel m;
  m.J0 = p.J0;
  m.J0_inv = sc.J0_inverse();
  m.Cbar = p.Cbar;
  m.Jw = p.Jw;
  m.umin = p.umin;
  m.umax = p.umax;
  m.wheel_torque_command = p.wheel_torque_command;
  m.wheel_speed_max = p.wheel_speed_max;
  m.w0 = p.w0;
  m.B = sc.B();
  m.B_pinv = sc.B_pinv();
  return m;
}

namespace {
std::string law_label(const LawEntry& e) {
  return e.source == "built-in" ? e.name : e.name + " (" + e.source + ")";
}
}  // namespace

Controller::Controller(const ControllerConfig& c)
    : cfg_((throw_if_errors("ControllerConfig", validate(c)), c)),
      model_(c.spacecraft),
      law_model_(law_model(model_)),
      guidance_(c.guidance, 1.0 / c.control_rate_hz),
      entry_(resolve_law(c.law)) {
  max_dt_ = kMaxDtPeriods / cfg_.control_rate_hz;
  const std::string who = "law " + law_label(entry_) + ": ";
  LawParams params(cfg_.law_params);
  const LawSetup setup{law_model_, cfg_.control_rate_hz, params};
  try {
    law_ = entry_.create(setup);
  } catch (const LawParamError& e) {
    std::string d = e.what();
    if (d.compare(0, e.key().size() + 2, e.key() + ": ") == 0) d = d.substr(e.key().size() + 2);
    throw LawError("params." + e.key(), who + "laws." + entry_.name + "." + e.key() + ": " + d, d);
  } catch (const std::exception& e) {
    throw LawError("law", who + "construction failed: " + e.what(),
                   std::string("construction failed: ") + e.what());
  } catch (...) {
    throw LawError("law", who + "construction failed (not a std::exception)", "construction failed");
  }
  if (!law_) throw LawError("law", who + "its factory returned no law", "its factory returned no law");
  for (const std::string& k : params.unused()) {
    const std::string d = "unknown parameter of law " + entry_.name;
    throw LawError("params." + k, who + "laws." + entry_.name + "." + k + ": " + d, d);
  }
  // What the law commands against what the wheels take (docs/LAWS.md,
  // "What a law commands"): Jw > 0 is validated with the spacecraft, so the
  // conversion always exists.
  const bool law_torque = entry_.command == LawCommand::Torque;
  if (law_torque != law_model_.wheel_torque_command) convert_ = law_torque ? -1 : +1;
  telemetry_names_ = law_->telemetry_names();
  if (cfg_.magnetic.active()) mag_ = std::make_unique<MagneticControl>(cfg_.magnetic, cfg_.spacecraft);
  if (telemetry_names_.size() > static_cast<std::size_t>(kLawMaxTelemetry)) {
    const std::string d = "declares " + std::to_string(telemetry_names_.size()) +
                          " telemetry names, at most " + std::to_string(kLawMaxTelemetry);
    throw LawError("law", who + d, d);
  }
}

Vec4 Controller::to_wheels(const Vec4& u) const {
  // The drive's arithmetic (types.hpp wheel_torque_command): torque = Jw a,
  // a = torque / Jw, per wheel.
  if (convert_ > 0) return law_model_.Jw.cwiseProduct(u);
  if (convert_ < 0) return u.cwiseQuotient(law_model_.Jw);
  return u;
}

Vec4 Controller::to_law(const Vec4& u) const {
  if (convert_ > 0) return u.cwiseQuotient(law_model_.Jw);
  if (convert_ < 0) return law_model_.Jw.cwiseProduct(u);
  return u;
}

std::unique_ptr<Controller> Controller::create(const ControllerConfig& c) {
  return std::make_unique<Controller>(c);
}

LawInput Controller::input_at(const Measurement& m, double dt) {
  LawInput in;
  in.t = m.t;
  in.t_engaged = m.t - t0_;
  in.dt = dt;
  in.m = m;
  in.ref.sigma_DN = guidance_.sigma_DN();
  in.ref.omega_DN_D = omega_d(cfg_.guidance, m.t);
  in.ref.omega_dot_DN_D = omega_d_dot(cfg_.guidance, m.t);
  in.e = tracking_errors(model_, m, in.ref.sigma_DN, in.ref.omega_DN_D, in.ref.omega_dot_DN_D);
  // The prescribed bound is reported for every law (a SAFE step stamped
  // before the engagement, a step back, reports it at the engagement).
  in.ppc = ppc_transform(cfg_.ppc, in.e.sigma_BD, std::max(0.0, m.t - t0_));
  in.u_sat_prev = u_sat_prev_;
  return in;
}

void Controller::law_failed(const char* call, double t, const char* what) {
  // The exceptional path (a law that failed): the only place that may allocate.
  failures_.last_call = call;
  failures_.last_t = t;
  failures_.last_what = what;
  engaged_ = false;  // the next valid step re-engages (reset) the law
}

bool Controller::engage(const Measurement& m) {
  t0_ = m.t;
  t_prev_ = m.t;
  guidance_.reset(m.t);
  u_sat_prev_.setZero();
  ++counts_.engagements;
  try {
    ++counts_.law_resets;
    law_->reset(input_at(m, 0.0));
  } catch (const std::exception& e) {
    ++failures_.reset;
    law_failed("reset", m.t, e.what());
    return false;
  } catch (...) {
    ++failures_.reset;
    law_failed("reset", m.t, "unknown exception");
    return false;
  }
  engaged_ = true;
  first_ = true;
  return true;
}

void Controller::reset(const Measurement& m) { engage(m); }

Command Controller::safe_command(double t, int flags) {
  Command out;
  out.t = t;
  out.mode = MODE_SAFE;
  out.flags = flags;
  out.sigma_DN = guidance_.sigma_DN();
  engaged_ = false;
  return out;
}

void Controller::observe(const Measurement& m, Command& out, LawInput& in) {
  guidance_.advance(m.t);
  in = input_at(m, 0.0);
  out.sigma_DN = in.ref.sigma_DN;
  out.sigma_BD = in.e.sigma_BD;
  out.omega_BD_B = in.e.omega_BD_B;
  out.chi = in.ppc.chi;
  out.lam = in.ppc.lambda;
  out.flags |= in.ppc.violated;  // FLAG_BOUND_X/Y/Z are bits 0..2
}

Command Controller::step(const Measurement& m) {
  if (!mag_) return step_law(m, nullptr);
  return step(m, Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
}

Command Controller::step(const Measurement& m, const Vec3& B_B) {
  if (!mag_) return step_law(m, nullptr);
  // The magnetic part beside the law (magnetic_control.hpp; docs/MODEL.md section 17).
  MagneticOutput mo = mag_->idle(B_B);
  if (!measurement_valid(m, cfg_.safety)) {  // SAFE: the law's path, the rods idle
    Command out = step_law(m, nullptr);
    out.magnetic = mo;
    return out;
  }
  if (mag_->mode_at(m.omega_BN_B.norm(), mo) == DetumbleMode::Detumble) {
    // B-dot on the rods, the wheels commanded zero, the law not stepped: it
    // is (re-)engaged from the measurement at the switch to Attitude.
    ++counts_.steps;
    Command out;
    out.t = m.t;
    out.mode = MODE_NORMAL;
    out.flags = mo.switched ? FLAG_MODE_SWITCH : 0;
    out.sigma_DN = guidance_.sigma_DN();
    // The tracking errors and the envelope stay true while detumbling, as in
    // SAFE (bounded work: the guidance's evaluation at m.t).
    LawInput in;
    if (m.t >= guidance_.t()) observe(m, out, in);
    engaged_ = false;
    mag_->detumble(m.t, B_B, m.omega_BN_B, m.wheel_speed, mo);
    out.magnetic = mo;
    return out;
  }
  mag_->attitude(m.wheel_speed, B_B, mo);
  Command out = step_law(m, cfg_.magnetic.momentum_enabled ? &mo.wheel_cmd : nullptr);
  if (out.mode == MODE_SAFE) {  // no wheel command: no feed-forward, so no dipole either
    mo.rod_dipole_cmd.setZero();
    mo.m_B_cmd.setZero();
  }
  if (mo.switched) out.flags |= FLAG_MODE_SWITCH;
  out.magnetic = mo;
  return out;
}

Command Controller::step_law(const Measurement& m, const Vec4* extra) {
  ++counts_.steps;
  LawInput in;
  if (!measurement_valid(m, cfg_.safety)) {
    Command out = safe_command(m.t, FLAG_INVALID_STATE);
    // Telemetry stays true in SAFE mode when the state is finite but out of
    // range (a tumble past max_rate): the errors are still well defined.
    if (std::isfinite(m.t) && m.sigma_BN.allFinite() && m.omega_BN_B.allFinite() &&
        m.wheel_speed.allFinite() && m.t >= guidance_.t())
      observe(m, out, in);
    return out;
  }
  if (engaged_ && (m.t < t_prev_ || m.t - t_prev_ > max_dt_)) {
    // A time jump (docs/CORE.md, "The time contract"): the law's states
    // cannot be carried across it. SAFE zeros now; the next valid state
    // re-engages the law at its own time. The telemetry stays true: the
    // reference at m.t (bounded work, Guidance::reset).
    const bool back = m.t < t_prev_;
    ++(back ? counts_.steps_back : counts_.jumps_ahead);
    Command out = safe_command(m.t, FLAG_TIME_JUMP | (back ? FLAG_TIME_NOT_ADVANCING : 0));
    guidance_.reset(m.t);
    observe(m, out, in);
    return out;
  }
  if (!engaged_ && !engage(m)) {  // (re-)engage from this measurement; a reset that threw: SAFE
    Command out = safe_command(m.t, FLAG_LAW_INVALID);
    return out;
  }
  Command out;
  out.t = m.t;
  out.mode = MODE_NORMAL;
  double dt = m.t - t_prev_;
  if (dt < 0.0 || (dt == 0.0 && !first_)) {
    out.flags |= FLAG_TIME_NOT_ADVANCING;
    dt = 0.0;
  }
  first_ = false;
  observe(m, out, in);
  in.dt = dt;
  LawOutput lo;
  // The message is copied inside the handler: what() points into the
  // exception, which is gone after it (the failure path may allocate).
  std::string why;
  bool threw = false;
  try {
    ++counts_.law_steps;
    law_->step(in, lo);
  } catch (const std::exception& e) {
    threw = true;
    why = e.what();
  } catch (...) {
    threw = true;
    why = "unknown exception";
  }
  if (threw || !lo.u_cmd.allFinite()) {
    // A law that fails gives SAFE zeros; the next valid step re-engages it.
    ++failures_.step;
    law_failed("step", m.t, threw ? why.c_str() : "non-finite command");
    out.mode = MODE_SAFE;
    out.flags |= FLAG_LAW_INVALID;
    return out;
  }
  // The one place every law's output passes: in the wheels' unit before
  // saturation (the limits umin/umax are the wheels').
  const Vec4 law_w = to_wheels(lo.u_cmd);
  // The momentum manager's command (feed-forward + null space, already in
  // the wheels' unit) is summed with the law's before the one saturation.
  out.u_cmd = extra != nullptr ? Vec4(law_w + *extra) : law_w;
  out.e1 = lo.e1;
  out.e2 = lo.e2;
  out.z1 = lo.z1;
  out.z2 = lo.z2;
  out.x2d = lo.x2d;
  out.vs = lo.vs;
  out.rho_hat = lo.rho_hat;
  out.telemetry = lo.telemetry;

  out.u_sat = model_.saturate(out.u_cmd);
  for (int i = 0; i < 4; ++i)
    if (out.u_sat(i) != out.u_cmd(i)) out.flags |= (FLAG_SAT_1 << i);
  // The law sees its own unit back (the held command, anti-windup): with the
  // manager's command added, its own share of it (u_sat less the manager's
  // where a wheel saturated, its own command where none did).
  if (extra != nullptr) {
    Vec4 share;
    for (int i = 0; i < 4; ++i) share(i) = out.u_sat(i) == out.u_cmd(i) ? law_w(i) : out.u_sat(i) - (*extra)(i);
    u_sat_prev_ = to_law(share);
  } else {
    u_sat_prev_ = to_law(out.u_sat);
  }
  std::string after_why;
  bool after_threw = false;
  try {
    ++counts_.law_afters;
    law_->after(lo.u_cmd, u_sat_prev_);
  } catch (const std::exception& e) {
    after_threw = true;
    after_why = e.what();
  } catch (...) {
    after_threw = true;
    after_why = "unknown exception";
  }
  if (after_threw) {
    // The law's state after this command is unknown: SAFE now, re-engage next.
    ++failures_.after;
    law_failed("after", m.t, after_why.c_str());
    Command safe = safe_command(m.t, out.flags | FLAG_LAW_INVALID);
    safe.sigma_DN = out.sigma_DN;
    safe.sigma_BD = out.sigma_BD;
    safe.omega_BD_B = out.omega_BD_B;
    return safe;
  }
  if (dt > 0.0) t_prev_ = m.t;
  return out;
}

std::vector<std::pair<std::string, std::string>> check_law(const ControllerConfig& c) {
  std::vector<std::pair<std::string, std::string>> out;
  std::unique_ptr<Controller> ctl;
  try {
    ctl = Controller::create(c);
  } catch (const LawError& e) {
    out.emplace_back(e.key(), e.what());
    return out;
  } catch (const std::exception& e) {
    out.emplace_back("", e.what());
    return out;
  }
  // The probe: one step at rest at t = 0 on a separate instance.
  Measurement m;
  const Command cmd = ctl->step(m);
  if (cmd.flags & FLAG_LAW_INVALID)
    out.emplace_back("law", "law " + law_label(resolve_law(ctl->config().law)) + ": returns a non-finite command (or throws) at rest (probe step at t = 0)");
  return out;
}

}  // namespace sc_rt
