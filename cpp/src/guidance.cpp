#include "sc_rt/guidance.hpp"

#include <cmath>
#include <stdexcept>

#include "sc_rt/mrp.hpp"
#include "sc_rt/util.hpp"

namespace sc_rt {

std::vector<std::string> validate(const GuidanceParams& p) {
  std::vector<std::string> errs;
  if (!p.sigma_d0.allFinite() || p.sigma_d0.norm() > 1.0 + 1e-12)
    errs.push_back("sigma_d0 must be finite with |sigma_d0| <= 1, got " + format_matrix(p.sigma_d0));
  if (!(p.omega_bias.allFinite() && p.omega_cos.allFinite() && p.omega_sin.allFinite()))
    errs.push_back("omega_d amplitudes must be finite");
  if (!std::isfinite(p.omega_freq))
    errs.push_back("omega_d frequency must be finite, got " + format_double(p.omega_freq));
  return errs;
}

Vec3 omega_d(const GuidanceParams& p, double t) {
  const double w = p.omega_freq;
  return p.omega_bias + p.omega_cos * std::cos(w * t) + p.omega_sin * std::sin(w * t);
}

Vec3 omega_d_dot(const GuidanceParams& p, double t) {
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

Guidance::Guidance(const GuidanceParams& p, double max_step) : p_(p), max_step_(max_step) {
  throw_if_errors("GuidanceParams", validate(p));
  if (!(max_step > 0.0 && std::isfinite(max_step)))
    throw std::invalid_argument("Guidance max_step must be > 0, got " + format_double(max_step));
  sigma_ = p_.sigma_d0;
}

void Guidance::reset(double t0) {
  t_ = 0.0;
  sigma_ = p_.sigma_d0;
  if (t0 > 0.0) advance(t0);
  t_ = t0;
}

void Guidance::advance(double t) {
  if (!(t > t_)) return;
  const double span = t - t_;
  const int n = static_cast<int>(std::ceil(span / max_step_ - 1e-9));
  const double h = span / (n < 1 ? 1 : n);
  for (int i = 0; i < (n < 1 ? 1 : n); ++i) sigma_ = guidance_rk4_step(p_, sigma_, t_ + i * h, h);
  t_ = t;
}

}  // namespace sc_rt
