// A PD that fails outside step(): its reset throws at every re-engagement
// (the first engagement passes), or its after() throws at t_after, and it
// returns NaN for t in [t_nan, t_nan + 0.25) s (a SAFE step: the next step re-engages,
// calling reset). Every failure must be contained (SAFE + FLAG_LAW_INVALID,
// counted and named) and the run must go on (issue #25).
#include <limits>
#include <stdexcept>
#include <sc_rt/law.hpp>
struct ThrowsIn final : sc_rt::ControlLaw {
  explicit ThrowsIn(const sc_rt::LawSetup& s)
      : Bp(s.model.B_pinv), t_nan(s.params.number("t_nan", 2.0)),
        reset_throws(s.params.number("reset_throws", 1.0)), t_after(s.params.number("t_after", -1.0)),
        omega_x_below(s.params.number("omega_x_below", -1e300)) {}
  void reset(const sc_rt::LawInput& in) override {
    if (resets++ > 0 && reset_throws > 0.0) throw std::runtime_error("reset exploded at re-engagement");
    // a Monte Carlo draw: the engagement's reset throws when the body rate's x is below omega_x_below
    if (in.m.omega_BN_B(0) < omega_x_below) throw std::runtime_error("reset exploded on this draw");
  }
  void step(const sc_rt::LawInput& in, sc_rt::LawOutput& out) override {
    out.u_cmd = -Bp * (0.05 * in.e.sigma_BD + 0.24 * in.e.omega_BD_B);
    if (in.t >= t_nan - 1e-9 && in.t < t_nan + 0.25) out.u_cmd(0) = std::numeric_limits<double>::quiet_NaN();
    t_last = in.t;
  }
  void after(const sc_rt::Vec4&, const sc_rt::Vec4&) override {
    if (t_after >= 0.0 && t_last >= t_after - 1e-9 && t_last < t_after + 0.05) throw std::runtime_error("after exploded");
  }
  sc_rt::Mat43 Bp;
  double t_nan, reset_throws, t_after, omega_x_below;
  double t_last = 0.0;
  int resets = 0;
};
SC_RT_LAW_PLUGIN("t-throws-in", ThrowsIn, "throws in reset at re-engagement, or in after")
