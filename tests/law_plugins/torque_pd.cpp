// The same PD commanding motor torques Jw a [N m] (SC_RT_LAW_COMMAND), its
// u_cmd also its telemetry tau1..tau4.
#include <sc_rt/law.hpp>
struct TorquePd final : sc_rt::ControlLaw {
  explicit TorquePd(const sc_rt::LawSetup& s) : model(s.model) {}
  void reset(const sc_rt::LawInput&) override {}
  void step(const sc_rt::LawInput& in, sc_rt::LawOutput& out) override {
    const sc_rt::Vec3 tau = -0.5 * in.e.sigma_BD - 5.0 * in.e.omega_BD_B;
    out.u_cmd = model.Jw.cwiseProduct(model.wheels_for_torque(tau));
    for (int i = 0; i < 4; ++i) out.telemetry[static_cast<std::size_t>(i)] = out.u_cmd(i);
  }
  std::vector<std::string> telemetry_names() const override { return {"tau1", "tau2", "tau3", "tau4"}; }
  sc_rt::LawModel model;
};
SC_RT_LAW_PLUGIN("t-torque-pd", TorquePd, "a PD commanding motor torques")
SC_RT_LAW_COMMAND(sc_rt::LawCommand::Torque)
