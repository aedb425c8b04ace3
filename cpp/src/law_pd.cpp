// PD baseline: uc = -B+ (beta1 x1 + beta2 x2). Its parameters, from its own
// table ([laws.pd] of the scenario) through LawParams like any plugin's.
#include "sc_rt/controllers.hpp"

namespace sc_rt {

namespace {

// The defaults: designed by `sc-rt design scenarios/paper_fault_free.toml`
// (docs/DESIGN.md), critically damped with the 48.9 s settling time of the
// paper's slowest envelope.
const LawParams::Items& pd_defaults() {
  static const LawParams::Items d = {
      {"beta1", {0.05693}},  // [1/s^2] on sigma_BD
      {"beta2", {0.2386}},   // [1/s] on omega_BD_B
  };
  return d;
}

class PdLaw final : public ControlLaw {
 public:
  explicit PdLaw(const LawSetup& s)
      : Bp_(s.model.B_pinv),
        beta1_(s.params.positive("beta1", pd_defaults()[0].second[0])),
        beta2_(s.params.positive("beta2", pd_defaults()[1].second[0])) {}
  void reset(const LawInput&) override {}
  void step(const LawInput& in, LawOutput& out) override {
    out.u_cmd = -Bp_ * (beta1_ * in.e.sigma_BD + beta2_ * in.e.omega_BD_B);
    out.e1 = in.e.sigma_BD;
    out.e2 = in.e.omega_BD_B;
  }

 private:
  Mat43 Bp_;
  double beta1_, beta2_;
};

}  // namespace

void register_pd_law() {
  register_law("pd", "PD baseline on sigma_BD and omega_BD_B through B+",
               [](const LawSetup& s) { return std::make_unique<PdLaw>(s); }, pd_defaults());
}

}  // namespace sc_rt
