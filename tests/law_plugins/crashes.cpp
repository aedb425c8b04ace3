// A PD whose process dies in step() at t >= t_crash (default 5 s): a real
// SIGSEGV, raised (dereferencing null would be undefined behaviour, which a
// compiler may remove). The bench must report the controller's death as a
// failed run, naming the signal and the time (issue #25).
#include <csignal>
#include <sc_rt/law.hpp>
struct Crashes final : sc_rt::ControlLaw {
  explicit Crashes(const sc_rt::LawSetup& s)
      : Bp(s.model.B_pinv), t_crash(s.params.number("t_crash", 5.0)),
        omega_x_below(s.params.number("omega_x_below", -1e300)) {}
  void reset(const sc_rt::LawInput&) override {}
  void step(const sc_rt::LawInput& in, sc_rt::LawOutput& out) override {
    // a crash at t_crash, or (a Monte Carlo draw) at the first step when the body rate's x is below omega_x_below
    if (in.t >= t_crash - 1e-9 || (in.t < 1e-9 && in.m.omega_BN_B(0) < omega_x_below)) std::raise(SIGSEGV);
    out.u_cmd = -Bp * (0.05 * in.e.sigma_BD + 0.24 * in.e.omega_BD_B);
  }
  sc_rt::Mat43 Bp;
  double t_crash, omega_x_below;
};
SC_RT_LAW_PLUGIN("t-crashes", Crashes, "SIGSEGV in step at t_crash")
