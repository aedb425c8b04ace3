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

Vec3 mrp_subtract(const Vec3& s, const Vec3& sd) {
  // (8): sigma_e = [sd (s's - 1) + s (1 - sd'sd) - 2 sd^ s]
  //               / [1 + (s's)(sd'sd) + 2 sd's]
  const double ss = s.squaredNorm();
  const double sdsd = sd.squaredNorm();
  const Vec3 num = sd * (ss - 1.0) + s * (1.0 - sdsd) - 2.0 * sd.cross(s);
  double den = 1.0 + ss * sdsd + 2.0 * sd.dot(s);
  if (den * den < 1e-12 * num.squaredNorm()) {
    // Near the singular composition (relative rotation near 360 deg in this
    // representation): compose with the shadow set of sd instead, which
    // describes the same attitude and keeps the denominator away from 0.
    const Vec3 sd2 = mrp_shadow(sd);
    const double sd2sd2 = sd2.squaredNorm();
    const Vec3 num2 = sd2 * (ss - 1.0) + s * (1.0 - sd2sd2) - 2.0 * sd2.cross(s);
    den = 1.0 + ss * sd2sd2 + 2.0 * sd2.dot(s);
    return mrp_short(num2 / den);
  }
  return mrp_short(num / den);
}

}  // namespace sc_rt
