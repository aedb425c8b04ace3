#include "sc_rt/momentum.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "sc_rt/mrp.hpp"
#include "sc_rt/util.hpp"

namespace sc_rt {

Vec3 torque_to_dipole(const Vec3& tau_B, const Vec3& B_B) {
  const double b2 = B_B.squaredNorm();
  if (!(b2 > 0.0)) return Vec3::Zero();
  return B_B.cross(tau_B) / b2;  // m = (B x tau) / |B|^2: m x B = tau - b (b . tau)
}

Vec3 cross_product_dipole(const Vec3& h_err_B, const Vec3& B_B, double k) {
  const double b2 = B_B.squaredNorm();
  if (!(b2 > 0.0)) return Vec3::Zero();
  return (k / b2) * h_err_B.cross(B_B);  // m = k (h_err x B) / |B|^2
}

const char* unload_kind_name(UnloadKind kind) {
  switch (kind) {
    case UnloadKind::CrossProduct: return "cross_product";
    case UnloadKind::Continuous: return "continuous";
  }
  return "unknown";
}

namespace {
double wheel_capacity(const SpacecraftParams& w) {
  double c = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 4; ++i) c = std::min(c, w.Jw(i) * w.wheel_speed_max(i));
  return c;
}
}  // namespace

std::vector<std::string> validate(const MomentumParams& p, const SpacecraftParams& wheels) {
  std::vector<std::string> errs = validate(wheels);
  if (!(std::isfinite(p.gain) && p.gain > 0.0))
    errs.push_back("gain must be finite and > 0, got " + format_double(p.gain));
  if (!(std::isfinite(p.null_gain) && p.null_gain >= 0.0))
    errs.push_back("null_gain must be finite and >= 0, got " + format_double(p.null_gain));
  if (!std::isfinite(p.null_bias)) errs.push_back("null_bias must be finite, got " + format_double(p.null_bias));
  if (p.kind != UnloadKind::CrossProduct && p.kind != UnloadKind::Continuous)
    errs.push_back("kind must be CrossProduct (0) or Continuous (1), got " + std::to_string(static_cast<int>(p.kind)));
  if (p.kind == UnloadKind::CrossProduct && p.hysteresis) {
    if (!(p.off_fraction >= 0.0 && p.off_fraction < p.on_fraction && p.on_fraction <= 1.0))
      errs.push_back("need 0 <= off_fraction < on_fraction <= 1, got off_fraction " +
                     format_double(p.off_fraction) + ", on_fraction " + format_double(p.on_fraction));
    if (!std::isfinite(p.capacity))
      errs.push_back("capacity must be finite, got " + format_double(p.capacity));
    else if (p.capacity <= 0.0 && !std::isfinite(wheel_capacity(wheels)))
      errs.push_back("capacity <= 0 takes min_i Jw_i wheel_speed_max_i, but wheel_speed_max is " +
                     format_matrix(wheels.wheel_speed_max) + ": give a capacity or finite speed limits");
  }
  return errs;
}

MomentumManager::MomentumManager(const MomentumParams& p, const SpacecraftParams& wheels,
                                 const MagnetorquerParams& rods)
    : p_(p),
      Cbar_(wheels.Cbar),
      Jw_(wheels.Jw),
      torque_command_(wheels.wheel_torque_command),
      alloc_(rods) {
  throw_if_errors("MomentumParams", validate(p, wheels));
  capacity_ = p.capacity > 0.0 ? p.capacity : wheel_capacity(wheels);
  // Cbar+ = Cbar' (Cbar Cbar')^-1 (validate: Cbar has rank 3)
  Cbar_pinv_ = Cbar_.transpose() * (Cbar_ * Cbar_.transpose()).inverse();
  null_proj_ = Eigen::Matrix4d::Identity() - Cbar_pinv_ * Cbar_;
  // The null vector: the right singular vector of the smallest (zero) singular value.
  const Eigen::JacobiSVD<Eigen::Matrix4d> svd(Eigen::Matrix4d(Cbar_pinv_ * Cbar_), Eigen::ComputeFullV);
  // Cbar+ Cbar projects onto the row space; its null direction is V's last column.
  null_ = svd.matrixV().col(3);
  int first = 0;
  while (first < 3 && std::abs(null_(first)) < 1e-12) ++first;
  if (null_(first) < 0.0) null_ = -null_;
  if (p.null_bias != 0.0) {
    // Omega_t = beta Jw^-1 n (body momentum Cbar Jw Omega_t = 0), with min_i |Omega_t_i| = |null_bias|.
    const Vec4 v = null_.cwiseQuotient(Jw_);
    const double vmin = v.cwiseAbs().minCoeff();
    if (!(vmin > 1e-9 * v.cwiseAbs().maxCoeff()))
      throw std::invalid_argument("invalid MomentumParams: null_bias " + format_double(p.null_bias) +
                                  " needs every wheel in the null space, but the null vector is " +
                                  format_matrix(null_));
    omega_t_ = (p.null_bias / vmin) * v;
  }
}

Vec4 MomentumManager::wheel_command(const Vec4& T) const {
  return torque_command_ ? T : Vec4(T.cwiseQuotient(Jw_));  // inverse of wheel_torque_command
}

MomentumOutput MomentumManager::update(const Vec4& wheel_speed, const Vec3& B_B, bool unloading) const {
  MomentumOutput o;
  const Vec4 dh_W = Jw_.cwiseProduct(wheel_speed - omega_t_);  // [N m s] per wheel
  o.h_wheels_B = Cbar_ * Jw_.cwiseProduct(wheel_speed);
  o.h_err_B = Cbar_ * dh_W;
  o.fill = o.h_err_B.norm() / capacity_;
  const int n = static_cast<int>(alloc_.params().G_B.cols());
  o.dipole = RodVec::Zero(n);
  if (p_.kind == UnloadKind::Continuous) {
    // Basilisk's mtbMomentumManagement: tau_ideal_W = -c Jw (Omega - Omega_t).
    o.unloading = true;
    const Vec4 tau_ideal_W = -p_.gain * dh_W;
    const Vec3 tau_ideal_B = Cbar_ * tau_ideal_W;
    // d = -(B~ G)+ tau_ideal_B, (B~ G)+ = (B~ G)' ((B~ G)(B~ G)')+ (3x3, symmetric)
    const RodAxes& G = alloc_.params().G_B;
    const RodAxes A = skew(B_B) * G;
    const Mat3 AAt = A * A.transpose();
    const Eigen::SelfAdjointEigenSolver<Mat3> es(AAt);
    const Vec3 lam = es.eigenvalues();
    const double lmax = lam.cwiseAbs().maxCoeff();
    Vec3 lam_inv = Vec3::Zero();
    // B~ G always has a zero singular value (along B); its eigenvalue here is rounding,
    // ~1e-16 lmax: eigenvalues below 1e-12 lmax (singular values below 1e-6 of the
    // largest) count as zero.
    for (int i = 0; i < 3; ++i)
      if (lmax > 0.0 && lam(i) > 1e-12 * lmax) lam_inv(i) = 1.0 / lam(i);
    const Mat3 AAt_pinv = es.eigenvectors() * lam_inv.asDiagonal() * es.eigenvectors().transpose();
    o.dipole = -(A.transpose() * (AAt_pinv * tau_ideal_B));
    const RodVec& dmax = alloc_.params().dipole_max;
    for (int i = 0; i < n; ++i) o.dipole(i) = std::min(std::max(o.dipole(i), -dmax(i)), dmax(i));
    o.m_B = G * o.dipole;
    o.torque_mag_B = magnetic_torque(o.m_B, B_B);  // -B~ G d
    const Vec4 T = tau_ideal_W + Cbar_pinv_ * (o.torque_mag_B - tau_ideal_B);
    o.torque_ff = Cbar_pinv_ * o.torque_mag_B;
    o.torque_null = T - o.torque_ff;  // = (I - Cbar+ Cbar) tau_ideal_W
    o.wheel_cmd = wheel_command(T);
    return o;
  }
  // Cross-product law with hysteresis on |h_err| / capacity.
  if (p_.hysteresis) {
    if (!unloading && o.fill > p_.on_fraction) unloading = true;
    else if (unloading && o.fill < p_.off_fraction) unloading = false;
  } else {
    unloading = true;
  }
  o.unloading = unloading;
  if (unloading) {
    const DipoleAllocation a = alloc_.allocate(cross_product_dipole(o.h_err_B, B_B, p_.gain));
    o.dipole = a.dipole;
    o.m_B = a.m_B;
    o.scale = a.scale;
    o.torque_mag_B = magnetic_torque(o.m_B, B_B);
    o.torque_ff = Cbar_pinv_ * o.torque_mag_B;  // -Cbar T_ff = -tau_mag on the body
  }
  if (p_.null_gain > 0.0) o.torque_null = -p_.null_gain * (null_proj_ * dh_W);
  o.wheel_cmd = wheel_command(o.torque_ff + o.torque_null);
  return o;
}

}  // namespace sc_rt
