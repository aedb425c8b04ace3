// The paper's law (docs/MODEL.md section 7), two registry entries:
//   dsc-ppc: (36), (37), corrected (41), anti-windup (42), observer (22)
//   dsc    : the same with e1 = x1, r = I and no chi_dot term
// Parameters: the law's own table ([laws.dsc-ppc] / [laws.dsc] of the
// scenario) through LawParams, like any plugin's: the DSC gains and the
// observer's (neso_*). The envelope is the controller's ([controller.ppc]).
#include <cmath>

#include "sc_rt/controllers.hpp"
#include "sc_rt/mrp.hpp"

namespace sc_rt {

namespace {

// The paper's values (section 4, docs/MODEL.md section 8).
const LawParams::Items& dsc_defaults() {
  static const LawParams::Items d = {
      {"k1", {0.1}},    // [1/s] (36)
      {"k2", {4.0}},    // [1/s] (41)
      {"k3", {0.01}},   // [-] (41) anti-windup coupling
      {"k4", {22.0}},   // [1/s] (42)
      {"k6", {1.0}},    // [-] Theorem 1 only
      {"tau", {0.1}},   // [s] filter time constant (37)
      {"neso_k1", {0.2, 0.2, 0.2}},     // [-] kappa1 of the observer (22)
      {"neso_k2", {0.03, 0.03, 0.03}},  // [-] kappa2
      {"neso_k3", {0.08, 0.08, 0.08}},  // [-] kappa3
      {"neso_k4", {0.06, 0.06, 0.06}},  // [-] kappa4
      {"neso_alpha", {0.7}},            // [-] in [0.5, 1]
      {"neso_substeps", {1}},           // RK4 steps of the observer per control period
      {"neso_init_from_measurement", {0}},  // 1: z1(t0) = x2(t0); 0: z1(t0) = 0 (the paper)
  };
  return d;
}

struct DscGains {
  double k1, k2, k3, k4, k6, tau;
};

const std::vector<double>& dsc_default(const char* key) {
  for (const auto& kv : dsc_defaults())
    if (kv.first == key) return kv.second;
  throw std::logic_error(std::string("no default for ") + key);
}

DscGains dsc_gains(const LawParams& p) {
  auto d = [](const char* k) { return dsc_default(k)[0]; };
  const double k3 = p.number("k3", d("k3"));
  if (!(k3 >= 0.0)) LawParams::fail("k3", "must be >= 0, got " + LawParams::text(k3));
  return {p.positive("k1", d("k1")), p.positive("k2", d("k2")), k3, p.positive("k4", d("k4")),
          p.positive("k6", d("k6")), p.positive("tau", d("tau"))};
}

Vec3 vec3_default(const char* key) {
  const std::vector<double>& v = dsc_default(key);
  return Vec3(v[0], v[1], v[2]);
}

NesoParams neso_params(const LawParams& p) {
  NesoParams n;
  n.k1 = p.vec3("neso_k1", vec3_default("neso_k1"));
  n.k2 = p.vec3("neso_k2", vec3_default("neso_k2"));
  n.k3 = p.vec3("neso_k3", vec3_default("neso_k3"));
  n.k4 = p.vec3("neso_k4", vec3_default("neso_k4"));
  n.alpha = p.number("neso_alpha", dsc_default("neso_alpha")[0]);
  const double sub = p.number("neso_substeps", dsc_default("neso_substeps")[0]);
  if (!(sub >= 1.0 && sub <= 10000.0 && sub == std::floor(sub)))
    LawParams::fail("neso_substeps", "must be an integer in [1, 10000], got " + LawParams::text(sub));
  n.substeps = static_cast<int>(sub);
  const double init = p.number("neso_init_from_measurement", dsc_default("neso_init_from_measurement")[0]);
  if (!(init == 0.0 || init == 1.0))
    LawParams::fail("neso_init_from_measurement", "must be 0 or 1 (false or true), got " + LawParams::text(init));
  n.init_from_measurement = init == 1.0;
  const char* keys[4] = {"neso_k1", "neso_k2", "neso_k3", "neso_k4"};
  const Vec3* ks[4] = {&n.k1, &n.k2, &n.k3, &n.k4};
  for (int i = 0; i < 4; ++i)
    if (ks[i]->minCoeff() <= 0.0) LawParams::fail(keys[i], "must be > 0 on every axis");
  if (!(n.alpha >= 0.5 && n.alpha <= 1.0))
    LawParams::fail("neso_alpha", "must be in [0.5, 1], got " + LawParams::text(n.alpha));
  return n;
}

class DscLaw final : public ControlLaw {
 public:
  DscLaw(const LawSetup& s, bool use_ppc)
      : model_(s.model), g_(dsc_gains(s.params)), neso_p_(neso_params(s.params)), use_ppc_(use_ppc),
        neso_(neso_p_) {}

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
               [](const LawSetup& s) { return std::make_unique<DscLaw>(s, true); }, dsc_defaults());
  register_law("dsc", "dynamic surface control with NESO, no prescribed performance",
               [](const LawSetup& s) { return std::make_unique<DscLaw>(s, false); }, dsc_defaults());
}

}  // namespace sc_rt
