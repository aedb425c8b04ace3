// A PD law that allocates on the heap at every step (a std::vector and a
// std::string past the small-string limit): what tests/test_no_alloc.py's
// counter must see, the proof that it bites.
#include <string>
#include <vector>
#include <sc_rt/law.hpp>
struct Allocates final : sc_rt::ControlLaw {
  explicit Allocates(const sc_rt::LawSetup& s) : Bp(s.model.B_pinv) {}
  void reset(const sc_rt::LawInput&) override {}
  void step(const sc_rt::LawInput& in, sc_rt::LawOutput& out) override {
    std::vector<double> gains{0.05, 0.24};  // one allocation per step
    out.u_cmd = -Bp * (gains[0] * in.e.sigma_BD + gains[1] * in.e.omega_BD_B);
    label = std::string("a label longer than the small-string buffer at t = ") + std::to_string(in.t);
  }
  sc_rt::Mat43 Bp;
  std::string label;
};
SC_RT_LAW_PLUGIN("t-allocates", Allocates, "a PD that allocates at every step")
