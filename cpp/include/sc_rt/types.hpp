// Fixed-size Eigen types used throughout the core (no heap allocation), and
// the one conversion both the plant (wheels.hpp) and a law (law.hpp's
// LawModel) need, here because a plugin gets this header and law.hpp only.
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>  // cross()

namespace sc_rt {
using Vec3 = Eigen::Vector3d;
using Vec4 = Eigen::Matrix<double, 4, 1>;
using Mat3 = Eigen::Matrix3d;
using Mat34 = Eigen::Matrix<double, 3, 4>;
using Mat43 = Eigen::Matrix<double, 4, 3>;

// The motor torque [N m] a wheel command u asks of a wheel of spin inertia Jw:
// Jw u for an acceleration command [rad/s^2], u for a torque command.
inline double wheel_torque_command(double u, double Jw, bool torque_command) {
  return torque_command ? u : Jw * u;
}
}  // namespace sc_rt
