#include "translate.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <type_traits>

#include <sc_rt_lcm/controller_status_fields.hpp>

#include "sc_rt/closed_loop.hpp"

namespace sc_rt {

namespace {
template <int N>
Eigen::Matrix<double, N, 1> vec(const double (&a)[N]) {
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) v(i) = a[i];
  return v;
}
template <int N, typename V>
void put(double (&a)[N], const V& v) {
  for (int i = 0; i < N; ++i) a[i] = v(i);
}
// A field's value into its slot of the status's generated table block
// (sc_rt_lcm/controller_status_fields.hpp); a field not on the bus has none.
template <typename V>
void put_slot(sc_rt_lcm::controller_status_t& m, FieldId f, const V& v) {
  double* d = status_slot(m, f);
  if (!d) return;
  if constexpr (std::is_arithmetic_v<V>)
    *d = static_cast<double>(v);
  else
    for (int i = 0; i < v.size(); ++i) d[i] = v(i);
}
}  // namespace

void magnetic_from_lcm(const sc_rt_lcm::controller_config_t& m, MagneticConfig& c) {
  c = MagneticConfig{};
  c.rods_enabled = m.mag_rods_enabled;
  if (c.rods_enabled) {
    if (m.mag_n_rods < 1 || m.mag_n_rods > kMaxRods)
      throw std::invalid_argument("controller_config_t.mag_n_rods must be 1.." + std::to_string(kMaxRods) +
                                  " with mag_rods_enabled, got " + std::to_string(m.mag_n_rods));
    const int n = m.mag_n_rods;
    c.rods.G_B.resize(3, n);
    c.rods.dipole_max.resize(n);
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < 3; ++i) c.rods.G_B(i, j) = m.mag_G_B[i][j];
      c.rods.dipole_max(j) = m.mag_dipole_max[j];
    }
  }
  c.momentum_enabled = m.mag_momentum_enabled;
  if (m.mag_unload_kind < 0 || m.mag_unload_kind > 1)
    throw std::invalid_argument("controller_config_t.mag_unload_kind must be 0..1, got " +
                                std::to_string(m.mag_unload_kind));
  MomentumParams& p = c.momentum;
  p.kind = static_cast<UnloadKind>(m.mag_unload_kind);
  p.gain = m.mag_gain;
  p.hysteresis = m.mag_hysteresis;
  p.on_fraction = m.mag_on_fraction;
  p.off_fraction = m.mag_off_fraction;
  p.capacity = m.mag_capacity;
  p.null_gain = m.mag_null_gain;
  p.null_bias = m.mag_null_bias;
  c.bdot_enabled = m.bdot_enabled;
  if (m.bdot_derivative < 0 || m.bdot_derivative > 1)
    throw std::invalid_argument("controller_config_t.bdot_derivative must be 0..1, got " +
                                std::to_string(m.bdot_derivative));
  BdotParams& b = c.bdot;
  b.gain = m.bdot_gain;
  b.normalized = m.bdot_normalized;
  b.derivative = static_cast<BdotDerivative>(m.bdot_derivative);
  b.filter_tau = m.bdot_filter_tau;
  b.rate_on = m.bdot_rate_on;
  b.rate_off = m.bdot_rate_off;
  if (!c.momentum_enabled && !c.bdot_enabled) c = MagneticConfig{};  // none: the controller without them
  // the values themselves: MagneticConfig's validate (Controller's constructor)
}

void magnetic_to_lcm(const MagneticConfig& c, sc_rt_lcm::controller_config_t& m) {
  if (!c.active()) {  // none: every field off and zero, as sc_rt.scenario.config_msg writes it
    m.mag_rods_enabled = m.mag_momentum_enabled = m.bdot_enabled = m.mag_hysteresis = m.bdot_normalized = false;
    m.mag_n_rods = m.mag_unload_kind = m.bdot_derivative = 0;
    for (int j = 0; j < kMaxRods; ++j) {
      for (int i = 0; i < 3; ++i) m.mag_G_B[i][j] = 0.0;
      m.mag_dipole_max[j] = 0.0;
    }
    m.mag_gain = m.mag_on_fraction = m.mag_off_fraction = m.mag_capacity = m.mag_null_gain = m.mag_null_bias = 0.0;
    m.bdot_gain = m.bdot_filter_tau = m.bdot_rate_on = m.bdot_rate_off = 0.0;
    return;
  }
  m.mag_rods_enabled = c.rods_enabled;
  const int n = m.mag_rods_enabled ? static_cast<int>(c.rods.G_B.cols()) : 0;
  m.mag_n_rods = static_cast<int8_t>(n);
  for (int j = 0; j < kMaxRods; ++j) {
    for (int i = 0; i < 3; ++i) m.mag_G_B[i][j] = j < n ? c.rods.G_B(i, j) : 0.0;
    m.mag_dipole_max[j] = j < n ? c.rods.dipole_max(j) : 0.0;
  }
  const MomentumParams& p = c.momentum;
  m.mag_momentum_enabled = c.momentum_enabled;
  m.mag_unload_kind = static_cast<int8_t>(p.kind);
  m.mag_gain = p.gain;
  m.mag_hysteresis = p.hysteresis;
  m.mag_on_fraction = p.on_fraction;
  m.mag_off_fraction = p.off_fraction;
  m.mag_capacity = p.capacity;
  m.mag_null_gain = p.null_gain;
  m.mag_null_bias = p.null_bias;
  const BdotParams& b = c.bdot;
  m.bdot_enabled = c.bdot_enabled;
  m.bdot_gain = b.gain;
  m.bdot_normalized = b.normalized;
  m.bdot_derivative = static_cast<int8_t>(b.derivative);
  m.bdot_filter_tau = b.filter_tau;
  m.bdot_rate_on = b.rate_on;
  m.bdot_rate_off = b.rate_off;
}

ControllerConfig config_from_lcm(const sc_rt_lcm::controller_config_t& m) {
  ControllerConfig c;
  if (m.law_api_version != SC_RT_LAW_API_VERSION)
    throw std::invalid_argument("controller_config_t is for the law interface version " +
                                std::to_string(m.law_api_version) + ", this controller has " +
                                std::to_string(SC_RT_LAW_API_VERSION) +
                                ": send it from an sc-rt of the same version");
  c.law = m.law;  // resolved (a plugin loaded) by the Controller
  if (m.n_law_params < 0 || m.n_law_param_values < 0)
    throw std::invalid_argument("controller_config_t: negative law parameter counts");
  std::size_t at = 0;
  for (int i = 0; i < m.n_law_params; ++i) {
    const std::size_t n = m.law_param_len[i] < 0 ? 0 : static_cast<std::size_t>(m.law_param_len[i]);
    if (at + n > m.law_param_values.size())
      throw std::invalid_argument("controller_config_t: law_param_len exceeds law_param_values");
    c.law_params.emplace_back(m.law_param_keys[i],
                              std::vector<double>(m.law_param_values.begin() + at,
                                                  m.law_param_values.begin() + at + n));
    at += n;
  }
  c.control_rate_hz = m.control_rate_hz;
  SpacecraftParams& s = c.spacecraft;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) s.J0(i, j) = m.J0[i][j];
    for (int j = 0; j < 4; ++j) s.Cbar(i, j) = m.Cbar[i][j];
  }
  s.Jw = vec(m.Jw);
  s.umin = vec(m.umin);
  s.umax = vec(m.umax);
  s.wheel_torque_command = m.wheel_torque_command;
  s.wheel_speed_max = vec(m.wheel_speed_max);
  for (int i = 0; i < 4; ++i)  // 0 on the wire: no limit
    if (!(s.wheel_speed_max(i) > 0.0)) s.wheel_speed_max(i) = std::numeric_limits<double>::infinity();
  s.w0 = m.w0;
  s.pinv_damping = m.pinv_damping;
  GuidanceParams& g = c.guidance;
  g.sigma_d0 = vec(m.sigma_d0);
  g.omega_bias = vec(m.omega_d_bias);
  g.omega_cos = vec(m.omega_d_cos);
  g.omega_sin = vec(m.omega_d_sin);
  g.omega_freq = m.omega_d_freq;
  if (m.guidance_kind < 0 || m.guidance_kind > 3)
    throw std::invalid_argument("controller_config_t.guidance_kind must be 0..3, got " +
                                std::to_string(m.guidance_kind));
  g.kind = static_cast<GuidanceKind>(m.guidance_kind);
  g.slew_target = vec(m.slew_target);
  g.slew_start = m.slew_start;
  g.slew_duration = m.slew_duration;
  if (m.ref_n < 0 || m.ref_n > kGuidanceTableMax)
    throw std::invalid_argument("controller_config_t.ref_n must be 0.." +
                                std::to_string(kGuidanceTableMax) + ", got " + std::to_string(m.ref_n));
  g.table_t.resize(m.ref_n);
  g.table_sigma.resize(m.ref_n, 3);
  g.table_omega.resize(m.ref_n, 3);
  for (int k = 0; k < m.ref_n; ++k) {
    g.table_t(k) = m.ref_t[k];
    for (int i = 0; i < 3; ++i) {
      g.table_sigma(k, i) = m.ref_sigma[k][i];
      g.table_omega(k, i) = m.ref_omega[k][i];
    }
  }
  PpcParams& p = c.ppc;
  p.chi0 = vec(m.ppc_chi0);
  p.chiinf = vec(m.ppc_chiinf);
  p.gamma = vec(m.ppc_gamma);
  p.dmin = vec(m.ppc_dmin);
  p.dmax = vec(m.ppc_dmax);
  c.safety = {m.max_rate, m.max_wheel_speed, m.stale_periods};
  magnetic_from_lcm(m, c.magnetic);
  return c;
}

sc_rt_lcm::controller_config_t config_to_lcm(const ControllerConfig& c, const std::string& scenario) {
  sc_rt_lcm::controller_config_t m{};
  m.utime = 0;
  m.scenario = scenario;
  m.law = c.law;
  m.law_api_version = SC_RT_LAW_API_VERSION;
  m.n_law_params = static_cast<int32_t>(c.law_params.size());
  for (const auto& [key, values] : c.law_params) {
    m.law_param_keys.push_back(key);
    m.law_param_len.push_back(static_cast<int32_t>(values.size()));
    m.law_param_values.insert(m.law_param_values.end(), values.begin(), values.end());
  }
  m.n_law_param_values = static_cast<int32_t>(m.law_param_values.size());
  m.control_rate_hz = c.control_rate_hz;
  const SpacecraftParams& s = c.spacecraft;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) m.J0[i][j] = s.J0(i, j);
    for (int j = 0; j < 4; ++j) m.Cbar[i][j] = s.Cbar(i, j);
  }
  put(m.Jw, s.Jw);
  put(m.umin, s.umin);
  put(m.umax, s.umax);
  m.wheel_torque_command = s.wheel_torque_command;
  for (int i = 0; i < 4; ++i)  // no limit (inf) is 0 on the wire
    m.wheel_speed_max[i] = std::isfinite(s.wheel_speed_max(i)) ? s.wheel_speed_max(i) : 0.0;
  m.w0 = s.w0;
  m.pinv_damping = s.pinv_damping;
  put(m.sigma_d0, c.guidance.sigma_d0);
  put(m.omega_d_bias, c.guidance.omega_bias);
  put(m.omega_d_cos, c.guidance.omega_cos);
  put(m.omega_d_sin, c.guidance.omega_sin);
  m.omega_d_freq = c.guidance.omega_freq;
  const GuidanceParams& g = c.guidance;
  m.guidance_kind = static_cast<int8_t>(g.kind);
  put(m.slew_target, g.slew_target);
  m.slew_start = g.slew_start;
  m.slew_duration = g.slew_duration;
  m.ref_n = static_cast<int32_t>(g.table_t.size());
  m.ref_t.assign(g.table_t.data(), g.table_t.data() + g.table_t.size());
  m.ref_sigma.assign(m.ref_n, std::vector<double>(3, 0.0));
  m.ref_omega.assign(m.ref_n, std::vector<double>(3, 0.0));
  for (int k = 0; k < m.ref_n && k < g.table_sigma.rows() && k < g.table_omega.rows(); ++k) {
    for (int i = 0; i < 3; ++i) {
      m.ref_sigma[k][i] = g.table_sigma(k, i);
      m.ref_omega[k][i] = g.table_omega(k, i);
    }
  }
  put(m.ppc_chi0, c.ppc.chi0);
  put(m.ppc_chiinf, c.ppc.chiinf);
  put(m.ppc_gamma, c.ppc.gamma);
  put(m.ppc_dmin, c.ppc.dmin);
  put(m.ppc_dmax, c.ppc.dmax);
  m.max_rate = c.safety.max_rate;
  m.max_wheel_speed = c.safety.max_wheel_speed;
  m.stale_periods = c.safety.stale_periods;
  magnetic_to_lcm(c.magnetic, m);
  return m;
}

ControllerConfig config_from_bytes(const void* data, int size) {
  sc_rt_lcm::controller_config_t m;
  if (m.decode(data, 0, size) < 0)
    throw std::invalid_argument(
        "cannot decode controller_config_t (" + std::to_string(size) +
        " bytes): wrong type, truncated, or built from other .lcm files");
  return config_from_lcm(m);
}

Measurement measurement_from_lcm(const sc_rt_lcm::plant_state_t& msg) {
  Measurement m;
  m.t = msg.t;
  m.sigma_BN = vec(msg.sigma_BN);
  m.omega_BN_B = vec(msg.omega_BN_B);
  m.wheel_speed = vec(msg.wheel_speed);
  return m;
}

void fill_wheel_cmd(const Command& c, sc_rt_lcm::wheel_cmd_t& msg) {
  msg.t = c.t;
  put(msg.u_cmd, c.u_cmd);
  put(msg.u_sat, c.u_sat);
  msg.mode = static_cast<int8_t>(c.mode);
  msg.flags = c.flags;
}

void fill_rod_cmd(const Command& c, int n_rods, sc_rt_lcm::rod_cmd_t& msg) {
  msg.t = c.t;
  msg.n_rods = static_cast<int8_t>(n_rods);
  for (int i = 0; i < kMaxRods; ++i) {  // no decision (NaN): zero, the rods off
    const double d = i < n_rods ? c.magnetic.rod_dipole_cmd(i) : 0.0;
    msg.dipole[i] = std::isfinite(d) ? d : 0.0;
  }
}

void fill_status(const Command& c, int law, int n_telemetry, sc_rt_lcm::controller_status_t& msg) {
  msg.t = c.t;
  msg.law = static_cast<int8_t>(law);
  msg.mode = static_cast<int8_t>(c.mode);
  msg.flags = c.flags;
  put(msg.u_cmd, c.u_cmd);
  put(msg.u_sat, c.u_sat);
  msg.n_telemetry = static_cast<int8_t>(n_telemetry);
  for_each_command_field(c, [&msg](FieldId f, const auto& v) { put_slot(msg, f, v); });
}

NavSetup nav_from_lcm(const sc_rt_lcm::controller_config_t& m) {
  NavSetup n;
  n.enabled = m.nav_enabled;
  if (!n.enabled) return n;
  n.use_estimate = m.nav_use_estimate;
  MekfParams& k = n.mekf;
  k.arw = m.nav_arw;
  k.rrw = m.nav_rrw;
  k.bias_sigma = m.nav_bias_sigma;
  k.bias_tau = m.nav_bias_tau;
  k.quantization = m.nav_quantization;
  k.sigma_cross = m.nav_sigma_cross;
  k.sigma_boresight = m.nav_sigma_boresight;
  k.boresight = vec(m.nav_boresight);
  k.initial_attitude_sigma = m.nav_initial_attitude_sigma;
  k.initial_bias_sigma = m.nav_initial_bias_sigma;
  k.degraded_after = m.nav_degraded_after;
  k.history = m.nav_history;
  k.calibrate = m.nav_calibrate;
  k.initial_scale_factor_sigma = m.nav_initial_scale_factor_sigma;
  k.initial_misalignment_sigma = m.nav_initial_misalignment_sigma;
  n.sigma0 = vec(m.nav_sigma0);
  n.mag_enabled = n.enabled && m.nav_mag_enabled;
  if (n.mag_enabled) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) n.mag_R_SB(r, c) = m.nav_mag_R_SB[r][c];
    // the mounting is a rotation: R R' = I (to rounding of the scenario's MRP)
    if (!n.mag_R_SB.allFinite() || (n.mag_R_SB * n.mag_R_SB.transpose() - Mat3::Identity()).cwiseAbs().maxCoeff() > 1e-9)
      throw std::invalid_argument("controller_config_t: nav_mag_R_SB is not a rotation matrix");
  }
  const double nonneg[] = {k.arw, k.rrw, k.bias_sigma, k.quantization, k.sigma_cross, k.sigma_boresight,
                           k.initial_attitude_sigma, k.initial_bias_sigma, k.degraded_after,
                           k.initial_scale_factor_sigma, k.initial_misalignment_sigma};
  for (double v : nonneg)
    if (!(v >= 0.0) || !std::isfinite(v))
      throw std::invalid_argument("controller_config_t: a nav_* noise value is negative or not finite");
  if (!(k.bias_tau > 0.0) || !(k.boresight.norm() > 0.0) || !k.boresight.allFinite())
    throw std::invalid_argument("controller_config_t: nav_bias_tau <= 0 or a zero/non-finite nav_boresight");
  if (k.history < 2 || k.history > 100000)
    throw std::invalid_argument("controller_config_t: nav_history must be 2..100000");
  if (!n.sigma0.allFinite() || n.sigma0.norm() > 1.0 + 1e-9)
    throw std::invalid_argument("controller_config_t: nav_sigma0 is not a finite MRP (|sigma| <= 1)");
  return n;
}

NavSetup nav_from_bytes(const void* data, int size) {
  sc_rt_lcm::controller_config_t m;
  if (m.decode(data, 0, size) < 0) throw std::invalid_argument("cannot decode controller_config_t");
  return nav_from_lcm(m);
}

bool field_from_lcm(const sc_rt_lcm::magnetometer_t& msg, Vec3& B_B) {
  if (msg.source != sc_rt_lcm::magnetometer_t::SOURCE_TRUE_FIELD ||
      msg.frame != sc_rt_lcm::magnetometer_t::FRAME_BODY)
    return false;  // a sensor's sample: the estimator's (not on this branch of the bench)
  const Vec3 B = vec(msg.B);
  if (!B.allFinite()) return false;
  B_B = B;
  return true;
}

bool mag_sample_from_lcm(const sc_rt_lcm::magnetometer_t& msg, MagSample& s) {
  if (msg.source != sc_rt_lcm::magnetometer_t::SOURCE_SENSOR || msg.frame != sc_rt_lcm::magnetometer_t::FRAME_SENSOR)
    return false;  // the ideal field: the ideal magnetometer's (field_from_lcm)
  const Vec3 B = vec(msg.B);
  if (!std::isfinite(msg.t) || !B.allFinite()) return false;
  s = MagSample{msg.t, B};
  return true;
}

GyroSample gyro_from_lcm(const sc_rt_lcm::gyro_t& msg) { return GyroSample{msg.t, vec(msg.omega), msg.output}; }

StarSample star_from_lcm(const sc_rt_lcm::star_tracker_t& msg) {
  return StarSample{msg.t_exposure, msg.t_delivery, vec(msg.sigma_BN)};
}

TachSample tach_from_lcm(const sc_rt_lcm::tachometer_t& msg) {
  return TachSample{msg.t, vec(msg.wheel_speed)};
}

void fill_nav_status(const NavTelemetry& t, sc_rt_lcm::controller_status_t& msg) {
  msg.nav = true;
  for_each_nav_field(t, [&msg](FieldId f, const auto& v) { put_slot(msg, f, v); });
  msg.nav_flags = t.flags;
}

}  // namespace sc_rt
