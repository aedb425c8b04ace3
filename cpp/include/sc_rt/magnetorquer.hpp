// Magnetorquers (issue #43 item 3; docs/MODEL.md section 13): N rods with unit
// axes in B and per-rod dipole limits, their faults, the torque of a magnetic
// dipole in the field, and the allocation of a body dipole onto the rods.
//
// Sign convention (the same as Basilisk's MtbEffector, whose computeForceTorque
// writes tau = -B~ G_t mu, i.e. -(B x m) = m x B):
//   m_B   = G_B d               body dipole [A m^2] of the rod dipoles d
//   tau_B = m_B x B_B           torque on the body [N m], B_B the field in B [T]
// A residual spacecraft dipole m_res_B is a disturbance through the same
// magnetic_torque(m_res_B, B_B).
//
// Fixed-capacity Eigen types (at most kMaxRods rods): no heap allocation in
// any update.
#pragma once
#include <array>
#include <string>
#include <vector>

#include "sc_rt/types.hpp"

namespace sc_rt {

constexpr int kMaxRods = 6;  //!< the most rods a magnetorquer set may have
//! [A m^2] one number per rod (size N, storage inline)
using RodVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxRods, 1>;
//! [-] rod axes in B, one column per rod (3 x N, storage inline)
using RodAxes = Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kMaxRods>;
//! the pseudo-inverse of RodAxes (N x 3)
using RodPinv = Eigen::Matrix<double, Eigen::Dynamic, 3, 0, kMaxRods, 3>;

// The torque [N m] on a magnetic dipole m_B [A m^2] in the field B_B [T]:
// tau = m x B (Basilisk's MtbEffector: -B~ m).
inline Vec3 magnetic_torque(const Vec3& m_B, const Vec3& B_B) { return m_B.cross(B_B); }

// What happens to one rod's dipole.
enum class RodFault : int {
  Healthy = 0,   //!< the commanded dipole, clipped to the rod's limit
  Dead = 1,      //!< 0 whatever the command
  Stuck = 2,     //!< a fixed dipole whatever the command (set_fault's stuck_dipole)
  Reversed = 3,  //!< the clipped command with its sign reversed (polarity wired backwards)
};
const char* rod_fault_name(RodFault f);

struct MagnetorquerParams {
  RodAxes G_B = RodAxes::Identity(3, 3);         //!< [-] unit rod axes in B (3 x N, 1 <= N <= kMaxRods)
  RodVec dipole_max = RodVec::Constant(3, 10.0);  //!< [A m^2] per-rod limit |d_i| <= dipole_max_i, > 0
};

// Every problem with the parameters, each naming the bad value; empty if valid.
std::vector<std::string> validate(const MagnetorquerParams& p);

struct MagnetorquerOutput {
  RodVec dipole;               //!< [A m^2] applied rod dipoles (after the limits and the faults)
  Vec3 m_B = Vec3::Zero();     //!< [A m^2] body dipole G_B dipole
  Vec3 torque_B = Vec3::Zero();  //!< [N m] m_B x B_B
  int clipped = 0;             //!< bit i: rod i's command was beyond its limit
};

// The rods of the plant: command in, applied dipoles and torque out. Faults
// can be injected live (set_fault: no allocation).
class Magnetorquers {
 public:
  explicit Magnetorquers(const MagnetorquerParams& p);  // throws std::invalid_argument
  int n_rods() const { return static_cast<int>(p_.G_B.cols()); }
  const MagnetorquerParams& params() const { return p_; }
  // Rod i's fault from now on (stuck_dipole [A m^2] is used by RodFault::Stuck only,
  // |stuck_dipole| <= the rod's dipole_max: std::invalid_argument otherwise).
  void set_fault(int rod, RodFault fault, double stuck_dipole = 0.0);
  RodFault fault(int rod) const;
  // d_cmd [A m^2] (size N) in the field B_B [T]: each rod clipped to
  // +-dipole_max_i, then its fault applied; m = G d; tau = m x B.
  MagnetorquerOutput update(const RodVec& d_cmd, const Vec3& B_B) const;

 private:
  MagnetorquerParams p_;
  std::array<RodFault, kMaxRods> fault_{};  // per rod
  std::array<double, kMaxRods> stuck_{};    // [A m^2] a stuck rod's dipole
};

// The controller's side: a body dipole onto the rods, d = G+ m_B (G+ the
// Moore-Penrose pseudo-inverse of G_B, computed once), then, if any rod is
// beyond its limit, the whole vector scaled by min_i dipole_max_i / |d_i| so
// that its direction is kept.
struct DipoleAllocation {
  RodVec dipole;         //!< [A m^2] rod dipoles, within the limits
  Vec3 m_B = Vec3::Zero();  //!< [A m^2] the body dipole they give, G_B dipole
  double scale = 1.0;    //!< [-] the saturation's scale factor (1: none)
};

class DipoleAllocator {
 public:
  explicit DipoleAllocator(const MagnetorquerParams& p);  // throws std::invalid_argument
  const RodPinv& G_pinv() const { return G_pinv_; }
  const MagnetorquerParams& params() const { return p_; }
  DipoleAllocation allocate(const Vec3& m_B) const;

 private:
  MagnetorquerParams p_;
  RodPinv G_pinv_;  // [-] Moore-Penrose pseudo-inverse of G_B (N x 3)
};

}  // namespace sc_rt
