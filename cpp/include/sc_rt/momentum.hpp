// Momentum management with magnetorquers (issue #43 item 4; docs/MODEL.md
// section 14): a component beside the attitude law, so it works with every
// law. Given the wheel speeds and the field in B, it returns rod dipole
// commands and a wheel command to add to the law's, such that the magnetic
// torque goes into the wheels (the body sees none) and removes the wheels'
// excess momentum.
//
// Frames and signs. h_w_B = Cbar Jw Omega is the wheels' momentum in B
// (Omega the speeds relative to the body, as in (3)); h_err_B = Cbar Jw
// (Omega - Omega_t), Omega_t the target speeds. A wheel motor torque T
// [N m] (one per wheel) puts -Cbar T on the body (docs/MODEL.md section 2,
// torque-commanded wheels; Jw times the acceleration on acceleration-commanded
// wheels). With the body held, an external torque tau goes into the wheels:
// d h_w / dt = tau. So the magnetic torque must be opposite to h_err:
//   cross-product law  m_B = k (h_err x B) / |B|^2,  k > 0 [1/s]
//   => tau = m x B = -k (I - b b') h_err   (b = B / |B|; (a x B) x B = B (a.B) - a |B|^2)
// which removes the part of h_err perpendicular to B at the rate k, and
// |tau| = k |h_err perpendicular to B|.
//
// The wheel feed-forward: T_ff = Cbar+ tau_mag (Cbar+ = Cbar' (Cbar Cbar')^-1,
// the minimum-norm motor torques), so that the wheels put -Cbar T_ff =
// -tau_mag on the body and the body sees m x B - tau_mag = 0.
//
// Null-space management (four wheels, null_gain > 0): T_null = -k_n (I - Cbar+
// Cbar) Jw (Omega - Omega_t), whose body torque -Cbar T_null is zero by
// construction; the wheels' momentum error in the null space of Cbar decays
// at the rate k_n, toward target speeds Omega_t that a null_bias keeps away
// from zero.
//
// Basilisk's continuous form (mtbMomentumManagement, after Hogan & Schaub):
// tau_ideal_W = -c Jw (Omega - Omega_t), tau_ideal_B = Cbar tau_ideal_W; the
// rod dipoles d = -(B~ G)+ tau_ideal_B (least squares), each clipped to its
// limit; tau_mag = -B~ G d; T = tau_ideal_W + Cbar+ (tau_mag - tau_ideal_B).
// The same as the cross-product law with k = c, null-space management with
// k_n = c and the feed-forward, but with Basilisk's allocation and per-rod
// clipping and without hysteresis.
#pragma once
#include "sc_rt/magnetorquer.hpp"
#include "sc_rt/spacecraft.hpp"

namespace sc_rt {

// The body dipole [A m^2] whose torque in the field B_B [T] is the part of
// tau_B [N m] perpendicular to B: m = (B x tau) / |B|^2 (Basilisk's
// torque2Dipole); zero when B = 0.
Vec3 torque_to_dipole(const Vec3& tau_B, const Vec3& B_B);

// The cross-product law's body dipole [A m^2]: m = k (h_err x B) / |B|^2,
// h_err_B [N m s], B_B [T], k [1/s]; zero when B = 0.
Vec3 cross_product_dipole(const Vec3& h_err_B, const Vec3& B_B, double k);

enum class UnloadKind : int {
  CrossProduct = 0,  //!< m = k (h_err x B)/|B|^2, direction-keeping saturation, hysteresis
  Continuous = 1,    //!< Basilisk's mtbMomentumManagement (always on, per-rod clipping)
};
const char* unload_kind_name(UnloadKind kind);

struct MomentumParams {
  UnloadKind kind = UnloadKind::CrossProduct;  //!< which unloading law
  double gain = 0.005;          //!< [1/s] k (c of the continuous form), > 0
  bool hysteresis = true;       //!< CrossProduct only: on above on_fraction, off below off_fraction
  double on_fraction = 0.5;     //!< [-] unloading turns on when |h_err| > on_fraction * capacity
  double off_fraction = 0.1;    //!< [-] and off when |h_err| < off_fraction * capacity
  double capacity = 0.0;        //!< [N m s] wheel momentum capacity; <= 0: min_i Jw_i wheel_speed_max_i
  double null_gain = 0.0;       //!< [1/s] null-space management k_n (0: off); Continuous uses gain
  double null_bias = 0.0;       //!< [rad/s] the target speeds' smallest magnitude along the null vector (0: zero speeds)
};

// Every problem with the parameters (and the wheels they need), each naming the bad value.
std::vector<std::string> validate(const MomentumParams& p, const SpacecraftParams& wheels);

struct MomentumOutput {
  bool unloading = false;           //!< the hysteresis state after this update (the caller keeps it)
  double fill = 0.0;                //!< [-] |h_err_B| / capacity
  Vec3 h_wheels_B = Vec3::Zero();   //!< [N m s] Cbar Jw Omega
  Vec3 h_err_B = Vec3::Zero();      //!< [N m s] Cbar Jw (Omega - Omega_t)
  RodVec dipole;                    //!< [A m^2] rod dipole commands (within the limits)
  Vec3 m_B = Vec3::Zero();          //!< [A m^2] G_B dipole
  double scale = 1.0;               //!< [-] CrossProduct's saturation scale (1: none)
  Vec3 torque_mag_B = Vec3::Zero(); //!< [N m] m_B x B_B, the torque the rods should give
  Vec4 torque_ff = Vec4::Zero();    //!< [N m] motor torques cancelling torque_mag_B on the body
  Vec4 torque_null = Vec4::Zero();  //!< [N m] null-space motor torques (no body torque)
  Vec4 wheel_cmd = Vec4::Zero();    //!< the two together in the wheels' command unit, to add to the law's
};

class MomentumManager {
 public:
  // wheels: Cbar, Jw, wheel_speed_max (finite when capacity <= 0), wheel_torque_command;
  // rods: the controller's knowledge of the magnetorquers. Throws std::invalid_argument.
  MomentumManager(const MomentumParams& p, const SpacecraftParams& wheels, const MagnetorquerParams& rods);
  // wheel_speed [rad/s] (Omega, relative to the body), B_B [T] (measured),
  // unloading: the state the previous update returned (false at the start).
  MomentumOutput update(const Vec4& wheel_speed, const Vec3& B_B, bool unloading) const;

  const MomentumParams& params() const { return p_; }
  double capacity() const { return capacity_; }           //!< [N m s]
  const Vec4& omega_target() const { return omega_t_; }   //!< [rad/s] Omega_t
  const Vec4& null_vector() const { return null_; }       //!< [-] unit n, Cbar n = 0, first nonzero entry > 0
  const Mat43& Cbar_pinv() const { return Cbar_pinv_; }   //!< Cbar' (Cbar Cbar')^-1
  // The motor torques T [N m] as the wheels' command (T / Jw on acceleration-commanded wheels).
  Vec4 wheel_command(const Vec4& T) const;

 private:
  MomentumParams p_;
  Mat34 Cbar_;                  // [-] wheel axes in B
  Vec4 Jw_;                     // [kg m^2] wheel spin inertias
  bool torque_command_;         // the wheels take motor torques [N m], else accelerations [rad/s^2]
  DipoleAllocator alloc_;       // the rods as the controller knows them
  double capacity_ = 0.0;       // [N m s]
  Mat43 Cbar_pinv_;             // [-] Cbar' (Cbar Cbar')^-1
  Eigen::Matrix4d null_proj_;   // [-] I - Cbar+ Cbar, onto the null space of Cbar
  Vec4 null_ = Vec4::Zero();    // [-] unit null vector of Cbar
  Vec4 omega_t_ = Vec4::Zero(); // [rad/s] target speeds
};

}  // namespace sc_rt
