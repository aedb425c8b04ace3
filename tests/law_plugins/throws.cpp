// Its constructor throws: the loader reports "construction failed: ...".
#include <sc_rt/law.hpp>
struct Throws final : sc_rt::ControlLaw {
  explicit Throws(const sc_rt::LawSetup&) { throw std::runtime_error("no gains for this spacecraft"); }
  void reset(const sc_rt::LawInput&) override {}
  void step(const sc_rt::LawInput&, sc_rt::LawOutput&) override {}
};
SC_RT_LAW_PLUGIN("t-throws", Throws, "throws at construction")
