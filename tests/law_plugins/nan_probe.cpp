// Always a NaN command: refused by the probe step at rest before any run.
#include <limits>
#include <sc_rt/law.hpp>
struct NanProbe final : sc_rt::ControlLaw {
  explicit NanProbe(const sc_rt::LawSetup&) {}
  void reset(const sc_rt::LawInput&) override {}
  void step(const sc_rt::LawInput&, sc_rt::LawOutput& out) override {
    out.u_cmd.setConstant(std::numeric_limits<double>::quiet_NaN());
  }
};
SC_RT_LAW_PLUGIN("t-nan-probe", NanProbe, "NaN always")
