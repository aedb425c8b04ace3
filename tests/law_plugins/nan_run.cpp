// A PD that returns NaN for t in [t_nan, t_nan + 1) s and throws at t_throw:
// SAFE zeros, FLAG_LAW_INVALID, re-engagement, and the run goes on.
#include <limits>
#include <sc_rt/law.hpp>
struct NanRun final : sc_rt::ControlLaw {
  explicit NanRun(const sc_rt::LawSetup& s)
      : Bp(s.model.B_pinv), t_nan(s.params.number("t_nan", 2.0)), t_throw(s.params.number("t_throw", -1.0)) {}
  void reset(const sc_rt::LawInput&) override { ++resets; }
  void step(const sc_rt::LawInput& in, sc_rt::LawOutput& out) override {
    if (in.t >= t_throw && in.t < t_throw + 0.05 && t_throw >= 0.0) throw std::runtime_error("glitch");
    out.u_cmd = -Bp * (0.05 * in.e.sigma_BD + 0.24 * in.e.omega_BD_B);
    if (in.t >= t_nan && in.t < t_nan + 1.0 - 1e-9) out.u_cmd(2) = std::numeric_limits<double>::quiet_NaN();
    out.telemetry[0] = resets;
  }
  std::vector<std::string> telemetry_names() const override { return {"resets"}; }
  sc_rt::Mat43 Bp;
  double t_nan, t_throw;
  double resets = 0;
};
SC_RT_LAW_PLUGIN("t-nan-run", NanRun, "NaN for one second")
