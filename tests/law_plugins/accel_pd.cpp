// A PD that commands wheel accelerations and declares nothing (what every
// plugin built before interface revision 1 is): its u_cmd is also its
// telemetry a1..a4, so a test reads the law's own output from the record.
#include <sc_rt/law.hpp>
struct AccelPd final : sc_rt::ControlLaw {
  explicit AccelPd(const sc_rt::LawSetup& s) : model(s.model) {}
  void reset(const sc_rt::LawInput&) override {}
  void step(const sc_rt::LawInput& in, sc_rt::LawOutput& out) override {
    // tau = -kp sigma_BD - kd omega_BD_B [N m]; a = B+ J0^-1 tau [rad/s^2]
    const sc_rt::Vec3 tau = -0.5 * in.e.sigma_BD - 5.0 * in.e.omega_BD_B;
    out.u_cmd = model.wheels_for_torque(tau);
    for (int i = 0; i < 4; ++i) out.telemetry[static_cast<std::size_t>(i)] = out.u_cmd(i);
  }
  std::vector<std::string> telemetry_names() const override { return {"a1", "a2", "a3", "a4"}; }
  sc_rt::LawModel model;
};
SC_RT_LAW_PLUGIN("t-accel-pd", AccelPd, "a PD commanding wheel accelerations, declaring nothing")
