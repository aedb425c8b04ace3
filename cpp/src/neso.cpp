#include "sc_rt/neso.hpp"

#include <cmath>

#include "sc_rt/util.hpp"

namespace sc_rt {

std::vector<std::string> validate(const NesoParams& p) {
  std::vector<std::string> errs;
  const char* names[4] = {"k1", "k2", "k3", "k4"};
  const Vec3* ks[4] = {&p.k1, &p.k2, &p.k3, &p.k4};
  for (int i = 0; i < 4; ++i)
    if (!ks[i]->allFinite() || ks[i]->minCoeff() <= 0.0)
      errs.push_back(std::string("NESO ") + names[i] + " must be finite and > 0, got " +
                     format_matrix(*ks[i]));
  if (!(p.alpha >= 0.5 && p.alpha <= 1.0))
    errs.push_back("NESO alpha must be in [0.5, 1], got " + format_double(p.alpha));
  if (p.substeps < 1 || p.substeps > 10000)
    errs.push_back("NESO substeps must be in [1, 10000], got " + std::to_string(p.substeps));
  return errs;
}

Vec3 neso_condition_26(const NesoParams& p) {
  Vec3 margin;
  for (int j = 0; j < 3; ++j) {
    const double k1 = p.k1(j), k2 = p.k2(j), k3 = p.k3(j), k4 = p.k4(j), a = p.alpha;
    const double common = (a + 1.0) * (a + 1.0) * k1 * k1 * k2 * k2;
    const double rhs_div = k2 * k2 * k3 / a + common;
    const double rhs_mul = k2 * k2 * k3 * a + common;
    margin(j) = k3 * k4 - std::max(rhs_div, rhs_mul);
  }
  return margin;
}

Vec3 sig_pow(const Vec3& v, double a) {
  Vec3 r;
  for (int i = 0; i < 3; ++i) {
    const double x = v(i);
    r(i) = x > 0.0 ? std::pow(x, a) : (x < 0.0 ? -std::pow(-x, a) : 0.0);
  }
  return r;
}

Neso::Neso(const NesoParams& p) : p_(p) { throw_if_errors("NesoParams", validate(p)); }

void Neso::reset(const Vec3& z1, const Vec3& z2) {
  z1_ = z1;
  z2_ = z2;
}

namespace {
struct Deriv {
  Vec3 d1, d2;
};
// Right-hand side of (22). One log and one exp per axis:
// |e|^alpha = exp(alpha ln|e|) and |e|^(2 alpha - 1) = (|e|^alpha)^2 / |e|.
inline Deriv neso_rhs(const NesoParams& p, const Vec3& z1, const Vec3& z2, const Vec3& A,
                      const Vec3& x2, const Vec3& Bu) {
  const Vec3 e = z1 - x2;
  Vec3 s1, s2;
  for (int i = 0; i < 3; ++i) {
    const double x = e(i);
    if (x == 0.0) {
      s1(i) = 0.0;
      s2(i) = 0.0;
      continue;
    }
    const double ax = std::abs(x);
    const double pa = std::exp(p.alpha * std::log(ax));
    const double sg = x > 0.0 ? 1.0 : -1.0;
    s1(i) = sg * pa;
    s2(i) = sg * (pa * pa / ax);
  }
  Deriv d;
  d.d1 = A + Bu + z2 - p.k1.cwiseProduct(s1) - p.k2.cwiseProduct(e);
  d.d2 = -p.k3.cwiseProduct(s2) - p.k4.cwiseProduct(e);
  return d;
}
}  // namespace

void Neso::update(double h, const Vec3& A0, const Vec3& A1, const Vec3& x20, const Vec3& x21,
                  const Vec3& Bu) {
  if (!(h > 0.0)) return;
  const int n = p_.substeps;
  const double hs = h / n;
  const Vec3 dA = A1 - A0, dx = x21 - x20;
  for (int k = 0; k < n; ++k) {
    const double f0 = static_cast<double>(k) / n;
    const double fm = (k + 0.5) / n;
    const double f1 = static_cast<double>(k + 1) / n;
    const Vec3 Aa = A0 + f0 * dA, Am = A0 + fm * dA, Ab = A0 + f1 * dA;
    const Vec3 xa = x20 + f0 * dx, xm = x20 + fm * dx, xb = x20 + f1 * dx;
    const Deriv k1 = neso_rhs(p_, z1_, z2_, Aa, xa, Bu);
    const Deriv k2 = neso_rhs(p_, z1_ + 0.5 * hs * k1.d1, z2_ + 0.5 * hs * k1.d2, Am, xm, Bu);
    const Deriv k3 = neso_rhs(p_, z1_ + 0.5 * hs * k2.d1, z2_ + 0.5 * hs * k2.d2, Am, xm, Bu);
    const Deriv k4 = neso_rhs(p_, z1_ + hs * k3.d1, z2_ + hs * k3.d2, Ab, xb, Bu);
    z1_ += (hs / 6.0) * (k1.d1 + 2.0 * k2.d1 + 2.0 * k3.d1 + k4.d1);
    z2_ += (hs / 6.0) * (k1.d2 + 2.0 * k2.d2 + 2.0 * k3.d2 + k4.d2);
  }
}

}  // namespace sc_rt
