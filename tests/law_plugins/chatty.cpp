// A PD law that writes 16 KB to stderr at every step: its controller must
// neither block on the pipe nor keep more than the bench's cap of it
// (tests/test_child_output.py).
#include <cstdio>
#include <cstring>
#include <sc_rt/law.hpp>
struct Chatty final : sc_rt::ControlLaw {
  explicit Chatty(const sc_rt::LawSetup& s) : Bp(s.model.B_pinv) { std::memset(line, 'x', sizeof line - 1); }
  void reset(const sc_rt::LawInput&) override {}
  void step(const sc_rt::LawInput& in, sc_rt::LawOutput& out) override {
    out.u_cmd = -Bp * (0.05 * in.e.sigma_BD + 0.24 * in.e.omega_BD_B);
    for (int i = 0; i < 16; ++i) std::fputs(line, stderr);
  }
  sc_rt::Mat43 Bp;
  char line[1024] = {};
};
SC_RT_LAW_PLUGIN("t-chatty", Chatty, "a PD that writes 16 KB to stderr at every step")
