// PD baseline: uc = -B+ (beta1 x1 + beta2 x2). Gains: ControllerConfig::pd.
#include "sc_rt/controllers.hpp"

namespace sc_rt {

namespace {

class PdLaw final : public ControlLaw {
 public:
  explicit PdLaw(const LawSetup& s) : Bp_(s.model.B_pinv), g_(s.config->pd) {}
  void reset(const LawInput&) override {}
  void step(const LawInput& in, LawOutput& out) override {
    out.u_cmd = -Bp_ * (g_.beta1 * in.e.sigma_BD + g_.beta2 * in.e.omega_BD_B);
    out.e1 = in.e.sigma_BD;
    out.e2 = in.e.omega_BD_B;
  }

 private:
  Mat43 Bp_;
  PdGains g_;
};

}  // namespace

void register_pd_law() {
  register_law("pd", "PD baseline on sigma_BD and omega_BD_B through B+",
               [](const LawSetup& s) { return std::make_unique<PdLaw>(s); });
}

}  // namespace sc_rt
