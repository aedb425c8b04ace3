// The plant with torque-commanded wheels: every expression in the order of
// its Python twin (python/sc_rt/model/torque_plant.py), so that both give
// the same bits (see plant_kernels.hpp on why no Eigen products here).
#include "sc_rt/torque_plant.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <stdexcept>
#include <string>

#include "plant_kernels.hpp"

namespace sc_rt {

namespace {

constexpr double kOnes[4] = {1.0, 1.0, 1.0, 1.0};
constexpr double kZeros[4] = {0.0, 0.0, 0.0, 0.0};

// x_dot of the torque-commanded plant (TorquePlant.derivative in Python);
// on: per wheel, the static (Stribeck) part of the friction on.
void torque_derivative(const PlantParams& p, const TorqueWheels& w, const detail::Rhs& rhs, const double C[3][4],
                       const double CJ[3][4], const double Jw[4], double t, const double x[10],
                       const double u_motor[4], const double scale[4], const double brake[4], const bool on[4],
                       double out[10], const detail::MagField& mag) {
  double u[4];
  for (int i = 0; i < 4; ++i)
    u[i] = u_motor[i] + scale[i] * wheel_friction_torque(x[6 + i], w.friction[static_cast<std::size_t>(i)], on[i]) -
           brake[i] * x[6 + i];
  double hw[3], tw[3], d[3], sw[6];
  for (int r = 0; r < 3; ++r) {
    hw[r] = CJ[r][0] * x[6] + CJ[r][1] * x[7] + CJ[r][2] * x[8] + CJ[r][3] * x[9];
    tw[r] = C[r][0] * u[0] + C[r][1] * u[1] + C[r][2] * u[2] + C[r][3] * u[3];
  }
  detail::dist3(p, t, d);
  double gb[4], mb[6];
  rhs(x, x + 3, hw, tw, d, sw, detail::OrbitGG(p)(t, gb), mag(t, mb));
  for (int i = 0; i < 6; ++i) out[i] = sw[i];
  for (int i = 0; i < 4; ++i) out[6 + i] = u[i] / Jw[i] - (C[0][i] * sw[3] + C[1][i] * sw[4] + C[2][i] * sw[5]);
}

// M = J - Cbar diag(Jw) Cbar', element by element, the wheels in order (TorquePlant.__init__).
Mat3 hub_inertia(const PlantParams& p) {
  const Mat3 J = p.J0 + p.dJ;
  Mat3 M;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      double m = J(r, c);
      for (int i = 0; i < 4; ++i) m -= (p.Cbar(r, i) * p.Jw(i)) * p.Cbar(c, i);
      M(r, c) = m;
    }
  return M;
}

// RK4 with u, scale, brake held; the MRP short set after (TorquePlant.step_held).
template <class Deriv>
PlantState rk4_held(const Deriv& f, double t, const PlantState& x, double h) {
  double x0[10];
  for (int i = 0; i < 3; ++i) x0[i] = x.sigma_BN(i), x0[3 + i] = x.omega_BN_B(i);
  for (int i = 0; i < 4; ++i) x0[6 + i] = x.wheel_speed(i);
  const double hh = 0.5 * h;
  double k1[10], k2[10], k3[10], k4[10], xs[10];
  f(t, x0, k1);
  for (int i = 0; i < 10; ++i) xs[i] = x0[i] + hh * k1[i];
  f(t + hh, xs, k2);
  for (int i = 0; i < 10; ++i) xs[i] = x0[i] + hh * k2[i];
  f(t + hh, xs, k3);
  for (int i = 0; i < 10; ++i) xs[i] = x0[i] + h * k3[i];
  f(t + h, xs, k4);
  const double h6 = h / 6.0;
  double o[10];
  for (int i = 0; i < 10; ++i) o[i] = x0[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
  const double ss = o[0] * o[0] + o[1] * o[1] + o[2] * o[2];
  if (ss > 1.0)  // MRP shadow set: same attitude, |sigma| <= 1
    for (int i = 0; i < 3; ++i) o[i] = -o[i] / ss;
  PlantState r;
  for (int i = 0; i < 3; ++i) r.sigma_BN(i) = o[i], r.omega_BN_B(i) = o[3 + i];
  for (int i = 0; i < 4; ++i) r.wheel_speed(i) = o[6 + i];
  return r;
}

// The right-hand side's constants: built on the stack by the free step
// functions (the plant's step path does not allocate), held by a TorquePlant.
struct StackKernel {
  detail::Rhs rhs;
  double C[3][4], CJ[3][4], Jw[4];
  explicit StackKernel(const PlantParams& p) : StackKernel(p, hub_inertia(p)) {}
  StackKernel(const PlantParams& p, const Mat3& M) : rhs(p.J0 + p.dJ, M, p.w0) {
    for (int i = 0; i < 4; ++i) Jw[i] = p.Jw(i);
    for (int r = 0; r < 3; ++r)
      for (int i = 0; i < 4; ++i) C[r][i] = p.Cbar(r, i), CJ[r][i] = p.Cbar(r, i) * p.Jw(i);
  }
};

}  // namespace

struct TorquePlant::Kernel : StackKernel {
  using StackKernel::StackKernel;
};

TorquePlant::TorquePlant(const PlantParams& p, const TorqueWheels& wheels) : p_(p), w_(wheels) {
  M_ = hub_inertia(p);
  Eigen::SelfAdjointEigenSolver<Mat3> es(0.5 * (M_ + M_.transpose()));
  if (!(es.eigenvalues().minCoeff() > 0.0))
    throw std::invalid_argument("TorquePlant: J - Cbar diag(Jw) Cbar' is not positive definite");
  k_ = std::make_unique<const Kernel>(p, M_);
  if (wheels.stribeck_switching)
    throw std::invalid_argument(
        "TorquePlant: stribeck_switching needs the carried switches (torque_rk4_step with a WheelCarry)");
}

TorquePlant::~TorquePlant() = default;

void torque_step_inputs(const PlantParams& p, const ActuatorParams& a, double t, const Vec4& u_cmd,
                        const Vec4& wheel_speed, double u[4], double scale[4], double brake[4]) {
  const TorqueWheels& w = a.wheels;
  for (int i = 0; i < 4; ++i) {
    const auto s = static_cast<std::size_t>(i);
    u[i] = wheel_applied_torque(wheel_torque_command(u_cmd(i), p.Jw(i), w.torque_command), wheel_speed(i),
                                w.limits[s]);
    scale[i] = 1.0;
    brake[i] = 0.0;
  }
  for (int i = 0; i < 4; ++i) {  // step_inputs takes the faults in wheel order too
    const WheelFault& f = a.faults[static_cast<std::size_t>(i)];
    if (!(f.active && f.onset <= t && t < f.end)) continue;
    if (f.stuck) {
      u[i] = 0.0;
      brake[i] = p.Jw(i) * f.rate;
    } else {
      const double Y = -std::expm1(-f.rate * (t - f.onset));
      u[i] = u[i] + Y * ((f.effectiveness - 1.0) * u[i] + p.Jw(i) * f.bias);
      scale[i] = 1.0 + Y * (f.friction - 1.0);
    }
  }
}

namespace {
bool lagged(const ActuatorParams& a, const void* motor) {
  bool any = false;
  for (double tau : a.wheels.lag) any = any || tau > 0.0;
  if (any && motor == nullptr)
    throw std::invalid_argument("wheels with a motor lag need the motor state (plant_rk4_step's motor)");
  if (a.wheels.stribeck_switching && motor == nullptr)
    throw std::invalid_argument(
        "wheels with stribeck_switching need the carried switches (plant_rk4_step's motor, a WheelCarry)");
  return any;
}

// The friction's static part per wheel at a step's first stage (the row's):
// the carried switch through Basilisk's rule at the step's start speed, where
// omega - omega_start = 0 (switching), or the fixed flag.
void stage1_switches(const TorqueWheels& w, const WheelCarry* motor, const Vec4& wheel_speed, bool on[4]) {
  for (int i = 0; i < 4; ++i) {
    const auto s = static_cast<std::size_t>(i);
    on[i] = w.stribeck_switching ? wheel_stribeck_switch(motor->stribeck[s], wheel_speed(i), wheel_speed(i), w.friction[s])
                                 : w.stribeck;
  }
}
}  // namespace

PlantState torque_rk4_step(const PlantParams& p, const ActuatorParams& a, double t, const PlantState& x,
                           double h, const Vec4& u_cmd, WheelCarry* motor, const Vec3* dipole_B) {
  const StackKernel k(p);
  Vec3 rod_m;  // no dipole input: the rods' for a zero command (truth.py rk4_step)
  if (dipole_B == nullptr && p.rods.enabled) {
    rod_m = rods_dipole_B(p.rods, t);
    dipole_B = &rod_m;
  }
  double m[3];  // the body dipole held over the step (TorquePlant.step_held's)
  const detail::MagField mag(p, detail::held_dipole(p, dipole_B, m) ? m : nullptr);
  double u[4], scale[4], brake[4];
  torque_step_inputs(p, a, t, u_cmd, x.wheel_speed, u, scale, brake);
  if (lagged(a, motor)) {
    for (int i = 0; i < 4; ++i) {
      double avg, end;
      motor_lag(u[i], motor->motor(i), a.wheels.lag[static_cast<std::size_t>(i)], h, &avg, &end);
      u[i] = avg;
      motor->motor(i) = end;
    }
  } else if (motor != nullptr) {
    for (int i = 0; i < 4; ++i) motor->motor(i) = u[i];
  }
  // the friction's static part per wheel: fixed, or Basilisk's switch at every
  // stage against the step's start speed, carried to the next step (docs/MODEL.md)
  const TorqueWheels& w = a.wheels;
  const bool sw = w.stribeck_switching;
  bool on[4];
  for (int i = 0; i < 4; ++i) on[i] = sw ? motor->stribeck[static_cast<std::size_t>(i)] : w.stribeck;
  auto f = [&](double ts, const double* xs, double* out) {
    if (sw)
      for (int i = 0; i < 4; ++i) {
        const auto s = static_cast<std::size_t>(i);
        on[i] = wheel_stribeck_switch(on[i], xs[6 + i], x.wheel_speed(i), w.friction[s]);
      }
    torque_derivative(p, w, k.rhs, k.C, k.CJ, k.Jw, ts, xs, u, scale, brake, on, out, mag);
  };
  const PlantState r = rk4_held(f, t, x, h);
  if (sw)
    for (int i = 0; i < 4; ++i) motor->stribeck[static_cast<std::size_t>(i)] = on[i];
  return r;
}

PlantState plant_rk4_step(const PlantParams& p, const ActuatorParams& a, double t, const PlantState& x,
                          double h, const Vec4& u_cmd, WheelCarry& motor, const Vec3* dipole_B) {
  if (a.wheels.enabled) return torque_rk4_step(p, a, t, x, h, u_cmd, &motor, dipole_B);
  return plant_rk4_step(p, a, t, x, h, u_cmd, dipole_B);
}

WheelOutput plant_row(const PlantParams& p, const ActuatorParams& a, double t, const PlantState& x,
                      const Vec4& u_cmd, const WheelCarry* motor, const Vec3* dipole_B) {
  if (!a.wheels.enabled) return wheel_accel(a, t, u_cmd, x.wheel_speed);
  const StackKernel k(p);
  double u[4], scale[4], brake[4], x0[10], d[10];
  torque_step_inputs(p, a, t, u_cmd, x.wheel_speed, u, scale, brake);
  if (lagged(a, motor))
    for (int i = 0; i < 4; ++i)
      if (a.wheels.lag[static_cast<std::size_t>(i)] > 0.0) u[i] = motor->motor(i);
  bool on[4];
  stage1_switches(a.wheels, motor, x.wheel_speed, on);
  for (int i = 0; i < 3; ++i) x0[i] = x.sigma_BN(i), x0[3 + i] = x.omega_BN_B(i);
  for (int i = 0; i < 4; ++i) x0[6 + i] = x.wheel_speed(i);
  // the residual dipole and the one the step holds: dipole_B, or without it the
  // rods' for a zero command (torque_rk4_step's, truth.py row)
  double m[3];
  Vec3 rod_m;
  if (dipole_B == nullptr && p.rods.enabled) {
    rod_m = rods_dipole_B(p.rods, t);
    dipole_B = &rod_m;
  }
  const detail::MagField mag(p, detail::held_dipole(p, dipole_B, m) ? m : nullptr);
  torque_derivative(p, a.wheels, k.rhs, k.C, k.CJ, k.Jw, t, x0, u, scale, brake, on, d, mag);
  WheelOutput out;
  for (int i = 0; i < 4; ++i) {
    out.u_sat(i) = u[i] / p.Jw(i);
    out.accel(i) = d[6 + i];
    out.Y(i) = fault_Y(a.faults[static_cast<std::size_t>(i)], t);
  }
  return out;
}

void TorquePlant::derivative(double t, const double x[10], const double u_motor[4], double out[10]) const {
  derivative(t, x, u_motor, kOnes, kZeros, out);
}

void TorquePlant::derivative(double t, const double x[10], const double u_motor[4], const double scale[4],
                             const double brake[4], double out[10]) const {
  const Kernel& k = *k_;
  double m[3];  // the residual dipole (TorquePlant.derivative's, no magnetorquers)
  const detail::MagField mag(p_, detail::held_dipole(p_, nullptr, m) ? m : nullptr);
  const bool on[4] = {w_.stribeck, w_.stribeck, w_.stribeck, w_.stribeck};
  torque_derivative(p_, w_, k.rhs, k.C, k.CJ, k.Jw, t, x, u_motor, scale, brake, on, out, mag);
}

PlantState TorquePlant::step_held(double t, const PlantState& x, double h, const double u[4],
                                  const double scale[4], const double brake[4]) const {
  auto f = [&](double ts, const double* xs, double* out) { derivative(ts, xs, u, scale, brake, out); };
  return rk4_held(f, t, x, h);
}

PlantState TorquePlant::step(double t, const PlantState& x, double h, const Vec4& u_cmd) const {
  double u[4];
  for (int i = 0; i < 4; ++i)
    u[i] = wheel_applied_torque(u_cmd(i), x.wheel_speed(i), w_.limits[static_cast<std::size_t>(i)]);
  return step_held(t, x, h, u, kOnes, kZeros);
}

}  // namespace sc_rt
