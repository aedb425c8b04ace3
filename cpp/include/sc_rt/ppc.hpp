// Prescribed-performance transform (29)-(35), per axis i:
//   chi_i(t)  = (chi0_i - chiinf_i) exp(-gamma_i t) + chiinf_i          (29)
//   bound     : -dmin_i chi_i(t) < x1_i(t) < dmax_i chi_i(t)
//   lambda_i  = x1_i / chi_i
//   eps_i     = 1/2 ln((dmin_i + lambda_i) / (dmax_i - lambda_i))      (31)
//   e1_i      = eps_i - 1/2 ln(dmin_i / dmax_i)                        (36)
//   r_i       = 1/(2 chi_i) [1/(lambda_i + dmin_i) - 1/(lambda_i - dmax_i)]
//   e1_dot    = r (G(x1) x2 - Lambda chi_dot)                          (35)
// t is the time since the controller's engagement (its reset).
// Outside the bound lambda is clamped to a point just inside
// (-dmin, dmax) (a relative margin of clamp_margin of the interval) and the
// axis's violation flag is raised: the result is always finite.
#pragma once
#include <string>
#include <vector>

#include "sc_rt/law.hpp"
#include "sc_rt/types.hpp"

namespace sc_rt {

struct PpcParams {
  Vec3 chi0 = Vec3(0.11, 0.14, 0.2);         //!< [-] chi(0)
  Vec3 chiinf = Vec3(4e-6, 2e-6, 1.4e-6);    //!< [-] chi(infinity)
  Vec3 gamma = Vec3(0.12, 0.12, 0.08);       //!< [1/s] decay rate
  Vec3 dmin = Vec3(0.7, 1.0, 1.0);           //!< [-] lower bound factor
  Vec3 dmax = Vec3(1.0, 0.7, 0.3);           //!< [-] upper bound factor
  double clamp_margin = 1e-6;                //!< [-] relative margin of the clamp
};

std::vector<std::string> validate(const PpcParams& p);

// PpcResult (the transform at one time) is part of the law interface: sc_rt/law.hpp.

Vec3 ppc_chi(const PpcParams& p, double t);
Vec3 ppc_chi_dot(const PpcParams& p, double t);
// The transform of x1 at time t (never NaN/inf for finite x1 and t >= 0).
PpcResult ppc_transform(const PpcParams& p, const Vec3& x1, double t);
// The inverse: x1 from e1 at time t (for tests and analysis).
Vec3 ppc_inverse(const PpcParams& p, const Vec3& e1, double t);

}  // namespace sc_rt
