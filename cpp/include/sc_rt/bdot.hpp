// B-dot detumbling (issue #43 item 5; docs/MODEL.md section 15): the rod
// dipoles that damp the body rate with the field's rate of change in B, the
// gain rule of Markley & Crassidis and the mode switch between detumbling and
// the attitude law.
//
//   m_B = -(k / |B|^2) dB_B/dt      normalized (default; k [N m s], the gain rule's)
//   m_B = -k dB_B/dt                normalized = false (k [A m^2 s / T])
//
// dB_B/dt is either a first-order difference of successive field samples,
// (B_i - B_{i-1}) / (t_i - t_{i-1}), through a first-order low-pass filter
// (time constant filter_tau; exact for a derivative held over the interval:
// Bdot_f <- Bdot_f + (1 - exp(-dt / tau)) (raw - Bdot_f); tau = 0: the raw
// difference), or the analytic -omega_BN_B x B_B (the field fixed in N over a
// sample: dB_B/dt = -omega x B). With the analytic form the torque is
// m x B = -k (I - b b') omega (b = B/|B|), so the kinetic energy
// 1/2 omega' J omega never increases: d/dt = omega' (m x B) <= 0, saturation
// (a positive scale) included.
//
// The rods: d = G+ m_B, scaled as a whole into the limits (DipoleAllocator).
#pragma once
#include "sc_rt/magnetorquer.hpp"

namespace sc_rt {

enum class BdotDerivative : int {
  Difference = 0,  //!< successive samples, filtered
  Analytic = 1,    //!< -omega_BN_B x B_B
};

enum class DetumbleMode : int {
  Detumble = 0,  //!< B-dot commands the rods; the attitude law is idle
  Attitude = 1,  //!< the attitude law (and the momentum manager)
};
const char* detumble_mode_name(DetumbleMode mode);

// The mode after this sample: Detumble while |omega| > rate_on (entered
// from Attitude above rate_on), Attitude once |omega| < rate_off (from
// Detumble); between the two the mode is kept (hysteresis). rate [rad/s].
DetumbleMode detumble_mode(DetumbleMode previous, double rate, double rate_on, double rate_off);

// Markley & Crassidis' B-dot gain, after Avanzini & Giulietti:
// k = 2 n (1 + sin xi_m) J_min [N m s]; n the orbit rate [rad/s], xi_m the
// orbit's magnetic inclination [rad], J_min the smallest principal inertia
// [kg m^2]. Throws for n < 0 or J_min <= 0.
double bdot_gain(double orbit_rate, double magnetic_inclination, double J_min);

struct BdotParams {
  double gain = 0.0;           //!< k: [N m s] normalized, [A m^2 s / T] otherwise; > 0
  bool normalized = true;      //!< divide by |B|^2 (the gain rule's form)
  BdotDerivative derivative = BdotDerivative::Difference;  //!< how dB_B/dt is formed
  double filter_tau = 0.0;     //!< [s] low-pass time constant of the difference (0: none)
  double rate_on = 0.035;      //!< [rad/s] detumble above (2 deg/s)
  double rate_off = 0.0087;    //!< [rad/s] attitude law below (0.5 deg/s), < rate_on
};

std::vector<std::string> validate(const BdotParams& p);

// What the difference form carries between samples (the caller keeps it).
struct BdotState {
  bool primed = false;          //!< a previous sample exists
  double t = 0.0;               //!< [s] the previous sample's time
  Vec3 B_B = Vec3::Zero();      //!< [T] the previous sample
  Vec3 Bdot_B = Vec3::Zero();   //!< [T/s] the filtered derivative
};

struct BdotOutput {
  Vec3 Bdot_B = Vec3::Zero();   //!< [T/s] the derivative used
  RodVec dipole;                //!< [A m^2] rod dipole commands
  Vec3 m_B = Vec3::Zero();      //!< [A m^2] G_B dipole
  double scale = 1.0;           //!< [-] saturation scale (1: none)
  BdotState state;              //!< pass to the next update
};

class Bdot {
 public:
  Bdot(const BdotParams& p, const MagnetorquerParams& rods);  // throws std::invalid_argument
  // The sample at t [s]: B_B [T] measured, omega_BN_B [rad/s] (Analytic only).
  // The difference form gives no dipole at its first sample, and keeps its
  // derivative when t does not advance.
  BdotOutput update(const BdotState& s, double t, const Vec3& B_B, const Vec3& omega_BN_B) const;
  const BdotParams& params() const { return p_; }

 private:
  BdotParams p_;
  DipoleAllocator alloc_;
};

}  // namespace sc_rt
