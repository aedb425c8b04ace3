#include "sc_rt/ppc.hpp"

#include <cmath>

#include "sc_rt/util.hpp"

namespace sc_rt {

std::vector<std::string> validate(const PpcParams& p) {
  std::vector<std::string> errs;
  for (int i = 0; i < 3; ++i) {
    const std::string ax = " of axis " + std::to_string(i + 1);
    if (!(std::isfinite(p.chiinf(i)) && p.chiinf(i) > 0.0))
      errs.push_back("PPC chiinf" + ax + " must be > 0, got " + format_double(p.chiinf(i)));
    if (!(std::isfinite(p.chi0(i)) && p.chi0(i) >= p.chiinf(i)))
      errs.push_back("PPC chi0" + ax + " must be >= chiinf (" + format_double(p.chiinf(i)) +
                     "), got " + format_double(p.chi0(i)));
    if (!(std::isfinite(p.gamma(i)) && p.gamma(i) >= 0.0))
      errs.push_back("PPC gamma" + ax + " must be >= 0, got " + format_double(p.gamma(i)));
    if (!(std::isfinite(p.dmin(i)) && p.dmin(i) > 0.0))
      errs.push_back("PPC dmin" + ax + " must be > 0, got " + format_double(p.dmin(i)));
    if (!(std::isfinite(p.dmax(i)) && p.dmax(i) > 0.0))
      errs.push_back("PPC dmax" + ax + " must be > 0, got " + format_double(p.dmax(i)));
  }
  if (!(p.clamp_margin > 0.0 && p.clamp_margin < 0.5))
    errs.push_back("PPC clamp_margin must be in (0, 0.5), got " + format_double(p.clamp_margin));
  return errs;
}

Vec3 ppc_chi(const PpcParams& p, double t) {
  Vec3 c;
  for (int i = 0; i < 3; ++i)
    c(i) = (p.chi0(i) - p.chiinf(i)) * std::exp(-p.gamma(i) * t) + p.chiinf(i);  // (29)
  return c;
}

Vec3 ppc_chi_dot(const PpcParams& p, double t) {
  Vec3 c;
  for (int i = 0; i < 3; ++i)
    c(i) = -p.gamma(i) * (p.chi0(i) - p.chiinf(i)) * std::exp(-p.gamma(i) * t);
  return c;
}

PpcResult ppc_transform(const PpcParams& p, const Vec3& x1, double t) {
  PpcResult r;
  r.chi = ppc_chi(p, t);
  r.chi_dot = ppc_chi_dot(p, t);
  for (int i = 0; i < 3; ++i) {
    const double dmin = p.dmin(i), dmax = p.dmax(i);
    const double m = p.clamp_margin * (dmin + dmax);
    double lam = x1(i) / r.chi(i);
    if (!(lam > -dmin && lam < dmax)) {  // also catches NaN
      r.violated |= 1 << i;
      lam = (lam >= dmax) ? dmax - m : -dmin + m;
    } else if (lam > dmax - m) {
      lam = dmax - m;  // inside, but too close to the pole to be represented
    } else if (lam < -dmin + m) {
      lam = -dmin + m;
    }
    r.lambda(i) = lam;
    r.eps(i) = 0.5 * std::log((dmin + lam) / (dmax - lam));        // (31)
    r.e1(i) = r.eps(i) - 0.5 * std::log(dmin / dmax);              // (36)
    r.r(i) = 0.5 / r.chi(i) * (1.0 / (lam + dmin) - 1.0 / (lam - dmax));  // (35)
  }
  return r;
}

Vec3 ppc_inverse(const PpcParams& p, const Vec3& e1, double t) {
  const Vec3 chi = ppc_chi(p, t);
  Vec3 x1;
  for (int i = 0; i < 3; ++i) {
    // eps = e1 + 1/2 ln(dmin/dmax); (dmin + lam)/(dmax - lam) = exp(2 eps)
    const double q = std::exp(2.0 * e1(i)) * p.dmin(i) / p.dmax(i);
    const double lam = (q * p.dmax(i) - p.dmin(i)) / (1.0 + q);
    x1(i) = lam * chi(i);
  }
  return x1;
}

}  // namespace sc_rt
