#include "sc_rt/closed_loop.hpp"

#include <algorithm>
#include <limits>
#include <memory>
#include <stdexcept>
#include <utility>

namespace sc_rt {

namespace {
bool finite(const PlantState& x) {
  return x.sigma_BN.allFinite() && x.omega_BN_B.allFinite() && x.wheel_speed.allFinite();
}
}  // namespace

void ClosedLoopResult::reserve_rows(std::size_t n, bool with_nav) {
  capacity = n;
  nav = with_nav;
  data.assign(n * static_cast<std::size_t>(row_width(with_nav ? kNav : kLoop)), 0.0);
}

ClosedLoop::ClosedLoop(const ControllerConfig& cfg, const PlantParams& plant, const ActuatorParams& act,
                       const PlantState& x0, int n_ctrl, int n_sub, double rate, const NavConfig* nav)
    : plant_(plant), act_(act), delta2_(plant_), x_(x0), n_ctrl_(n_ctrl), n_sub_(n_sub), rate_(rate) {
  if (n_ctrl < 0 || n_sub < 1 || !(rate > 0.0))
    throw std::invalid_argument("simulate_closed_loop: need n_ctrl >= 0, n_sub >= 1, rate > 0");
  ctl_ = Controller::create(cfg);
  mag_ = cfg.magnetic.active();
  rods_ = mag_ && plant_.rods.enabled;
  if (nav) nv_ = std::make_unique<Navigation>(*nav);
  // with sensors the controller gets the field it measures (docs/MODEL.md section 17)
  if (nv_ && mag_ && !nav->sensors.magnetometer.enabled)
    throw std::invalid_argument("simulate_closed_loop: magnetic control with sensors needs the magnetometer "
                                "(NavConfig.sensors.magnetometer.enabled): the controller uses the field it measures");
  mag_meas_ = nv_ && mag_;
  h_ = 1.0 / (rate * n_sub);
  if (nv_) {
    nv_->reset(x_);
    tick(0, 0.0);
    ctl_->reset(nv_->measure(0.0, x_));
  } else {
    ctl_->reset(Measurement{0.0, x_.sigma_BN, x_.omega_BN_B, x_.wheel_speed});
  }
  next_ = nv_ ? nv_->next_tick(0) : 0;  // a tick with nothing due changes nothing: skip it
}

ClosedLoop::~ClosedLoop() = default;

void ClosedLoop::tick(std::int64_t i, double t) {
  // the magnetometer samples the plant's true field in B at the tick (evaluated only when it is due)
  Vec3 B_B;
  const bool field = nv_->magnetometer_due(i) && plant_field_B(plant_, t, x_.sigma_BN, B_B);
  nv_->tick(i, t, x_, field ? &B_B : nullptr);
}

const LawFailures& ClosedLoop::law_failures() const { return ctl_->law_failures(); }
const std::vector<std::string>& ClosedLoop::telemetry_names() const { return ctl_->telemetry_names(); }

int ClosedLoop::run(int rows, ClosedLoopResult* out) {
  if (out && rows > 0 &&
      (out->capacity < static_cast<std::size_t>(rows) || (nv_ && !out->nav)))
    throw std::invalid_argument("ClosedLoop::run: the result has room for fewer rows than asked "
                                "(reserve_rows, with the navigation's columns when it runs sensors)");
  Navigation* nv = nv_.get();
  const std::int64_t nsub64 = n_sub_;
  int written = 0;
  while (written < rows && !done_) {
    const int k = k_;
    const int i = written;  // the row in this chunk
    const double t = k / rate_;
    if (nv && k > 0 && k * nsub64 == next_) {
      tick(next_, t);
      next_ = nv->next_tick(next_);
    }
    const Measurement m = nv ? nv->measure(t, x_, out ? &tel_ : nullptr)
                             : Measurement{t, x_.sigma_BN, x_.omega_BN_B, x_.wheel_speed};
    // Magnetic control, docs/MODEL.md section 17: the true field in B at t_k
    // (one evaluation per control step; NaN without a field), which the
    // controller gets without sensors; with them it gets the magnetometer's
    // latest sample rotated to B (Navigation::field_B), the truth recorded beside it.
    Vec3 B_true = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
    if (mag_ && (!mag_meas_ || out)) plant_field_B(plant_, t, x_.sigma_BN, B_true);  // (sensed: for the record only)
    const Command c = mag_ ? ctl_->step(m, mag_meas_ ? nv->field_B() : B_true) : ctl_->step(m);
    // the rod commands held over the period; the row's wheel accelerations with
    // the dipole the step's first stage holds (docs/MODEL.md section 17)
    RodVec d_cmd, d_app;  // [A m^2] the rods' commands held, each rod's dipole applied
    Vec3 m_B0;
    if (rods_) {
      d_cmd = c.magnetic.rod_dipole_cmd.head(plant_.rods.params.G_B.cols());
      m_B0 = rods_dipole_B(plant_.rods, t, &d_cmd, out ? &d_app : nullptr);
    }
    const WheelOutput w = plant_row(plant_, act_, t, x_, c.u_cmd, &motor_, rods_ ? &m_B0 : nullptr);
    if (out) {
      out->put(FieldId::t, i, t);
      out->put(FieldId::sigma_BN, i, x_.sigma_BN);
      out->put(FieldId::omega_BN_B, i, x_.omega_BN_B);
      out->put(FieldId::wheel_speed, i, x_.wheel_speed);
      out->put(FieldId::wheel_accel, i, w.accel);
      out->put(FieldId::delta2, i, delta2_(t, x_, w.u_sat, w.accel));
      out->put(FieldId::H_N, i, total_momentum_N(plant_, x_));
      out->put(FieldId::B_B_true, i, B_true);
      // the rods' truth (docs/MODEL.md section 16): the dipole the row's first step holds, each
      // rod's beside it; without magnetic control the rods' own (a zero command: a stuck rod's)
      Vec3 m_B_app = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());  // [A m^2] NaN: no rods
      // [A m^2] per rod, NaN beyond the rods
      Eigen::Matrix<double, kMaxRods, 1> rod_app = Eigen::Matrix<double, kMaxRods, 1>::Constant(m_B_app(0));
      if (plant_.rods.enabled) {
        m_B_app = rods_ ? m_B0 : rods_dipole_B(plant_.rods, t, nullptr, &d_app);
        rod_app.head(d_app.size()) = d_app;
      }
      out->put(FieldId::m_B, i, m_B_app);
      out->put(FieldId::rod_dipole, i, rod_app);
      for_each_command_field(c, [out, i](FieldId f, const auto& v) { out->put(f, i, v); });
      if (nv) {
        out->put(FieldId::flags, i, c.flags | tel_.flags);
        for_each_nav_field(tel_, [out, i](FieldId f, const auto& v) { out->put(f, i, v); });
      }
    }
    ++written;
    ++k_;
    if (k == n_ctrl_) {
      done_ = true;
      break;
    }
    for (int j = 0; j < n_sub_; ++j) {
      if (nv && j > 0 && k * nsub64 + j == next_) {
        tick(next_, t + j * h_);
        next_ = nv->next_tick(next_);
      }
      if (rods_) {
        // the rod commands held over the period, through the plant's rods
        // and their faults at each step's time (truth.py rk4_step's dipole_B)
        const Vec3 m_B = j == 0 ? m_B0 : rods_dipole_B(plant_.rods, t + j * h_, &d_cmd);
        x_ = plant_rk4_step(plant_, act_, t + j * h_, x_, h_, c.u_cmd, motor_, &m_B);
      } else {
        x_ = plant_rk4_step(plant_, act_, t + j * h_, x_, h_, c.u_cmd, motor_);
      }
    }
    if (!finite(x_)) {
      diverged_ = done_ = true;
      break;
    }
  }
  if (out) out->rows = written;
  return written;
}

ClosedLoopResult simulate_closed_loop(const ControllerConfig& cfg, const PlantParams& plant,
                                      const ActuatorParams& act, const PlantState& x0, int n_ctrl,
                                      int n_sub, double rate, const NavConfig* nav) {
  ClosedLoop loop(cfg, plant, act, x0, n_ctrl, n_sub, rate, nav);
  ClosedLoopResult r;
  r.reserve_rows(static_cast<std::size_t>(n_ctrl) + 1, nav != nullptr);
  loop.run(n_ctrl + 1, &r);
  r.diverged = loop.diverged();
  r.law_failures = loop.law_failures();
  r.telemetry_names = loop.telemetry_names();
  return r;
}

}  // namespace sc_rt
