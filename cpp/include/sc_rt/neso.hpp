// Nonlinear extended state observer, NESO (22):
//   ev1    = z1 - x2
//   z1_dot = A + B sat(uc) + z2 - k1 sig^alpha(ev1) - k2 ev1
//   z2_dot = -k3 sig^(2 alpha - 1)(ev1) - k4 ev1
// z1 estimates x2 = omega_BD_B, z2 the lumped disturbance delta_2.
//
// Discretisation (sampled data). Over one control period [t_{k-1}, t_k] the
// wheel command is held (ZOH), so B sat(uc_{k-1}) is exact; the measured x2
// and the model term A are known at both ends and are interpolated linearly
// in between. The observer is integrated with `substeps` classical RK4 steps.
// The non-Lipschitz sig^(2 alpha - 1) term is continuous and bounded near 0
// (|.| <= |ev1|^(2 alpha - 1)), so every RK4 stage is finite; near zero error
// the discrete observer settles into a bounded limit cycle whose size scales
// with the step (tested in tests/test_neso.py, reported in docs/CORE.md).
#pragma once
#include <string>
#include <vector>

#include "sc_rt/types.hpp"

namespace sc_rt {

struct NesoParams {
  Vec3 k1 = Vec3::Constant(0.2);   //!< kappa1 diagonal
  Vec3 k2 = Vec3::Constant(0.03);  //!< kappa2 diagonal
  Vec3 k3 = Vec3::Constant(0.08);  //!< kappa3 diagonal
  Vec3 k4 = Vec3::Constant(0.06);  //!< kappa4 diagonal
  double alpha = 0.7;              //!< [-] in [0.5, 1]
  int substeps = 1;                //!< RK4 steps per control period (>= 1)
  bool init_from_measurement = false;  //!< z1(t0) = x2(t0) instead of 0 (paper: 0)
};

// Every problem with the parameters; the convergence condition (26) is
// checked separately (neso_condition_26) because the paper states it as
// sufficient, not necessary.
std::vector<std::string> validate(const NesoParams& p);

// Convergence condition (26) per axis, in both readings of the extraction:
//   k3 k4 > k2^2 k3 / alpha + (alpha + 1)^2 k1^2 k2^2   (divides)
//   k3 k4 > k2^2 k3 alpha   + (alpha + 1)^2 k1^2 k2^2   (multiplies)
// Returns, per axis, the margin lhs - rhs of the stricter reading (> 0 holds).
Vec3 neso_condition_26(const NesoParams& p);

// sig^a(v), element-wise |v_i|^a sign(v_i) (0 at 0 for every a >= 0).
Vec3 sig_pow(const Vec3& v, double a);

class Neso {
 public:
  explicit Neso(const NesoParams& p);
  void reset(const Vec3& z1, const Vec3& z2);
  // Propagate over [t_{k-1}, t_k] of length h: A and x2 move linearly from
  // (A0, x20) to (A1, x21); Bu = B sat(uc_{k-1}) is held.
  void update(double h, const Vec3& A0, const Vec3& A1, const Vec3& x20, const Vec3& x21,
              const Vec3& Bu);
  const Vec3& z1() const { return z1_; }
  const Vec3& z2() const { return z2_; }
  const NesoParams& params() const { return p_; }

 private:
  NesoParams p_;
  Vec3 z1_ = Vec3::Zero();
  Vec3 z2_ = Vec3::Zero();
};

}  // namespace sc_rt
