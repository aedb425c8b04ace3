// Adaptive boundary-layer sliding mode (docs/CORE.md). Its parameters, from
// its own table ([laws.rft] of the scenario) through LawParams.
//   s = x2 + c x1
//   uc = B+ [ -A - c G(x1) x2 - k s - rho_hat sat(s / phi) ]
//   rho_hat_dot = gain |s| - leak rho_hat   (exact with |s| held over a period)
#include <cmath>

#include "sc_rt/controllers.hpp"
#include "sc_rt/mrp.hpp"

namespace sc_rt {

namespace {

// This project's values (the paper's RFT reference is not identified, docs/MODEL.md section 7).
const LawParams::Items& rft_defaults() {
  static const LawParams::Items d = {
      {"c", {0.2}},      // [1/s] sliding surface s = x2 + c x1
      {"k", {0.4}},      // [1/s] linear reaching gain
      {"gain", {0.5}},   // [1/s] adaptation gain of rho_hat_dot = gain |s| - leak rho_hat
      {"leak", {0.01}},  // [1/s] leakage (sigma-modification)
      {"phi", {1e-2}},   // [rad/s] boundary layer width (wider than s moves in one period)
      {"rho0", {0.0}},   // [rad/s^2] rho_hat(t0)
  };
  return d;
}

struct RftGains {
  double c, k, gain, leak, phi, rho0;
};

double at_least_zero(const LawParams& p, const std::string& key, double def) {
  const double v = p.number(key, def);
  if (!(v >= 0.0)) LawParams::fail(key, "must be >= 0, got " + LawParams::text(v));
  return v;
}

RftGains rft_gains(const LawParams& p) {
  auto d = [](int i) { return rft_defaults()[static_cast<std::size_t>(i)].second[0]; };
  return {p.positive("c", d(0)), p.positive("k", d(1)), at_least_zero(p, "gain", d(2)),
          at_least_zero(p, "leak", d(3)), p.positive("phi", d(4)), at_least_zero(p, "rho0", d(5))};
}

class RftLaw final : public ControlLaw {
 public:
  explicit RftLaw(const LawSetup& s) : Bp_(s.model.B_pinv), g_(rft_gains(s.params)) {}
  void reset(const LawInput& in) override {
    rho_ = g_.rho0;
    s_norm_prev_ = (in.e.omega_BD_B + g_.c * in.e.sigma_BD).norm();
  }
  void step(const LawInput& in, LawOutput& out) override {
    const TrackingErrors& e = in.e;
    const double dt = in.dt;
    if (dt > 0.0) {
      if (g_.leak > 0.0) {
        const double a = std::exp(-g_.leak * dt);
        rho_ = a * rho_ + (1.0 - a) / g_.leak * g_.gain * s_norm_prev_;
      } else {
        rho_ += dt * g_.gain * s_norm_prev_;
      }
    }
    const Vec3 s = e.omega_BD_B + g_.c * e.sigma_BD;
    const Vec3 sat_s = (s / g_.phi).cwiseMax(-1.0).cwiseMin(1.0);
    const Vec3 v = -e.A - g_.c * (mrp_G(e.sigma_BD) * e.omega_BD_B) - g_.k * s - rho_ * sat_s;
    out.u_cmd = Bp_ * v;
    out.e1 = e.sigma_BD;
    out.e2 = s;
    out.rho_hat = rho_;
    s_norm_prev_ = s.norm();
  }

 private:
  Mat43 Bp_;
  RftGains g_;
  double rho_ = 0.0;
  double s_norm_prev_ = 0.0;
};

}  // namespace

void register_rft_law() {
  register_law("rft", "adaptive boundary-layer sliding mode (RFT baseline)",
               [](const LawSetup& s) { return std::make_unique<RftLaw>(s); }, rft_defaults());
}

}  // namespace sc_rt
