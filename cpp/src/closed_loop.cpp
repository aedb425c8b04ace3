#include "sc_rt/closed_loop.hpp"

#include <memory>
#include <stdexcept>

namespace sc_rt {

namespace {
template <typename V>
void put(std::vector<double>& dst, int row, const V& v) {
  for (int i = 0; i < v.size(); ++i) dst[static_cast<std::size_t>(row * v.size() + i)] = v(i);
}
bool finite(const PlantState& x) {
  return x.sigma_BN.allFinite() && x.omega_BN_B.allFinite() && x.wheel_speed.allFinite();
}
}  // namespace

ClosedLoopResult simulate_closed_loop(const ControllerConfig& cfg, const PlantParams& plant,
                                      const ActuatorParams& act, const PlantState& x0, int n_ctrl,
                                      int n_sub, double rate, const NavConfig* nav) {
  if (n_ctrl < 0 || n_sub < 1 || !(rate > 0.0))
    throw std::invalid_argument("simulate_closed_loop: need n_ctrl >= 0, n_sub >= 1, rate > 0");
  const auto ctl = Controller::create(cfg);
  const std::size_t n = static_cast<std::size_t>(n_ctrl) + 1;
  ClosedLoopResult r;
  r.t.resize(n);
  for (auto* v : {&r.sigma_BN, &r.omega_BN_B, &r.sigma_DN, &r.sigma_BD, &r.omega_BD_B, &r.z1, &r.z2,
                  &r.delta2, &r.chi, &r.lam, &r.e1, &r.e2})
    v->resize(3 * n);
  for (auto* v : {&r.wheel_speed, &r.u_cmd, &r.u_sat, &r.wheel_accel, &r.vs}) v->resize(4 * n);
  r.flags.resize(n);
  r.ctrl_mode.resize(n);
  std::unique_ptr<Navigation> nv;
  if (nav) {
    nv = std::make_unique<Navigation>(*nav);
    for (auto* v : {&r.sigma_BN_est, &r.bias_est, &r.bias_true, &r.att_est_error, &r.innovation})
      v->resize(3 * n);
    r.P_diag.resize(6 * n);
    r.nis.resize(n);
  }

  const double h = 1.0 / (rate * n_sub);
  PlantState x = x0;
  NavTelemetry tel;
  if (nv) {
    nv->reset(x);
    nv->tick(0, 0.0, x);
    ctl->reset(nv->measure(0.0, x));
  } else {
    ctl->reset(Measurement{0.0, x.sigma_BN, x.omega_BN_B, x.wheel_speed});
  }
  const std::int64_t nsub64 = n_sub;
  std::int64_t next = nv ? nv->next_tick(0) : 0;  // a tick with nothing due changes nothing: skip it
  for (int k = 0; k <= n_ctrl; ++k) {
    const double t = k / rate;
    if (nv && k > 0 && k * nsub64 == next) {
      nv->tick(next, t, x);
      next = nv->next_tick(next);
    }
    const Command c = ctl->step(nv ? nv->measure(t, x, &tel)
                                   : Measurement{t, x.sigma_BN, x.omega_BN_B, x.wheel_speed});
    const WheelOutput w = wheel_accel(act, t, c.u_cmd, x.wheel_speed);
    r.t[static_cast<std::size_t>(k)] = t;
    put(r.sigma_BN, k, x.sigma_BN);
    put(r.omega_BN_B, k, x.omega_BN_B);
    put(r.wheel_speed, k, x.wheel_speed);
    put(r.u_cmd, k, c.u_cmd);
    put(r.u_sat, k, c.u_sat);
    put(r.wheel_accel, k, w.accel);
    put(r.delta2, k, lumped_disturbance(plant, t, x, w.u_sat, w.accel));
    put(r.sigma_DN, k, c.sigma_DN);
    put(r.sigma_BD, k, c.sigma_BD);
    put(r.omega_BD_B, k, c.omega_BD_B);
    put(r.z1, k, c.z1);
    put(r.z2, k, c.z2);
    put(r.chi, k, c.chi);
    put(r.lam, k, c.lam);
    put(r.e1, k, c.e1);
    put(r.e2, k, c.e2);
    put(r.vs, k, c.vs);
    r.flags[static_cast<std::size_t>(k)] = nv ? (c.flags | tel.flags) : c.flags;
    if (nv) {
      put(r.sigma_BN_est, k, tel.sigma_est);
      put(r.bias_est, k, tel.bias_est);
      put(r.bias_true, k, tel.bias_true);
      put(r.att_est_error, k, tel.att_error);
      put(r.innovation, k, tel.innovation);
      put(r.P_diag, k, tel.P_diag);
      r.nis[static_cast<std::size_t>(k)] = tel.nis;
    }
    r.ctrl_mode[static_cast<std::size_t>(k)] = c.mode;
    r.rows = k + 1;
    if (k == n_ctrl) break;
    for (int j = 0; j < n_sub; ++j) {
      if (nv && j > 0 && k * nsub64 + j == next) {
        nv->tick(next, t + j * h, x);
        next = nv->next_tick(next);
      }
      x = plant_rk4_step(plant, act, t + j * h, x, h, c.u_cmd);
    }
    if (!finite(x)) {
      r.diverged = true;
      break;
    }
  }
  r.law_failures = ctl->law_failures();
  return r;
}

}  // namespace sc_rt
