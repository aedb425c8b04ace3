// Flight-like reaction wheel torques (issue #28, first part): the limits a
// torque-commanded wheel applies to its command, and its friction, per
// wheel. The same functions as python/sc_rt/model/wheels.py (its docstring
// states the model and its source, Basilisk's reaction wheel effector),
// bitwise (tests/test_wheels.py). ActuatorParams::wheels (plant.hpp) puts
// them in the plant (torque_plant.cpp).
#pragma once
#include <array>
#include <cmath>

#include "sc_rt/types.hpp"  // wheel_torque_command

namespace sc_rt {

struct WheelLimits {
  double u_max = 0.0;      //!< [N m] motor torque limit (<= 0: none)
  double u_min = 0.0;      //!< [N m] deadband
  double p_max = 0.0;      //!< [W] power limit on |u Omega| (<= 0: none)
  double omega_max = 0.0;  //!< [rad/s] speed limit (<= 0: none)
};

struct WheelFriction {
  double coulomb = 0.0;            //!< [N m]
  double static_ = 0.0;            //!< [N m] breakaway torque (Stribeck)
  double beta = 0.0;               //!< [rad/s] Stribeck speed (<= 0: no static part)
  double viscous = 0.0;            //!< [N m s]
  double omega_limit_cycle = 0.0;  //!< [rad/s] linear below it (<= 0: never)
};

// The four torque-commanded wheels (sc_rt.model.wheels.TorqueWheels).
struct TorqueWheels {
  bool enabled = false;   //!< false: the paper's acceleration-commanded wheels
  std::array<WheelLimits, 4> limits{};
  std::array<WheelFriction, 4> friction{};
  bool stribeck = false;        //!< the static (Stribeck) part of the friction
  bool torque_command = false;  //!< the command is a motor torque [N m], not an acceleration [rad/s^2]
  std::array<double, 4> lag{};  //!< [s] first-order motor lag time constants (0: none)
};

// A first-order motor lag over a step h [s] toward the torque c from the motor
// torque m [N m], time constant tau [s] (sc_rt.model.wheels.motor_lag): the
// torque averaged over the step in *avg, the torque at its end in *end.
inline void motor_lag(double c, double m, double tau, double h, double* avg, double* end) {
  if (tau <= 0.0) {
    *avg = c;
    *end = c;
    return;
  }
  const double d = m - c;
  *avg = c + d * (tau / h) * -std::expm1(-h / tau);
  *end = c + d * std::exp(-h / tau);
}

// The motor torque applied for the command u at the wheel speed omega:
// torque limit, deadband, power limit, speed limit, in that order.
double wheel_applied_torque(double u, double omega, const WheelLimits& lim);

// The friction torque at omega (opposing it); stribeck: the static part on.
double wheel_friction_torque(double omega, const WheelFriction& f, bool stribeck);

}  // namespace sc_rt
