// The plant with torque-commanded reaction wheels (issue #28): the C++ twin of
// python/sc_rt/model/torque_plant.py, bitwise equal (tests/test_torque_plant.py).
//
//   M omega_dot = -omega^ (J omega + Cbar Jw Omega_w) - Cbar u + u_g + d,   M = J - Cbar diag(Jw) Cbar'
//   Omega_dot_i = u_i / Jw_i - g_i' omega_dot
//
// u: the motor torque after its limits (taken at the step's start speed, held
// over the step) plus the friction at each RK4 stage's speed (docs/MODEL.md,
// "Flight-like wheels").
#pragma once
#include <array>
#include <memory>

#include "sc_rt/plant.hpp"
#include "sc_rt/wheels.hpp"

namespace sc_rt {

class TorquePlant {
 public:
  //! Throws std::invalid_argument when M is not positive definite.
  TorquePlant(const PlantParams& p, const TorqueWheels& wheels);
  ~TorquePlant();
  TorquePlant(const TorquePlant&) = delete;
  TorquePlant& operator=(const TorquePlant&) = delete;
  //! One classical RK4 step from t to t + h [s], the motor commands u_cmd [N m] held.
  PlantState step(double t, const PlantState& x, double h, const Vec4& u_cmd) const;
  //! x_dot at (t, x) with the motor torques u_motor [N m] (after their limits).
  void derivative(double t, const double x[10], const double u_motor[4], double out[10]) const;
  //! The same with friction scales and seizure brakes (step_inputs).
  void derivative(double t, const double x[10], const double u_motor[4], const double scale[4],
                  const double brake[4], double out[10]) const;
  //! One RK4 step with the motor torques u, friction scales and brakes held.
  PlantState step_held(double t, const PlantState& x, double h, const double u[4], const double scale[4],
                       const double brake[4]) const;
  const Mat3& M() const { return M_; }

 private:
  struct Kernel;  // the right-hand side's constants (torque_plant.cpp)
  PlantParams p_;
  TorqueWheels w_;
  Mat3 M_;
  std::unique_ptr<const Kernel> k_;
};

}  // namespace sc_rt
