// Declares a command kind that does not exist: refused at load.
#include <sc_rt/law.hpp>
struct BadCommand final : sc_rt::ControlLaw {
  explicit BadCommand(const sc_rt::LawSetup&) {}
  void reset(const sc_rt::LawInput&) override {}
  void step(const sc_rt::LawInput&, sc_rt::LawOutput&) override {}
};
SC_RT_LAW_PLUGIN("t-badcommand", BadCommand, "declares command 7")
extern "C" __attribute__((visibility("default"))) int sc_rt_law_command(void) { return 7; }
