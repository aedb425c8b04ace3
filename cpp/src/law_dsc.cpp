// The paper's law (docs/MODEL.md section 7), two registry entries:
//   dsc-ppc: (36), (37), corrected (41), anti-windup (42), observer (22)
//   dsc    : the same with e1 = x1, r = I and no chi_dot term
// Gains: ControllerConfig::dsc, ::neso, ::ppc (the scenario's [controller.*]).
#include <cmath>

#include "sc_rt/controllers.hpp"
#include "sc_rt/mrp.hpp"

namespace sc_rt {

namespace {

class DscLaw final : public ControlLaw {
 public:
  DscLaw(const LawSetup& s, bool use_ppc)
      : model_(s.model), g_(s.config->dsc), neso_p_(s.config->neso), use_ppc_(use_ppc),
        neso_(s.config->neso) {}

  void reset(const LawInput& in) override {
    Vec3 e1, r;
    x2bar_prev_ = virtual_control(in.e, in.ppc, e1, r);  // in.ppc is at t_engaged = 0
    x2d_ = x2bar_prev_;  // (37): x2d(0) = x2bar(0)
    vs_.setZero();       // (42): vs(0) = 0
    du_prev_.setZero();
    neso_.reset(neso_p_.init_from_measurement ? in.e.omega_BD_B : Vec3::Zero(), Vec3::Zero());
    A_prev_ = in.e.A;
    x2_prev_ = in.e.omega_BD_B;
  }

  void step(const LawInput& in, LawOutput& out) override {
    const TrackingErrors& e = in.e;
    const double dt = in.dt;
    const Mat34& B = model_.B;
    if (dt > 0.0) {
      // Observer (22) over the period just ended: B sat(uc) held, A and x2 linear.
      neso_.update(dt, A_prev_, e.A, x2_prev_, e.omega_BD_B, B * in.u_sat_prev);
      // Filter (37) and compensator (42) are linear with inputs held over the
      // period: exact discretisation.
      const double a = std::exp(-dt / g_.tau);
      x2d_ = a * x2d_ + (1.0 - a) * x2bar_prev_;
      const double b = std::exp(-g_.k4 * dt);
      vs_ = b * vs_ + ((1.0 - b) / g_.k4) * du_prev_;
    }
    Vec3 e1, r;
    const Vec3 x2bar = virtual_control(e, in.ppc, e1, r);
    const Vec3 x2d_dot = (x2bar - x2d_) / g_.tau;  // (37) at t_k
    const Vec3 e2 = e.omega_BD_B - x2d_;           // (27)
    const Mat3 G = mrp_G(e.sigma_BD);
    // (41), corrected (erratum 1): + x2d_dot
    const Vec3 v = -e.A - g_.k2 * e2 - G.transpose() * r.cwiseProduct(e1) - g_.k3 * (B * vs_) -
                   neso_.z2() + x2d_dot;
    out.u_cmd = model_.B_pinv * v;
    out.e1 = e1;
    out.e2 = e2;
    out.z1 = neso_.z1();
    out.z2 = neso_.z2();
    out.x2d = x2d_;
    out.vs = vs_;
    x2bar_prev_ = x2bar;
    A_prev_ = e.A;
    x2_prev_ = e.omega_BD_B;
  }

  void after(const Vec4& u_cmd, const Vec4& u_sat) override { du_prev_ = u_sat - u_cmd; }  // (42)

 private:
  // Virtual control (36): x2bar = -(r G)^-1 (k1 e1 - r Lambda chi_dot)
  //                             = -G^-1 (k1 r^-1 e1 - Lambda chi_dot).
  Vec3 virtual_control(const TrackingErrors& e, const PpcResult& p, Vec3& e1, Vec3& r) const {
    const Mat3 Ginv = mrp_G_inverse(e.sigma_BD);
    if (!use_ppc_) {  // DSC: e1 = x1, r = I, no chi_dot term
      e1 = e.sigma_BD;
      r.setOnes();
      return -Ginv * (g_.k1 * e1);
    }
    e1 = p.e1;
    r = p.r;
    return -Ginv * (g_.k1 * e1.cwiseQuotient(r) - p.lambda.cwiseProduct(p.chi_dot));
  }

  LawModel model_;
  DscGains g_;
  NesoParams neso_p_;
  bool use_ppc_;
  Neso neso_;
  Vec3 x2d_ = Vec3::Zero();
  Vec3 x2bar_prev_ = Vec3::Zero();
  Vec4 vs_ = Vec4::Zero();
  Vec4 du_prev_ = Vec4::Zero();
  Vec3 A_prev_ = Vec3::Zero();
  Vec3 x2_prev_ = Vec3::Zero();
};

}  // namespace

void register_dsc_laws() {
  register_law("dsc-ppc", "dynamic surface control with prescribed performance and NESO (the paper's law)",
               [](const LawSetup& s) { return std::make_unique<DscLaw>(s, true); });
  register_law("dsc", "dynamic surface control with NESO, no prescribed performance",
               [](const LawSetup& s) { return std::make_unique<DscLaw>(s, false); });
}

}  // namespace sc_rt
