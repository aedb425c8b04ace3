// Quaternion feedback regulator: B. Wie, H. Weiss, A. Arapostathis,
// "Quaternion feedback regulator for spacecraft eigenaxis rotations",
// J. Guidance, Control, and Dynamics 12(3), 1989, 375-380.
//
//   tau = -K q_e - C omega_e + omega x h,   K = k J, C = c J
//
// q_e: vector part of the attitude-error quaternion of B relative to D
// (q0 >= 0: the short rotation), omega_e = omega_BD_B. With K and C
// proportional to the inertia (the paper's eigenaxis condition) and the
// gyroscopic term cancelled, J omega_e_dot = -k J q_e - c J omega_e: a
// rest-to-rest rotation stays about the eigenaxis of the initial error.
// h = J omega + Cbar Jw Omega is the whole angular momentum (the paper's
// omega x J omega plus the wheels' share). J is the controller's J0. The body
// torque goes to the four wheels through B+ like the built-in laws:
// u_cmd = B+ J0^-1 tau.
//
// Parameters ([controller.params]): k [1/s^2] (default 0.08), c [1/s]
// (default 0.4), gyro (1: cancel omega x h, default; 0: omit it).
// Written from docs/LAWS.md only; links nothing of the core.
#include <sc_rt/law.hpp>

namespace {

class QuaternionFeedback final : public sc_rt::ControlLaw {
 public:
  explicit QuaternionFeedback(const sc_rt::LawSetup& s)
      : model_(s.model),
        k_(s.params.positive("k", 0.08)),
        c_(s.params.positive("c", 0.4)),
        gyro_(s.params.number("gyro", 1.0)) {
    if (gyro_ != 0.0 && gyro_ != 1.0) sc_rt::LawParams::fail("gyro", "must be 0 or 1");
  }

  void reset(const sc_rt::LawInput&) override {}

  void step(const sc_rt::LawInput& in, sc_rt::LawOutput& out) override {
    const sc_rt::Vec3& s = in.e.sigma_BD;  // MRP, |s| <= 1
    const double s2 = s.squaredNorm();
    const double q0 = (1.0 - s2) / (1.0 + s2);
    const sc_rt::Vec3 q = (2.0 / (1.0 + s2)) * s;  // vector part of the error quaternion
    const sc_rt::Vec3& w = in.e.omega_BD_B;
    const sc_rt::Mat3& J = model_.J0;
    sc_rt::Vec3 tau = -k_ * (J * q) - c_ * (J * w);
    if (gyro_ != 0.0) {
      const sc_rt::Vec3& W = in.m.omega_BN_B;
      const sc_rt::Vec3 h = J * W + model_.Cbar * model_.Jw.cwiseProduct(in.m.wheel_speed);
      tau += W.cross(h);
    }
    out.u_cmd = model_.wheels_for_torque(tau);
    out.e1 = q;
    out.e2 = w;
    out.telemetry[0] = q0;
    out.telemetry[1] = tau.norm();
  }

  std::vector<std::string> telemetry_names() const override { return {"q0", "torque_norm [N m]"}; }

 private:
  sc_rt::LawModel model_;
  double k_, c_, gyro_;
};

}  // namespace

SC_RT_LAW_PLUGIN("quaternion-feedback", QuaternionFeedback,
                 "Wie, Weiss & Arapostathis 1989 quaternion feedback regulator (eigenaxis rotations)")
