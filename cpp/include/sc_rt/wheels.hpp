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
  bool stribeck = false;        //!< the static (Stribeck) part of the friction, always on
  //! the static part switched per wheel by Basilisk's rule (wheel_stribeck_switch), a state the
  //! run carries (WheelCarry::stribeck); exclusive with stribeck
  bool stribeck_switching = false;
  bool torque_command = false;  //!< the command is a motor torque [N m], not an acceleration [rad/s^2]
  std::array<double, 4> lag{};  //!< [s] first-order motor lag time constants (0: none)
};

// What a run carries from step to step beside x for torque-commanded wheels
// (sc_rt.model.truth.new_motor's list: the 4 motor torques, then with
// stribeck_switching the 4 Stribeck switches as 0/1). Zero at the start.
struct WheelCarry {
  Vec4 motor = Vec4::Zero();       //!< [N m] the motor torques (a lag's state)
  std::array<bool, 4> stribeck{};  //!< [-] per wheel: the static (Stribeck) friction part on
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

// Basilisk's switch of the static (Stribeck) part at one evaluation of the
// friction (updateContributions in Basilisk's
// src/simulation/dynamics/reactionWheels/reactionWheelStateEffector.cpp, run
// at every derivative call): on is the switch before it, omega [rad/s] the
// wheel speed there, omega_start [rad/s] the speed at the step's start (Basilisk's
// omegaBefore). On when |omega| < 0.1 omega_limit_cycle; then off when the
// wheel decelerates, sign(omega) = -sign(omega - omega_start) != 0; never on
// with beta <= 0 (sc_rt.model.wheels.stribeck_switch).
bool wheel_stribeck_switch(bool on, double omega, double omega_start, const WheelFriction& f);

}  // namespace sc_rt
