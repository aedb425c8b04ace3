#include "sc_rt/bdot.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "sc_rt/util.hpp"

namespace sc_rt {

const char* detumble_mode_name(DetumbleMode mode) {
  switch (mode) {
    case DetumbleMode::Detumble: return "detumble";
    case DetumbleMode::Attitude: return "attitude";
  }
  return "unknown";
}

DetumbleMode detumble_mode(DetumbleMode previous, double rate, double rate_on, double rate_off) {
  if (previous == DetumbleMode::Attitude) return rate > rate_on ? DetumbleMode::Detumble : DetumbleMode::Attitude;
  return rate < rate_off ? DetumbleMode::Attitude : DetumbleMode::Detumble;
}

double bdot_gain(double orbit_rate, double magnetic_inclination, double J_min) {
  if (!(std::isfinite(orbit_rate) && orbit_rate >= 0.0))
    throw std::invalid_argument("bdot_gain: orbit_rate must be finite and >= 0, got " + format_double(orbit_rate));
  if (!(std::isfinite(J_min) && J_min > 0.0))
    throw std::invalid_argument("bdot_gain: J_min must be finite and > 0, got " + format_double(J_min));
  if (!std::isfinite(magnetic_inclination))
    throw std::invalid_argument("bdot_gain: magnetic_inclination must be finite, got " +
                                format_double(magnetic_inclination));
  return 2.0 * orbit_rate * (1.0 + std::sin(magnetic_inclination)) * J_min;  // k = 2 n (1 + sin xi_m) J_min
}

std::vector<std::string> validate(const BdotParams& p) {
  std::vector<std::string> errs;
  if (!(std::isfinite(p.gain) && p.gain > 0.0))
    errs.push_back("gain must be finite and > 0, got " + format_double(p.gain));
  if (!(std::isfinite(p.filter_tau) && p.filter_tau >= 0.0))
    errs.push_back("filter_tau must be finite and >= 0, got " + format_double(p.filter_tau));
  if (p.derivative != BdotDerivative::Difference && p.derivative != BdotDerivative::Analytic)
    errs.push_back("derivative must be Difference (0) or Analytic (1), got " +
                   std::to_string(static_cast<int>(p.derivative)));
  if (!(std::isfinite(p.rate_on) && std::isfinite(p.rate_off) && 0.0 <= p.rate_off && p.rate_off < p.rate_on))
    errs.push_back("need 0 <= rate_off < rate_on, got rate_off " + format_double(p.rate_off) + ", rate_on " +
                   format_double(p.rate_on));
  return errs;
}

Bdot::Bdot(const BdotParams& p, const MagnetorquerParams& rods) : p_(p), alloc_(rods) {
  throw_if_errors("BdotParams", validate(p));
}

BdotOutput Bdot::update(const BdotState& s, double t, const Vec3& B_B, const Vec3& omega_BN_B) const {
  BdotOutput o;
  o.state = s;
  bool have = true;
  if (p_.derivative == BdotDerivative::Analytic) {
    o.Bdot_B = -omega_BN_B.cross(B_B);  // dB_B/dt = -omega x B, B fixed in N
  } else if (!s.primed) {
    have = false;  // the first sample: no difference yet
    o.state.primed = true;
    o.state.t = t;
    o.state.B_B = B_B;
    o.state.Bdot_B.setZero();
  } else if (t > s.t) {
    const double dt = t - s.t;
    const Vec3 raw = (B_B - s.B_B) / dt;
    const double a = p_.filter_tau > 0.0 ? -std::expm1(-dt / p_.filter_tau) : 1.0;
    o.state.Bdot_B = s.Bdot_B + a * (raw - s.Bdot_B);
    o.state.t = t;
    o.state.B_B = B_B;
    o.Bdot_B = o.state.Bdot_B;
  } else {
    o.Bdot_B = s.Bdot_B;  // time did not advance: the derivative held
  }
  Vec3 m = Vec3::Zero();
  if (have) {
    if (p_.normalized) {
      const double b2 = B_B.squaredNorm();
      if (b2 > 0.0) m = -(p_.gain / b2) * o.Bdot_B;
    } else {
      m = -p_.gain * o.Bdot_B;
    }
  }
  const DipoleAllocation a = alloc_.allocate(m);
  o.dipole = a.dipole;
  o.m_B = a.m_B;
  o.scale = a.scale;
  return o;
}

}  // namespace sc_rt
