#include "sc_rt/mrp.hpp"

namespace sc_rt {

Mat3 skew(const Vec3& x) {
  Mat3 m;
  m << 0.0, -x.z(), x.y(),
       x.z(), 0.0, -x.x(),
       -x.y(), x.x(), 0.0;
  return m;
}

Mat3 mrp_G(const Vec3& s) {
  // (2)
  const double ss = s.squaredNorm();
  return 0.25 * ((1.0 - ss) * Mat3::Identity() + 2.0 * skew(s) + 2.0 * s * s.transpose());
}

Mat3 mrp_G_inverse(const Vec3& s) {
  const double k = 1.0 + s.squaredNorm();
  return (16.0 / (k * k)) * mrp_G(s).transpose();
}

Mat3 mrp_to_dcm(const Vec3& s) {
  // (10)
  const double ss = s.squaredNorm();
  const Mat3 S = skew(s);
  const double d = 1.0 + ss;
  return Mat3::Identity() + (8.0 * S * S - 4.0 * (1.0 - ss) * S) / (d * d);
}

Vec3 mrp_shadow(const Vec3& s) { return -s / s.squaredNorm(); }

Vec3 mrp_short(const Vec3& s) { return s.squaredNorm() > 1.0 ? mrp_shadow(s) : s; }

namespace {
// (8) as printed; returns the denominator through den.
Vec3 compose8(const Vec3& s, const Vec3& sd, double& den) {
  // sigma_e = [sd (s's - 1) + s (1 - sd'sd) - 2 sd^ s] / [1 + (s's)(sd'sd) + 2 sd's]
  const double ss = s.squaredNorm();
  const double sdsd = sd.squaredNorm();
  den = 1.0 + ss * sdsd + 2.0 * sd.dot(s);
  return sd * (ss - 1.0) + s * (1.0 - sdsd) - 2.0 * sd.cross(s);
}
}  // namespace

Vec3 mrp_subtract(const Vec3& s, const Vec3& sd) {
  double den;
  const Vec3 num = compose8(s, sd, den);
  // den = 1 + |s|^2 |sd|^2 + 2 sd's >= (1 - |s||sd|)^2 vanishes when the
  // relative rotation is 360 deg in this pair of sets. Composing with the
  // shadow set of s (the same attitude) then has den = |s - sd|^2 / |s|^2,
  // and the two cannot be small together: use the larger.
  if (den < 0.25 && s.squaredNorm() > 0.0) {
    double den2;
    const Vec3 num2 = compose8(mrp_shadow(s), sd, den2);
    if (den2 > den) return mrp_short(num2 / den2);
  }
  return mrp_short(num / den);
}

}  // namespace sc_rt
