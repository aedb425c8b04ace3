// The right version but another compiler/ABI fingerprint.
#include <sc_rt/law.hpp>
struct Fp final : sc_rt::ControlLaw {
  explicit Fp(const sc_rt::LawSetup&) {}
  void reset(const sc_rt::LawInput&) override {}
  void step(const sc_rt::LawInput&, sc_rt::LawOutput&) override {}
};
extern "C" __attribute__((visibility("default"))) int sc_rt_law_api_version(void) { return SC_RT_LAW_API_VERSION; }
extern "C" __attribute__((visibility("default"))) const sc_rt::LawPluginInfo* sc_rt_law_plugin(void) {
  static const sc_rt::LawPluginInfo info{SC_RT_LAW_API_VERSION, "api-1 othercc-3 cxxabi-other", "t-fingerprint", "",
                                         [](const sc_rt::LawSetup& s) -> sc_rt::ControlLaw* { return new Fp(s); }};
  return &info;
}
