#include "sc_rt/wheels.hpp"

#include <cmath>
#include <cstdlib>

namespace sc_rt {

double wheel_applied_torque(double u, double omega, const WheelLimits& lim) {
  if (lim.u_max > 0.0) {
    if (u > lim.u_max) {
      u = lim.u_max;
    } else if (u < -lim.u_max) {
      u = -lim.u_max;
    }
  }
  if (std::fabs(u) < lim.u_min) u = 0.0;
  if (lim.p_max > 0.0 && std::fabs(u * omega) >= lim.p_max) u = std::copysign(lim.p_max / std::fabs(omega), u);
  if (lim.omega_max > 0.0 && std::fabs(omega) >= lim.omega_max && omega * u >= 0.0) u = 0.0;
  return u;
}

namespace {
double friction(double omega, const WheelFriction& f, bool stribeck) {
  if (stribeck) {
    const double b = f.beta;
    return std::sqrt(2.0 * std::exp(1.0)) * (f.static_ - f.coulomb) * std::exp(-(omega / b) * (omega / b) / 2.0) *
               omega / (b * std::sqrt(2.0)) +
           f.coulomb * std::tanh(omega * 10.0 / b) + f.viscous * omega;
  }
  const double sign = static_cast<double>((omega > 0.0) - (omega < 0.0));
  return sign * f.coulomb + f.viscous * omega;
}
}  // namespace

double wheel_friction_torque(double omega, const WheelFriction& f, bool stribeck) {
  stribeck = stribeck && f.beta > 0.0;
  double force = friction(omega, f, stribeck);
  const double lc = f.omega_limit_cycle;
  if (lc > 0.0 && std::fabs(omega) < lc) force = friction(lc, f, stribeck) / lc * omega;
  return -force;
}

bool wheel_stribeck_switch(bool on, double omega, double omega_start, const WheelFriction& f) {
  if (!(f.beta > 0.0)) return false;
  if (std::fabs(omega) < 0.1 * f.omega_limit_cycle) on = true;  // near rest: on
  const int s = (omega > 0.0) - (omega < 0.0);
  const double d = omega - omega_start;
  const int sd = (d > 0.0) - (d < 0.0);
  return on && std::abs(s - sd) < 2;  // off while |omega| decreases
}

}  // namespace sc_rt
