// A PD whose step never returns from t >= t_hang (default 0.5 s): the
// bench must stop a contained run of it after its stall timeout and name
// the law (issue 40 item 7, sc_rt.isolate).
#include <atomic>
#include <sc_rt/law.hpp>
struct Hangs final : sc_rt::ControlLaw {
  explicit Hangs(const sc_rt::LawSetup& s) : Bp(s.model.B_pinv), t_hang(s.params.number("t_hang", 0.5)) {}
  void reset(const sc_rt::LawInput&) override {}
  void step(const sc_rt::LawInput& in, sc_rt::LawOutput& out) override {
    static std::atomic<bool> forever{true};  // an atomic load the compiler cannot remove
    while (in.t >= t_hang - 1e-9 && forever.load(std::memory_order_relaxed)) {
    }
    out.u_cmd = -Bp * (0.05 * in.e.sigma_BD + 0.24 * in.e.omega_BD_B);
  }
  sc_rt::Mat43 Bp;
  double t_hang;
};
SC_RT_LAW_PLUGIN("t-hangs", Hangs, "never returns from step at t_hang")
