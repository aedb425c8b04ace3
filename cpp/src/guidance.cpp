#include "sc_rt/guidance.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "sc_rt/mrp.hpp"
#include "sc_rt/util.hpp"

namespace sc_rt {

namespace {
constexpr double kPi = 3.14159265358979323846;

// The MRP of R(rel) R(base): the rotation rel after base (short set).
Vec3 compose(const Vec3& rel, const Vec3& base) { return mrp_subtract(rel, -base); }

// Slew angle theta(t) [rad], its rate and acceleration, cycloidal profile.
struct SlewAngle {
  double theta, rate, accel;
};
SlewAngle slew_profile(const GuidanceParams& p, double phi, double t) {
  if (!(t > p.slew_start)) return {0.0, 0.0, 0.0};
  const double T = p.slew_duration;
  const double s = (t - p.slew_start) / T;
  if (s >= 1.0) return {phi, 0.0, 0.0};
  const double w = 2.0 * kPi * s;
  return {phi * (s - std::sin(w) / (2.0 * kPi)), phi / T * (1.0 - std::cos(w)),
          2.0 * kPi * phi / (T * T) * std::sin(w)};
}

int table_size(const GuidanceParams& p) { return static_cast<int>(p.table_t.size()); }

// The sizes a Table's evaluation relies on (validate() checks the rest);
// without them an unvalidated table would be read out of bounds.
int checked_table_size(const GuidanceParams& p) {
  const int n = table_size(p);
  if (n < 2 || p.table_sigma.rows() != n || p.table_omega.rows() != n)
    throw std::invalid_argument("a table reference needs >= 2 samples with one sigma and omega row each "
                                "(validate() the GuidanceParams)");
  return n;
}

// k with t_k <= t < t_k+1, for t_0 <= t < t_n-1.
int table_segment(const GuidanceParams& p, double t) {
  const double* b = p.table_t.data();
  const double* e = b + p.table_t.size();
  return static_cast<int>(std::upper_bound(b, e, t) - b) - 1;
}

void append_vec3_errors(std::vector<std::string>& errs, const std::string& what, const MatX3& m,
                        bool mrp) {
  for (Eigen::Index k = 0; k < m.rows(); ++k) {
    const Vec3 v = m.row(k).transpose();
    if (!v.allFinite() || (mrp && v.norm() > 1.0 + 1e-12)) {
      errs.push_back(what + " sample " + std::to_string(k) + " must be finite" +
                     (mrp ? " with |sigma| <= 1" : "") + ", got " + format_matrix(v));
      return;
    }
  }
}
}  // namespace

const char* guidance_kind_name(GuidanceKind k) {
  switch (k) {
    case GuidanceKind::Paper: return "paper";
    case GuidanceKind::Hold: return "hold";
    case GuidanceKind::Slew: return "slew";
    case GuidanceKind::Table: return "table";
  }
  return "unknown";
}

std::vector<std::string> validate(const GuidanceParams& p) {
  std::vector<std::string> errs;
  const int kind = static_cast<int>(p.kind);
  if (kind < 0 || kind > 3) {
    errs.push_back("guidance kind must be 0..3 (paper, hold, slew, table), got " + std::to_string(kind));
    return errs;
  }
  if (p.kind != GuidanceKind::Table &&
      (!p.sigma_d0.allFinite() || p.sigma_d0.norm() > 1.0 + 1e-12))
    errs.push_back("sigma_d0 must be finite with |sigma_d0| <= 1, got " + format_matrix(p.sigma_d0));
  if (p.kind == GuidanceKind::Paper) {
    if (!(p.omega_bias.allFinite() && p.omega_cos.allFinite() && p.omega_sin.allFinite()))
      errs.push_back("omega_d amplitudes must be finite");
    if (!std::isfinite(p.omega_freq))
      errs.push_back("omega_d frequency must be finite, got " + format_double(p.omega_freq));
    if (errs.empty()) {
      const GuidancePeriodTable tab = guidance_period_table(p);
      if (tab.kind == GuidancePeriodTable::Periodic && tab.n_steps > kGuidancePeriodStepsMax)
        errs.push_back(
            "omega_d frequency " + format_double(p.omega_freq) + " rad/s is too slow for its rates: the " +
            "period 2 pi/|freq| = " + format_double(tab.period) + " s needs " +
            std::to_string(tab.n_steps) + " RK4 steps to tabulate, at most " +
            std::to_string(kGuidancePeriodStepsMax) +
            " (the bounded evaluation of a late joiner or a re-engagement, docs/CORE.md): use freq = 0 " +
            "(a constant rate) or a frequency at least " +
            format_double(std::fabs(p.omega_freq) * double(tab.n_steps) / double(kGuidancePeriodStepsMax)) +
            " rad/s");
    }
  }
  if (p.kind == GuidanceKind::Slew) {
    if (!p.slew_target.allFinite() || p.slew_target.norm() > 1.0 + 1e-12)
      errs.push_back("slew_target must be finite with |slew_target| <= 1, got " +
                     format_matrix(p.slew_target));
    if (!std::isfinite(p.slew_start))
      errs.push_back("slew_start must be finite, got " + format_double(p.slew_start));
    if (!(p.slew_duration > 0.0 && std::isfinite(p.slew_duration)))
      errs.push_back("slew_duration must be > 0 and finite, got " + format_double(p.slew_duration));
  }
  if (p.kind == GuidanceKind::Table) {
    const int n = table_size(p);
    if (n < 2 || n > kGuidanceTableMax) {
      errs.push_back("a table reference needs 2.." + std::to_string(kGuidanceTableMax) +
                     " samples, got " + std::to_string(n));
      return errs;
    }
    if (p.table_sigma.rows() != n || p.table_omega.rows() != n) {
      errs.push_back("table_sigma and table_omega must have one row per time (" + std::to_string(n) +
                     "), got " + std::to_string(p.table_sigma.rows()) + " and " +
                     std::to_string(p.table_omega.rows()));
      return errs;
    }
    for (int k = 0; k < n; ++k) {
      if (!std::isfinite(p.table_t(k)) || (k > 0 && !(p.table_t(k) > p.table_t(k - 1)))) {
        errs.push_back("table_t must be finite and strictly increasing, got " +
                       format_double(p.table_t(k)) + " at sample " + std::to_string(k));
        break;
      }
    }
    append_vec3_errors(errs, "table_sigma", p.table_sigma, true);
    append_vec3_errors(errs, "table_omega", p.table_omega, false);
  }
  return errs;
}

bool guidance_integrated(const GuidanceParams& p) { return p.kind == GuidanceKind::Paper; }

Vec3 slew_axis(const GuidanceParams& p) {
  const Vec3 d = mrp_subtract(p.slew_target, p.sigma_d0);
  const double n = d.norm();
  return n > 0.0 ? Vec3(d / n) : Vec3(Vec3::Zero());
}

double slew_angle(const GuidanceParams& p) {
  return 4.0 * std::atan(mrp_subtract(p.slew_target, p.sigma_d0).norm());
}

Vec3 sigma_d(const GuidanceParams& p, double t) {
  switch (p.kind) {
    case GuidanceKind::Hold:
      return p.sigma_d0;
    case GuidanceKind::Slew: {
      if (!(t > p.slew_start)) return p.sigma_d0;
      if (t >= p.slew_start + p.slew_duration) return mrp_short(p.slew_target);
      const SlewAngle a = slew_profile(p, slew_angle(p), t);
      return compose(std::tan(0.25 * a.theta) * slew_axis(p), p.sigma_d0);
    }
    case GuidanceKind::Table: {
      const int n = checked_table_size(p);
      if (!(t > p.table_t(0))) return p.table_sigma.row(0).transpose();
      if (t >= p.table_t(n - 1)) return p.table_sigma.row(n - 1).transpose();
      const int k = table_segment(p, t);
      const Vec3 s0 = p.table_sigma.row(k).transpose();
      const Vec3 d = mrp_subtract(p.table_sigma.row(k + 1).transpose(), s0);
      const double nd = d.norm();
      if (nd == 0.0) return s0;
      // SLERP: the fraction tau of the short rotation's angle 4 atan|d|
      const double tau = (t - p.table_t(k)) / (p.table_t(k + 1) - p.table_t(k));
      return compose((std::tan(tau * std::atan(nd)) / nd) * d, s0);
    }
    case GuidanceKind::Paper:
      break;
  }
  throw std::invalid_argument(
      "sigma_d: the paper's reference is integrated, not a closed form (use Guidance)");
}

Vec3 omega_d(const GuidanceParams& p, double t) {
  switch (p.kind) {
    case GuidanceKind::Hold:
      return Vec3::Zero();
    case GuidanceKind::Slew:
      return slew_profile(p, slew_angle(p), t).rate * slew_axis(p);
    case GuidanceKind::Table: {
      const int n = checked_table_size(p);
      if (t < p.table_t(0) || t > p.table_t(n - 1)) return Vec3::Zero();
      if (t == p.table_t(n - 1)) return p.table_omega.row(n - 1).transpose();
      const int k = table_segment(p, t);
      const double tau = (t - p.table_t(k)) / (p.table_t(k + 1) - p.table_t(k));
      const Vec3 w0 = p.table_omega.row(k).transpose();
      return w0 + tau * (Vec3(p.table_omega.row(k + 1).transpose()) - w0);
    }
    case GuidanceKind::Paper:
      break;
  }
  const double w = p.omega_freq;
  return p.omega_bias + p.omega_cos * std::cos(w * t) + p.omega_sin * std::sin(w * t);
}

Vec3 omega_d_dot(const GuidanceParams& p, double t) {
  switch (p.kind) {
    case GuidanceKind::Hold:
      return Vec3::Zero();
    case GuidanceKind::Slew:
      return slew_profile(p, slew_angle(p), t).accel * slew_axis(p);
    case GuidanceKind::Table: {
      const int n = checked_table_size(p);
      if (t < p.table_t(0) || t > p.table_t(n - 1)) return Vec3::Zero();
      const int k = std::min(table_segment(p, t), n - 2);  // t_n-1: the last segment's slope
      return (Vec3(p.table_omega.row(k + 1).transpose()) - Vec3(p.table_omega.row(k).transpose())) /
             (p.table_t(k + 1) - p.table_t(k));
    }
    case GuidanceKind::Paper:
      break;
  }
  const double w = p.omega_freq;
  return w * (-p.omega_cos * std::sin(w * t) + p.omega_sin * std::cos(w * t));
}

Vec3 guidance_rk4_step(const GuidanceParams& p, const Vec3& s, double t, double h) {
  const Vec3 w_mid = omega_d(p, t + 0.5 * h);
  const Vec3 k1 = mrp_G(s) * omega_d(p, t);
  const Vec3 k2 = mrp_G(s + 0.5 * h * k1) * w_mid;
  const Vec3 k3 = mrp_G(s + 0.5 * h * k2) * w_mid;
  const Vec3 k4 = mrp_G(s + h * k3) * omega_d(p, t + h);
  return mrp_short(s + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4));
}

GuidancePeriodTable guidance_period_table(const GuidanceParams& p) {
  GuidancePeriodTable tab;
  if (!guidance_integrated(p)) return tab;
  const double f = std::fabs(p.omega_freq);
  const double amp = p.omega_cos.norm() + p.omega_sin.norm();
  if (f == 0.0 || amp == 0.0) {  // omega_DN_D(t) = omega_d(p, 0) for all t
    tab.kind = GuidancePeriodTable::Constant;
    tab.omega = omega_d(p, 0.0);
    return tab;
  }
  tab.kind = GuidancePeriodTable::Periodic;
  tab.period = 2.0 * kPi / f;
  const double rate = std::max(p.omega_bias.norm() + amp, f);
  const double n = std::ceil(tab.period * rate / kGuidanceTableStepAngle);
  if (!(n <= double(kGuidancePeriodStepsMax))) {  // over the budget: reported by validate()
    tab.n_steps = n < 9e18 ? static_cast<long long>(n) : (1LL << 62);
    return tab;
  }
  const long long steps = std::max(1LL, static_cast<long long>(n));
  tab.stride = static_cast<int>(std::max<long long>(
      32, (steps + kGuidanceTableAnchorsMax - 1) / kGuidanceTableAnchorsMax));
  tab.anchors = static_cast<int>((steps + tab.stride - 1) / tab.stride);
  tab.n_steps = static_cast<long long>(tab.anchors) * tab.stride;
  tab.h = tab.period / double(tab.n_steps);
  return tab;
}

Guidance::Guidance(const GuidanceParams& p, double max_step) : p_(p), max_step_(max_step) {
  throw_if_errors("GuidanceParams", validate(p));
  if (!(max_step > 0.0 && std::isfinite(max_step)))
    throw std::invalid_argument("Guidance max_step must be > 0, got " + format_double(max_step));
  sigma_ = guidance_integrated(p_) ? p_.sigma_d0 : sigma_d(p_, 0.0);
  table_ = guidance_period_table(p_);
  // allocated here, filled at the first seek or prepare(): a step never allocates
  if (table_.kind == GuidancePeriodTable::Periodic)
    anchors_.assign(static_cast<std::size_t>(table_.anchors) + 1, Vec3::Zero());
}

void Guidance::reset(double t0) {
  if (!guidance_integrated(p_)) {
    t_ = t0;
    sigma_ = sigma_d(p_, t0);
    return;
  }
  // The reference is a function of time on one time line: a reset at or
  // after the current time continues from where the reference is (a
  // re-engagement an hour into a run costs the steps since the last call,
  // not an hour of RK4 steps); a reset before it starts the time line again
  // from t = 0 (a new plant session). Either way advance() bounds the work.
  if (!(t0 >= t_)) {
    t_ = 0.0;
    sigma_ = p_.sigma_d0;
  }
  if (t0 > t_) advance(t0);
  t_ = t0;
}

void Guidance::advance(double t) {
  if (!(t > t_)) return;
  if (!guidance_integrated(p_)) {
    sigma_ = sigma_d(p_, t);
    t_ = t;
    return;
  }
  const double n = std::ceil((t - t_) / max_step_ - 1e-9);
  if (n > double(kGuidanceMaxCatchUp)) {  // too far for the time line: from the definition at t
    seek(t);
    return;
  }
  integrate(t, n < 1.0 ? 1 : static_cast<int>(n));
}

void Guidance::integrate(double t, int n) {
  const double h = (t - t_) / n;
  for (int i = 0; i < n; ++i) sigma_ = guidance_rk4_step(p_, sigma_, t_ + i * h, h);
  rk4_steps_ += static_cast<std::uint64_t>(n);
  t_ = t;
}

void Guidance::prepare() {
  if (built_ || table_.kind != GuidancePeriodTable::Periodic) return;
  // Psi(t), the rotation of D from t = 0 (sigma_DN(t) = Psi(t) sigma_d0):
  // the same kinematics from the identity, sampled every stride steps.
  Vec3 s = Vec3::Zero();
  anchors_[0] = s;
  long long i = 0;
  for (int j = 1; j <= table_.anchors; ++j) {
    for (int k = 0; k < table_.stride; ++k, ++i)
      s = guidance_rk4_step(p_, s, double(i) * table_.h, table_.h);
    anchors_[static_cast<std::size_t>(j)] = s;
  }
  rk4_steps_ += static_cast<std::uint64_t>(table_.n_steps);
  built_ = true;
}

Vec3 Guidance::periodic_at(double t) {
  prepare();
  const GuidancePeriodTable& tb = table_;
  const double P = tb.period;
  const double k = std::floor(t / P);
  const double span_anchor = double(tb.stride) * tb.h;
  const double tau = t - k * P;
  double jd = std::floor(tau / span_anchor);
  if (!(jd >= 0.0)) jd = 0.0;
  if (jd > double(tb.anchors - 1)) jd = double(tb.anchors - 1);
  const int j = static_cast<int>(jd);
  const double t_a = k * P + jd * span_anchor;
  // M^k: the rotation over one period, k times (about its axis, angle k phi)
  const Vec3& sM = anchors_[static_cast<std::size_t>(tb.anchors)];
  const double nM = sM.norm();
  Vec3 Mk = Vec3::Zero();
  if (nM > 0.0 && k != 0.0) {
    const double psi = std::remainder(k * 4.0 * std::atan(nM), 2.0 * kPi);
    Mk = (std::tan(0.25 * psi) / nM) * sM;
  }
  Vec3 s = compose(anchors_[static_cast<std::size_t>(j)], compose(Mk, p_.sigma_d0));
  // from the anchor to t: at most stride (+1 for rounding) steps of <= h
  const double span = t - t_a;
  if (span != 0.0) {
    double nd = std::ceil(std::fabs(span) / tb.h - 1e-9);
    if (nd < 1.0) nd = 1.0;
    if (nd > double(tb.stride + 1)) nd = double(tb.stride + 1);
    const int n = static_cast<int>(nd);
    const double h = span / n;
    for (int i = 0; i < n; ++i) s = guidance_rk4_step(p_, s, t_a + i * h, h);
    rk4_steps_ += static_cast<std::uint64_t>(n);
  }
  return s;
}

void Guidance::seek(double t) {
  if (!std::isfinite(t))
    throw std::invalid_argument("Guidance::seek: t must be finite, got " + format_double(t));
  ++seeks_;
  if (!guidance_integrated(p_)) {
    sigma_ = sigma_d(p_, t);
  } else if (table_.kind == GuidancePeriodTable::Constant) {
    // rotation about the fixed axis of omega by |omega| t: Psi(t) = tan(angle / 4) e
    const double w = table_.omega.norm();
    const Vec3 rel = w > 0.0 ? Vec3((std::tan(0.25 * std::remainder(w * t, 2.0 * kPi)) / w) * table_.omega)
                             : Vec3(Vec3::Zero());
    sigma_ = compose(rel, p_.sigma_d0);
  } else {
    sigma_ = periodic_at(t);
  }
  t_ = t;
}

}  // namespace sc_rt
