#include "sc_rt/magnetorquer.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "sc_rt/util.hpp"

namespace sc_rt {

const char* rod_fault_name(RodFault f) {
  switch (f) {
    case RodFault::Healthy: return "healthy";
    case RodFault::Dead: return "dead";
    case RodFault::Stuck: return "stuck";
    case RodFault::Reversed: return "reversed";
  }
  return "unknown";
}

std::vector<std::string> validate(const MagnetorquerParams& p) {
  std::vector<std::string> errs;
  const auto n = p.G_B.cols();
  if (n < 1 || n > kMaxRods) {
    errs.push_back("G_B must have 1 to " + std::to_string(kMaxRods) + " columns (rods), got " +
                   std::to_string(n));
    return errs;
  }
  if (p.dipole_max.size() != n)
    errs.push_back("dipole_max has " + std::to_string(p.dipole_max.size()) + " entries for " +
                   std::to_string(n) + " rods");
  if (!p.G_B.allFinite()) errs.push_back("G_B is not finite: " + format_matrix(p.G_B));
  else
    for (int i = 0; i < n; ++i) {
      const double len = p.G_B.col(i).norm();
      if (std::abs(len - 1.0) > 1e-6)
        errs.push_back("rod " + std::to_string(i + 1) + "'s axis is not a unit vector (norm " +
                       format_double(len) + ")");
    }
  for (int i = 0; i < p.dipole_max.size(); ++i)
    if (!(std::isfinite(p.dipole_max(i)) && p.dipole_max(i) > 0.0))
      errs.push_back("dipole_max of rod " + std::to_string(i + 1) + " must be finite and > 0, got " +
                     format_double(p.dipole_max(i)));
  return errs;
}

Magnetorquers::Magnetorquers(const MagnetorquerParams& p) : p_(p) {
  throw_if_errors("MagnetorquerParams", validate(p));
  fault_.fill(RodFault::Healthy);
  stuck_.fill(0.0);
}

void Magnetorquers::set_fault(int rod, RodFault fault, double stuck_dipole) {
  if (rod < 0 || rod >= n_rods())
    throw std::invalid_argument("set_fault: rod " + std::to_string(rod) + " outside [0, " +
                                std::to_string(n_rods()) + ")");
  if (!std::isfinite(stuck_dipole))
    throw std::invalid_argument("set_fault: stuck_dipole must be finite, got " + format_double(stuck_dipole));
  if (fault == RodFault::Stuck && std::abs(stuck_dipole) > p_.dipole_max(rod))  // a rod saturates
    throw std::invalid_argument("set_fault: rod " + std::to_string(rod) + " stuck at " + format_double(stuck_dipole) +
                                " A m^2, beyond its dipole_max " + format_double(p_.dipole_max(rod)) + " A m^2");
  fault_[rod] = fault;
  stuck_[rod] = stuck_dipole;
}

RodFault Magnetorquers::fault(int rod) const {
  if (rod < 0 || rod >= n_rods())
    throw std::invalid_argument("fault: rod " + std::to_string(rod) + " outside [0, " +
                                std::to_string(n_rods()) + ")");
  return fault_[rod];
}

MagnetorquerOutput Magnetorquers::update(const RodVec& d_cmd, const Vec3& B_B) const {
  const int n = n_rods();
  if (d_cmd.size() != n)
    throw std::invalid_argument("Magnetorquers.update: " + std::to_string(d_cmd.size()) +
                                " dipole commands for " + std::to_string(n) + " rods");
  MagnetorquerOutput out;
  out.dipole.resize(n);  // inline storage: no allocation
  for (int i = 0; i < n; ++i) {
    const double lim = p_.dipole_max(i);
    double d = d_cmd(i);
    if (d > lim || d < -lim) out.clipped |= 1 << i;
    d = std::min(std::max(d, -lim), lim);  // per-rod clip, as MtbEffector
    switch (fault_[i]) {
      case RodFault::Healthy: break;
      case RodFault::Dead: d = 0.0; break;
      case RodFault::Stuck: d = stuck_[i]; break;
      case RodFault::Reversed: d = -d; break;
    }
    out.dipole(i) = d;
  }
  out.m_B = p_.G_B * out.dipole;                   // m = G d
  out.torque_B = magnetic_torque(out.m_B, B_B);    // tau = m x B
  return out;
}

DipoleAllocator::DipoleAllocator(const MagnetorquerParams& p) : p_(p) {
  throw_if_errors("MagnetorquerParams", validate(p));
  // Moore-Penrose pseudo-inverse of G (3 x N, any rank), once: singular
  // values below 1e-12 of the largest are treated as zero.
  const Eigen::MatrixXd G = p.G_B;
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(G, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd s = svd.singularValues();
  Eigen::VectorXd s_inv = Eigen::VectorXd::Zero(s.size());
  for (int i = 0; i < s.size(); ++i)
    if (s(i) > 1e-12 * s(0)) s_inv(i) = 1.0 / s(i);
  const Eigen::MatrixXd pinv = svd.matrixV() * s_inv.asDiagonal() * svd.matrixU().transpose();
  G_pinv_ = pinv;
}

DipoleAllocation DipoleAllocator::allocate(const Vec3& m_B) const {
  DipoleAllocation a;
  a.dipole = G_pinv_ * m_B;  // d = G+ m
  double scale = 1.0;
  for (int i = 0; i < a.dipole.size(); ++i) {
    const double mag = std::abs(a.dipole(i));
    if (mag > p_.dipole_max(i)) scale = std::min(scale, p_.dipole_max(i) / mag);
  }
  if (scale < 1.0) a.dipole *= scale;  // the whole vector: its direction kept
  a.scale = scale;
  a.m_B = p_.G_B * a.dipole;
  return a;
}

}  // namespace sc_rt
