#include "sc_rt/magnetic_control.hpp"

#include <stdexcept>

#include "sc_rt/util.hpp"

namespace sc_rt {

std::vector<std::string> validate(const MagneticConfig& c, const SpacecraftParams& wheels) {
  std::vector<std::string> errs;
  if (!c.active()) return errs;
  if (!c.rods_enabled) {
    errs.push_back(std::string("magnetic: ") + (c.momentum_enabled ? "momentum" : "bdot") +
                   " needs the rods (rods_enabled false)");
    return errs;
  }
  for (const std::string& e : validate(c.rods)) errs.push_back("magnetic.rods." + e);
  if (c.momentum_enabled)
    for (const std::string& e : validate(c.momentum, wheels)) errs.push_back("magnetic.momentum." + e);
  if (c.bdot_enabled)
    for (const std::string& e : validate(c.bdot)) errs.push_back("magnetic.bdot." + e);
  return errs;
}

MagneticControl::MagneticControl(const MagneticConfig& c, const SpacecraftParams& wheels) : cfg_(c) {
  throw_if_errors("MagneticConfig", validate(c, wheels));
  if (c.momentum_enabled) mgr_.emplace(c.momentum, wheels, c.rods);
  if (c.bdot_enabled) {
    bdot_.emplace(c.bdot, c.rods);
    mode_ = DetumbleMode::Detumble;  // the entry mode (magnetic_control.hpp)
  }
}

DetumbleMode MagneticControl::mode_at(double rate, MagneticOutput& out) {
  if (!bdot_) return DetumbleMode::Attitude;  // detumble_mode stays -1: no B-dot
  const DetumbleMode next = detumble_mode(mode_, rate, cfg_.bdot.rate_on, cfg_.bdot.rate_off);
  out.switched = next != mode_;
  if (out.switched && next == DetumbleMode::Detumble) bdot_state_ = BdotState{};  // a fresh derivative
  mode_ = next;
  out.detumble_mode = static_cast<int>(next);
  return next;
}

MagneticOutput MagneticControl::idle(const Vec3& B_B) const {
  MagneticOutput out;
  out.rod_dipole_cmd.setZero();
  out.m_B_cmd.setZero();
  out.B_B = B_B;
  if (mgr_) out.unloading = unloading_ ? 1 : 0;
  if (bdot_) out.detumble_mode = static_cast<int>(mode_);
  return out;
}

void MagneticControl::put_rods(const RodVec& d, const Vec3& m_B, MagneticOutput& out) const {
  out.rod_dipole_cmd.setZero();
  for (int i = 0; i < d.size(); ++i) out.rod_dipole_cmd(i) = d(i);
  out.m_B_cmd = m_B;
}

void MagneticControl::observe(const Vec4& wheel_speed, const Vec3& B_B, MagneticOutput& out) const {
  out.B_B = B_B;
  if (!mgr_) return;
  const Vec3 B = B_B.allFinite() ? B_B : Vec3::Zero();
  const MomentumOutput o = mgr_->update(wheel_speed, B, unloading_);
  out.h_wheels_B = o.h_wheels_B;
  out.wheel_fill = o.fill;
  out.unloading = unloading_ ? 1 : 0;  // the state held: a SAFE row commands nothing
}

void MagneticControl::detumble(double t, const Vec3& B_B, const Vec3& omega_BN_B, const Vec4& wheel_speed,
                               MagneticOutput& out) {
  unloading_ = false;  // no unloading while detumbling: the manager starts afresh in Attitude
  observe(wheel_speed, B_B, out);
  if (!B_B.allFinite()) return;  // no field known: the rods idle
  const BdotOutput o = bdot_->update(bdot_state_, t, B_B, omega_BN_B);
  bdot_state_ = o.state;
  put_rods(o.dipole, o.m_B, out);
}

void MagneticControl::attitude(const Vec4& wheel_speed, const Vec3& B_B, MagneticOutput& out) {
  out.B_B = B_B;
  if (!mgr_) return;
  // No field known: B = 0 gives no dipole and no feed-forward (null space only).
  const Vec3 B = B_B.allFinite() ? B_B : Vec3::Zero();
  const MomentumOutput o = mgr_->update(wheel_speed, B, unloading_);
  unloading_ = o.unloading;
  out.h_wheels_B = o.h_wheels_B;
  out.wheel_fill = o.fill;
  out.unloading = o.unloading ? 1 : 0;
  out.wheel_cmd = o.wheel_cmd;
  put_rods(o.dipole, o.m_B, out);
}

}  // namespace sc_rt
