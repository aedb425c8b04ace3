#include "sc_rt/controllers.hpp"

#include <cmath>
#include <stdexcept>

#include "sc_rt/mrp.hpp"
#include "sc_rt/util.hpp"

namespace sc_rt {

const char* law_name(Law law) {
  switch (law) {
    case Law::DscPpc: return "dsc-ppc";
    case Law::Dsc: return "dsc";
    case Law::Pd: return "pd";
    case Law::Rft: return "rft";
  }
  return "unknown";
}

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
  const int law = static_cast<int>(c.law);
  if (law < 0 || law > 3) errs.push_back("law must be 0..3, got " + std::to_string(law));
  positive(errs, "control_rate_hz", c.control_rate_hz);
  append(errs, validate(c.spacecraft));
  append(errs, validate(c.guidance));
  append(errs, validate(c.ppc));
  append(errs, validate(c.neso));
  positive(errs, "dsc.k1", c.dsc.k1);
  positive(errs, "dsc.k2", c.dsc.k2);
  positive(errs, "dsc.k3", c.dsc.k3, true);
  positive(errs, "dsc.k4", c.dsc.k4);
  positive(errs, "dsc.k6", c.dsc.k6);
  positive(errs, "dsc.tau", c.dsc.tau);
  positive(errs, "pd.beta1", c.pd.beta1);
  positive(errs, "pd.beta2", c.pd.beta2);
  positive(errs, "rft.c", c.rft.c);
  positive(errs, "rft.k", c.rft.k);
  positive(errs, "rft.gain", c.rft.gain, true);
  positive(errs, "rft.leak", c.rft.leak, true);
  positive(errs, "rft.phi", c.rft.phi);
  positive(errs, "rft.rho0", c.rft.rho0, true);
  positive(errs, "safety.max_rate", c.safety.max_rate);
  positive(errs, "safety.max_wheel_speed", c.safety.max_wheel_speed);
  positive(errs, "safety.stale_periods", c.safety.stale_periods);
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

Controller::Controller(const ControllerConfig& c)
    : cfg_((throw_if_errors("ControllerConfig", validate(c)), c)),
      model_(c.spacecraft),
      guidance_(c.guidance, 1.0 / c.control_rate_hz) {}

TrackingErrors Controller::errors_at(const Measurement& m) {
  const double t = m.t;
  return tracking_errors(model_, m, guidance_.sigma_DN(), omega_d(cfg_.guidance, t),
                         omega_d_dot(cfg_.guidance, t));
}

void Controller::reset(const Measurement& m) {
  t0_ = m.t;
  t_prev_ = m.t;
  guidance_.reset(m.t);
  u_sat_prev_.setZero();
  const TrackingErrors e = errors_at(m);
  law_reset(e, m);
  engaged_ = true;
  first_ = true;
}

Command Controller::safe_command(double t, int flags) {
  Command out;
  out.t = t;
  out.mode = MODE_SAFE;
  out.flags = flags;
  out.sigma_DN = guidance_.sigma_DN();
  engaged_ = false;
  return out;
}

void Controller::observe(const Measurement& m, Command& out, TrackingErrors& e, PpcResult& ppc) {
  guidance_.advance(m.t);
  e = errors_at(m);
  out.sigma_DN = guidance_.sigma_DN();
  out.sigma_BD = e.sigma_BD;
  out.omega_BD_B = e.omega_BD_B;
  // The prescribed bound is reported for every law.
  ppc = ppc_transform(cfg_.ppc, e.sigma_BD, m.t - t0_);
  out.chi = ppc.chi;
  out.lam = ppc.lambda;
  out.flags |= ppc.violated;  // FLAG_BOUND_X/Y/Z are bits 0..2
}

Command Controller::step(const Measurement& m) {
  TrackingErrors e;
  PpcResult ppc;
  if (!measurement_valid(m, cfg_.safety)) {
    Command out = safe_command(m.t, FLAG_INVALID_STATE);
    // Telemetry stays true in SAFE mode when the state is finite but out of
    // range (a tumble past max_rate): the errors are still well defined.
    if (std::isfinite(m.t) && m.sigma_BN.allFinite() && m.omega_BN_B.allFinite() &&
        m.wheel_speed.allFinite() && m.t >= guidance_.t())
      observe(m, out, e, ppc);
    return out;
  }
  if (!engaged_) reset(m);  // (re-)engage from this measurement
  Command out;
  out.t = m.t;
  out.mode = MODE_NORMAL;
  double dt = m.t - t_prev_;
  if (dt < 0.0 || (dt == 0.0 && !first_)) {
    out.flags |= FLAG_TIME_NOT_ADVANCING;
    dt = 0.0;
  }
  first_ = false;
  observe(m, out, e, ppc);
  law_step(e, ppc, dt, out);

  out.u_sat = model_.saturate(out.u_cmd);
  for (int i = 0; i < 4; ++i)
    if (out.u_sat(i) != out.u_cmd(i)) out.flags |= (FLAG_SAT_1 << i);
  u_sat_prev_ = out.u_sat;
  law_after(out);
  if (dt > 0.0) t_prev_ = m.t;
  return out;
}

namespace {

// DSC with (DscPpc) or without (Dsc) the prescribed-performance transform.
class DscController final : public Controller {
 public:
  DscController(const ControllerConfig& c, bool use_ppc)
      : Controller(c), use_ppc_(use_ppc), neso_(c.neso) {}

 protected:
  // Virtual control (36): x2bar = -(r G)^-1 (k1 e1 - r Lambda chi_dot)
  //                             = -G^-1 (k1 r^-1 e1 - Lambda chi_dot).
  Vec3 virtual_control(const TrackingErrors& e, const PpcResult& p, Vec3& e1, Vec3& r) const {
    const Mat3 Ginv = mrp_G_inverse(e.sigma_BD);
    if (!use_ppc_) {  // DSC: e1 = x1, r = I, no chi_dot term
      e1 = e.sigma_BD;
      r.setOnes();
      return -Ginv * (cfg_.dsc.k1 * e1);
    }
    e1 = p.e1;
    r = p.r;
    return -Ginv * (cfg_.dsc.k1 * e1.cwiseQuotient(r) - p.lambda.cwiseProduct(p.chi_dot));
  }

  void law_reset(const TrackingErrors& e, const Measurement&) override {
    Vec3 e1, r;
    x2bar_prev_ = virtual_control(e, ppc_transform(cfg_.ppc, e.sigma_BD, 0.0), e1, r);
    x2d_ = x2bar_prev_;  // (37): x2d(0) = x2bar(0)
    vs_.setZero();       // (42): vs(0) = 0
    du_prev_.setZero();
    neso_.reset(cfg_.neso.init_from_measurement ? e.omega_BD_B : Vec3::Zero(), Vec3::Zero());
    A_prev_ = e.A;
    x2_prev_ = e.omega_BD_B;
  }

  void law_step(const TrackingErrors& e, const PpcResult& ppc, double dt, Command& out) override {
    const DscGains& g = cfg_.dsc;
    const Mat34& B = model_.B();
    if (dt > 0.0) {
      // Observer (22) over the period just ended: B sat(uc) held, A and x2 linear.
      neso_.update(dt, A_prev_, e.A, x2_prev_, e.omega_BD_B, B * u_sat_prev_);
      // Filter (37) and compensator (42) are linear with inputs held over the
      // period: exact discretisation.
      const double a = std::exp(-dt / g.tau);
      x2d_ = a * x2d_ + (1.0 - a) * x2bar_prev_;
      const double b = std::exp(-g.k4 * dt);
      vs_ = b * vs_ + ((1.0 - b) / g.k4) * du_prev_;
    }
    Vec3 e1, r;
    const Vec3 x2bar = virtual_control(e, ppc, e1, r);
    const Vec3 x2d_dot = (x2bar - x2d_) / g.tau;  // (37) at t_k
    const Vec3 e2 = e.omega_BD_B - x2d_;          // (27)
    const Mat3 G = mrp_G(e.sigma_BD);
    // (41), corrected (erratum 1): + x2d_dot
    const Vec3 v = -e.A - g.k2 * e2 - G.transpose() * r.cwiseProduct(e1) - g.k3 * (B * vs_) -
                   neso_.z2() + x2d_dot;
    out.u_cmd = model_.B_pinv() * v;
    out.e1 = e1;
    out.e2 = e2;
    out.z1 = neso_.z1();
    out.z2 = neso_.z2();
    out.x2d = x2d_;
    out.vs = vs_;
    x2bar_prev_ = x2bar;
    A_prev_ = e.A;
    x2_prev_ = e.omega_BD_B;
  }

  void law_after(const Command& out) override { du_prev_ = out.u_sat - out.u_cmd; }  // (42)

 private:
  bool use_ppc_;
  Neso neso_;
  Vec3 x2d_ = Vec3::Zero();
  Vec3 x2bar_prev_ = Vec3::Zero();
  Vec4 vs_ = Vec4::Zero();
  Vec4 du_prev_ = Vec4::Zero();
  Vec3 A_prev_ = Vec3::Zero();
  Vec3 x2_prev_ = Vec3::Zero();
};

class PdController final : public Controller {
 public:
  using Controller::Controller;

 protected:
  void law_reset(const TrackingErrors&, const Measurement&) override {}
  void law_step(const TrackingErrors& e, const PpcResult&, double, Command& out) override {
    out.u_cmd = -model_.B_pinv() * (cfg_.pd.beta1 * e.sigma_BD + cfg_.pd.beta2 * e.omega_BD_B);
    out.e1 = e.sigma_BD;
    out.e2 = e.omega_BD_B;
  }
};

// Adaptive boundary-layer sliding mode (docs/CORE.md):
//   s = x2 + c x1
//   uc = B+ [ -A - c G(x1) x2 - k s - rho_hat sat(s / phi) ]
//   rho_hat_dot = gain |s| - leak rho_hat   (exact with |s| held over a period)
class RftController final : public Controller {
 public:
  using Controller::Controller;

 protected:
  void law_reset(const TrackingErrors& e, const Measurement&) override {
    rho_ = cfg_.rft.rho0;
    s_norm_prev_ = (e.omega_BD_B + cfg_.rft.c * e.sigma_BD).norm();
  }
  void law_step(const TrackingErrors& e, const PpcResult&, double dt, Command& out) override {
    const RftGains& g = cfg_.rft;
    if (dt > 0.0) {
      if (g.leak > 0.0) {
        const double a = std::exp(-g.leak * dt);
        rho_ = a * rho_ + (1.0 - a) / g.leak * g.gain * s_norm_prev_;
      } else {
        rho_ += dt * g.gain * s_norm_prev_;
      }
    }
    const Vec3 s = e.omega_BD_B + g.c * e.sigma_BD;
    const Vec3 sat_s = (s / g.phi).cwiseMax(-1.0).cwiseMin(1.0);
    const Vec3 v = -e.A - g.c * (mrp_G(e.sigma_BD) * e.omega_BD_B) - g.k * s - rho_ * sat_s;
    out.u_cmd = model_.B_pinv() * v;
    out.e1 = e.sigma_BD;
    out.e2 = s;
    out.rho_hat = rho_;
    s_norm_prev_ = s.norm();
  }

 private:
  double rho_ = 0.0;
  double s_norm_prev_ = 0.0;
};

}  // namespace

std::unique_ptr<Controller> Controller::create(const ControllerConfig& c) {
  switch (c.law) {
    case Law::DscPpc: return std::make_unique<DscController>(c, true);
    case Law::Dsc: return std::make_unique<DscController>(c, false);
    case Law::Pd: return std::make_unique<PdController>(c);
    case Law::Rft: return std::make_unique<RftController>(c);
  }
  throw std::invalid_argument("unknown law " + std::to_string(static_cast<int>(c.law)));
}

}  // namespace sc_rt
