// Validates its parameter: gain must be > 0 (LawParamError names the key).
#include <sc_rt/law.hpp>
struct BadParam final : sc_rt::ControlLaw {
  explicit BadParam(const sc_rt::LawSetup& s) : gain(s.params.positive("gain", 1.0)) {}
  void reset(const sc_rt::LawInput&) override {}
  void step(const sc_rt::LawInput&, sc_rt::LawOutput&) override {}
  double gain;
};
SC_RT_LAW_PLUGIN("t-badparam", BadParam, "checks gain > 0")
