// The plant with torque-commanded wheels: every expression in the order of
// its Python twin (python/sc_rt/model/torque_plant.py), so that both give
// the same bits (see plant_kernels.hpp on why no Eigen products here).
#include "sc_rt/torque_plant.hpp"

#include <Eigen/Eigenvalues>
#include <stdexcept>
#include <string>

#include "plant_kernels.hpp"

namespace sc_rt {

struct TorquePlant::Kernel {
  detail::Rhs rhs;
  double C[3][4], CJ[3][4], Jw[4];
  Kernel(const PlantParams& p, const Mat3& M) : rhs(p.J0 + p.dJ, M, p.w0) {
    for (int i = 0; i < 4; ++i) Jw[i] = p.Jw(i);
    for (int r = 0; r < 3; ++r)
      for (int i = 0; i < 4; ++i) C[r][i] = p.Cbar(r, i), CJ[r][i] = p.Cbar(r, i) * p.Jw(i);
  }
};

TorquePlant::TorquePlant(const PlantParams& p, const TorqueWheels& wheels) : p_(p), w_(wheels) {
  const Mat3 J = p.J0 + p.dJ;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      double m = J(r, c);
      for (int i = 0; i < 4; ++i) m -= (p.Cbar(r, i) * p.Jw(i)) * p.Cbar(c, i);
      M_(r, c) = m;
    }
  Eigen::SelfAdjointEigenSolver<Mat3> es(0.5 * (M_ + M_.transpose()));
  if (!(es.eigenvalues().minCoeff() > 0.0))
    throw std::invalid_argument("TorquePlant: J - Cbar diag(Jw) Cbar' is not positive definite");
  k_ = std::make_unique<const Kernel>(p, M_);
}

TorquePlant::~TorquePlant() = default;

void TorquePlant::derivative(double t, const double x[10], const double u_motor[4], double out[10]) const {
  const Kernel& k = *k_;
  double u[4];
  for (int i = 0; i < 4; ++i)
    u[i] = u_motor[i] + wheel_friction_torque(x[6 + i], w_.friction[static_cast<std::size_t>(i)], w_.stribeck);
  double hw[3], tw[3], d[3], sw[6];
  for (int r = 0; r < 3; ++r) {
    hw[r] = k.CJ[r][0] * x[6] + k.CJ[r][1] * x[7] + k.CJ[r][2] * x[8] + k.CJ[r][3] * x[9];
    tw[r] = k.C[r][0] * u[0] + k.C[r][1] * u[1] + k.C[r][2] * u[2] + k.C[r][3] * u[3];
  }
  detail::dist3(p_, t, d);
  k.rhs(x, x + 3, hw, tw, d, sw);
  for (int i = 0; i < 6; ++i) out[i] = sw[i];
  for (int i = 0; i < 4; ++i)
    out[6 + i] = u[i] / k.Jw[i] - (k.C[0][i] * sw[3] + k.C[1][i] * sw[4] + k.C[2][i] * sw[5]);
}

PlantState TorquePlant::step(double t, const PlantState& x, double h, const Vec4& u_cmd) const {
  double x0[10];
  for (int i = 0; i < 3; ++i) x0[i] = x.sigma_BN(i), x0[3 + i] = x.omega_BN_B(i);
  for (int i = 0; i < 4; ++i) x0[6 + i] = x.wheel_speed(i);
  double u[4];
  for (int i = 0; i < 4; ++i)
    u[i] = wheel_applied_torque(u_cmd(i), x0[6 + i], w_.limits[static_cast<std::size_t>(i)]);
  const double hh = 0.5 * h;
  double k1[10], k2[10], k3[10], k4[10], xs[10];
  derivative(t, x0, u, k1);
  for (int i = 0; i < 10; ++i) xs[i] = x0[i] + hh * k1[i];
  derivative(t + hh, xs, u, k2);
  for (int i = 0; i < 10; ++i) xs[i] = x0[i] + hh * k2[i];
  derivative(t + hh, xs, u, k3);
  for (int i = 0; i < 10; ++i) xs[i] = x0[i] + h * k3[i];
  derivative(t + h, xs, u, k4);
  const double h6 = h / 6.0;
  double o[10];
  for (int i = 0; i < 10; ++i) o[i] = x0[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
  const double ss = o[0] * o[0] + o[1] * o[1] + o[2] * o[2];
  if (ss > 1.0)  // MRP shadow set: same attitude, |sigma| <= 1
    for (int i = 0; i < 3; ++i) o[i] = -o[i] / ss;
  PlantState r;
  for (int i = 0; i < 3; ++i) r.sigma_BN(i) = o[i], r.omega_BN_B(i) = o[3 + i];
  for (int i = 0; i < 4; ++i) r.wheel_speed(i) = o[6 + i];
  return r;
}

}  // namespace sc_rt
