// The controller's magnetic part (issue #43 items 4 and 5; docs/MODEL.md
// section 17): the momentum manager (momentum.hpp) and B-dot detumbling
// (bdot.hpp) composed beside the attitude law, so they work with every law
// (built-in, plugin, Python). The Controller owns one and calls it at each
// step; the law sees none of it.
//
//   Attitude mode:  wheel command = the law's (in the wheels' unit) + the
//                   manager's feed-forward and null-space torques (in the
//                   wheels' unit, MomentumManager::wheel_command), then the
//                   controller's saturation; rod dipoles from the manager.
//   Detumble mode:  rod dipoles from B-dot, the wheels commanded zero, the
//                   law not stepped (re-engaged at the switch to Attitude).
//   The mode:       detumble_mode(previous, |omega_BN_B| measured, rate_on,
//                   rate_off) when B-dot is enabled, else always Attitude.
//                   With B-dot the controller starts in Detumble, as flight
//                   software enters its detumble mode after separation (or,
//                   here, a capture): it leaves below rate_off (at its first
//                   step when the body is already that slow) and re-enters
//                   only above rate_on, a safety threshold above any rate the
//                   attitude law commands.
//
// The field B_B [T] is the measured field in B (the true one on runs
// without a magnetometer); a non-finite B_B (no field known) gives zero rod
// dipoles and no feed-forward, the states kept.
//
// Pure: fixed-size Eigen types, no allocation in step(), bounded work.
#pragma once
#include <Eigen/Core>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "sc_rt/bdot.hpp"
#include "sc_rt/magnetorquer.hpp"
#include "sc_rt/momentum.hpp"
#include "sc_rt/spacecraft.hpp"

namespace sc_rt {

//! [A m^2] the rod dipole commands of a row: rod i in entry i, 0 beyond the rods given
using RodCmd = Eigen::Matrix<double, kMaxRods, 1>;

//! The controller's knowledge of the magnetorquers and what it does with them.
struct MagneticConfig {
  bool rods_enabled = false;       //!< the controller knows rods (needed by either part)
  MagnetorquerParams rods{};       //!< nominal rods (no faults): axes G_B [-], limits [A m^2]
  bool momentum_enabled = false;   //!< run the momentum manager in Attitude mode
  MomentumParams momentum{};       //!< its parameters (momentum.hpp)
  bool bdot_enabled = false;       //!< B-dot detumbling as a controller mode
  BdotParams bdot{};               //!< its parameters (bdot.hpp)
  //! Either part enabled: the controller runs the magnetic part at all.
  bool active() const { return momentum_enabled || bdot_enabled; }
};

// Every problem, each naming the key ("magnetic.rods", "magnetic.momentum",
// "magnetic.bdot") and the value; empty if valid (or nothing enabled).
std::vector<std::string> validate(const MagneticConfig& c, const SpacecraftParams& wheels);

//! What the magnetic part decided at one step (Command's magnetic fields).
struct MagneticOutput {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  RodCmd rod_dipole_cmd = RodCmd::Constant(kNaN);  //!< [A m^2] rod dipole commands (within the limits)
  Vec3 m_B_cmd = Vec3::Constant(kNaN);     //!< [A m^2] G_B rod_dipole_cmd, the body dipole commanded
  Vec3 B_B = Vec3::Constant(kNaN);         //!< [T] the field the controller used
  Vec3 h_wheels_B = Vec3::Constant(kNaN);  //!< [N m s] Cbar Jw Omega measured
  double wheel_fill = kNaN;                //!< [-] |h_err_B| / capacity (NaN: no manager)
  int unloading = -1;                      //!< 1 unloading, 0 not, -1 no manager
  int detumble_mode = -1;                  //!< DetumbleMode (0 detumble, 1 attitude), -1 no B-dot
  bool switched = false;                   //!< the detumble mode changed at this step
  Vec4 wheel_cmd = Vec4::Zero();           //!< the manager's wheel command, wheels' unit
  bool detumbling() const { return detumble_mode == static_cast<int>(DetumbleMode::Detumble); }
};

class MagneticControl {
 public:
  // Throws std::invalid_argument (validate's messages) for an active config.
  MagneticControl(const MagneticConfig& c, const SpacecraftParams& wheels);
  //! The mode for the measured rate [rad/s] (B-dot's hysteresis; Attitude
  //! without B-dot), stored; sets out.detumble_mode and out.switched.
  DetumbleMode mode_at(double rate, MagneticOutput& out);
  //! Detumble: B-dot's rod dipoles at t [s] from B_B [T] and omega_BN_B [rad/s]
  //! (the manager, if any, idle: its momentum fields from wheel_speed [rad/s]).
  void detumble(double t, const Vec3& B_B, const Vec3& omega_BN_B, const Vec4& wheel_speed,
                MagneticOutput& out);
  //! Attitude: the manager's rod dipoles and wheel command (zero without it)
  //! from the measured wheel speeds [rad/s] and B_B [T].
  void attitude(const Vec4& wheel_speed, const Vec3& B_B, MagneticOutput& out);
  //! The manager's momentum fields without a command (SAFE rows).
  void observe(const Vec4& wheel_speed, const Vec3& B_B, MagneticOutput& out) const;
  //! A row's output before the step decides: rods at zero, the states as held.
  MagneticOutput idle(const Vec3& B_B) const;
  DetumbleMode mode() const { return mode_; }
  bool unloading() const { return unloading_; }
  const MagneticConfig& config() const { return cfg_; }

 private:
  void put_rods(const RodVec& d, const Vec3& m_B, MagneticOutput& out) const;
  MagneticConfig cfg_;
  std::optional<MomentumManager> mgr_;
  std::optional<Bdot> bdot_;
  bool unloading_ = false;                       // the manager's hysteresis state
  BdotState bdot_state_{};                       // B-dot's derivative state
  DetumbleMode mode_ = DetumbleMode::Attitude;   // the current mode (Detumble at the start with B-dot)
};

}  // namespace sc_rt
