#include "sc_rt/spacecraft.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "sc_rt/mrp.hpp"
#include "sc_rt/util.hpp"

namespace sc_rt {

std::vector<std::string> validate(const SpacecraftParams& p) {
  std::vector<std::string> errs;
  auto fmt = [](const auto& m) { return format_matrix(m); };
  if (!p.J0.allFinite()) errs.push_back("J0 is not finite: " + fmt(p.J0));
  else {
    if ((p.J0 - p.J0.transpose()).cwiseAbs().maxCoeff() > 1e-9 * p.J0.cwiseAbs().maxCoeff())
      errs.push_back("J0 is not symmetric: " + fmt(p.J0));
    const Eigen::SelfAdjointEigenSolver<Mat3> es(0.5 * (p.J0 + p.J0.transpose()));
    if (es.eigenvalues().minCoeff() <= 0.0)
      errs.push_back("J0 is not positive definite (eigenvalues " + fmt(es.eigenvalues()) +
                     "): " + fmt(p.J0));
  }
  if (!p.Cbar.allFinite()) errs.push_back("Cbar is not finite: " + fmt(p.Cbar));
  else {
    for (int i = 0; i < 4; ++i) {
      const double n = p.Cbar.col(i).norm();
      if (std::abs(n - 1.0) > 1e-2)
        errs.push_back("Cbar column " + std::to_string(i + 1) + " is not a unit vector (norm " +
                       format_double(n) + ")");
    }
    const Eigen::JacobiSVD<Mat34> svd(p.Cbar);
    const auto sv = svd.singularValues();
    if (sv(2) < 1e-6 * sv(0))
      errs.push_back("Cbar is rank-deficient (singular values " + fmt(sv) +
                     "): the wheels cannot produce torque about every axis");
  }
  for (int i = 0; i < 4; ++i) {
    const std::string w = "wheel " + std::to_string(i + 1);
    if (!(std::isfinite(p.Jw(i)) && p.Jw(i) > 0.0))
      errs.push_back("Jw of " + w + " must be > 0, got " + format_double(p.Jw(i)));
    if (!(std::isfinite(p.umin(i)) && std::isfinite(p.umax(i))))
      errs.push_back("umin/umax of " + w + " must be finite, got " + format_double(p.umin(i)) +
                     ", " + format_double(p.umax(i)));
    else if (!(p.umin(i) < p.umax(i)))
      errs.push_back("umin >= umax for " + w + ": umin = " + format_double(p.umin(i)) +
                     ", umax = " + format_double(p.umax(i)));
  }
  if (!(std::isfinite(p.w0) && p.w0 >= 0.0))
    errs.push_back("w0 must be finite and >= 0, got " + format_double(p.w0));
  if (!(std::isfinite(p.pinv_damping) && p.pinv_damping >= 0.0))
    errs.push_back("pinv_damping must be finite and >= 0, got " + format_double(p.pinv_damping));
  return errs;
}

SpacecraftModel::SpacecraftModel(const SpacecraftParams& p) : p_(p) {
  throw_if_errors("SpacecraftParams", validate(p));
  J0inv_ = p.J0.inverse();
  // (21): B = -J0^-1 Cbar Jw, Jw = diag of the wheel inertias.
  B_ = -J0inv_ * p.Cbar * p.Jw.asDiagonal();
  const Mat3 BBt = B_ * B_.transpose();
  const Eigen::JacobiSVD<Mat34> svd(B_);
  const auto sv = svd.singularValues();
  if (p.pinv_damping == 0.0 && sv(2) < 1e-9 * sv(0)) {
    std::ostringstream os;
    os << "B = -J0^-1 Cbar Jw is rank-deficient (singular values " << format_matrix(sv)
       << "): set pinv_damping > 0 for a damped pseudo-inverse";
    throw std::invalid_argument(os.str());
  }
  const double d2 = p.pinv_damping * p.pinv_damping;
  Bp_ = B_.transpose() * (BBt + d2 * Mat3::Identity()).inverse();
}

Vec4 SpacecraftModel::saturate(const Vec4& u) const {
  return u.cwiseMax(p_.umin).cwiseMin(p_.umax);
}

Vec3 gravity_gradient(const Mat3& J, const Vec3& sigma_BN, double w0) {
  // (5),(6): R3 is the third column of R(sigma) (nadir in B)
  const Vec3 R3 = mrp_to_dcm(sigma_BN).col(2);
  return 3.0 * w0 * w0 * R3.cross(J * R3);
}

}  // namespace sc_rt
