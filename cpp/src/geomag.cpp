// The geomagnetic field (sc_rt/geomag.hpp): every expression in the order of
// its Python twin, python/sc_rt/model/field.py (bitwise equal).
#include "sc_rt/geomag.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "sc_rt/orbit.hpp"
#include "sc_rt/util.hpp"

namespace sc_rt {

namespace {
#include "igrf14_table.inc"
#include "wmm2025_table.inc"
}  // namespace

double decimal_year(double jd) { return 2000.0 + (jd - 2451544.5) / 365.25; }

GeomagCoeffs igrf14_coefficients(double year, int nmax) {
  if (!(year >= kIgrf14Years[0] && year <= kIgrf14Years[kIgrf14Epochs - 1]))
    throw std::invalid_argument("igrf14_coefficients: year must be in [1900, 2030], got " + format_double(year));
  if (nmax < 1 || nmax > kGeomagMaxDegree)
    throw std::invalid_argument("igrf14_coefficients: nmax must be in [1, 13], got " + std::to_string(nmax));
  // linear in time between the 5-year epochs (IGRF's rule; after 2025.0 the SV)
  int k = static_cast<int>(std::floor((year - kIgrf14Years[0]) / 5.0));
  if (k > kIgrf14Epochs - 2) k = kIgrf14Epochs - 2;
  const double f = (year - kIgrf14Years[k]) / 5.0;
  GeomagCoeffs c;
  c.nmax = nmax;
  for (int row = 0; row < kIgrf14Rows; ++row) {
    const int n = kIgrf14N[row], m = kIgrf14M[row];
    if (n > nmax) continue;
    const double v0 = kIgrf14Coeffs[row][k], v1 = kIgrf14Coeffs[row][k + 1];
    const double v = v0 + f * (v1 - v0);
    if (m >= 0) c.g[n][m] = v;
    else c.h[n][-m] = v;
  }
  return c;
}

GeomagCoeffs wmm2025_coefficients(double year, int nmax) {
  if (!(year >= kWmm2025Epoch && year <= kWmm2025Last))
    throw std::invalid_argument("wmm2025_coefficients: year must be in [2025, 2030], got " + format_double(year));
  if (nmax < 1 || nmax > kWmmMaxDegree)
    throw std::invalid_argument("wmm2025_coefficients: nmax must be in [1, 12], got " + std::to_string(nmax));
  // the WMM2025 report's eq. (9): g(t) = g(t0) + (t - t0) g-dot, h likewise
  const double dt = year - kWmm2025Epoch;
  GeomagCoeffs c;
  c.nmax = nmax;
  for (int row = 0; row < kWmm2025Rows; ++row) {
    const int n = kWmm2025N[row], m = kWmm2025M[row];
    if (n > nmax) continue;
    const double* v = kWmm2025Coeffs[row];  // g, h [nT], g-dot, h-dot [nT/yr]
    c.g[n][m] = v[0] + dt * v[2];
    c.h[n][m] = v[1] + dt * v[3];
  }
  return c;
}

GeomagCoeffs geomag_model_coefficients(const std::string& model, double year) {
  if (model == "igrf") return igrf14_coefficients(year, kGeomagMaxDegree);
  if (model == "dipole") return igrf14_coefficients(year, 1);
  if (model == "wmm2025") return wmm2025_coefficients(year, kWmmMaxDegree);
  throw std::invalid_argument("geomag_model_coefficients: model must be \"igrf\", \"dipole\" or \"wmm2025\", got \"" +
                              model + "\"");
}

GeomagField::GeomagField(const GeomagCoeffs& c) : c_(c) {
  if (c.nmax < 1 || c.nmax > kGeomagMaxDegree)
    throw std::invalid_argument("GeomagField: nmax must be in [1, 13], got " + std::to_string(c.nmax));
  for (int n = 0; n <= kGeomagMaxDegree; ++n) {
    d_[n] = n <= 1 ? 1.0 : std::sqrt((2.0 * n - 1.0) / (2.0 * n));
    for (int m = 0; m <= kGeomagMaxDegree; ++m) {
      a_[n][m] = 0.0;
      b_[n][m] = 0.0;
      if (m < n) {
        const double q = std::sqrt(static_cast<double>(n * n - m * m));
        a_[n][m] = (2.0 * n - 1.0) / q;
        b_[n][m] = std::sqrt(static_cast<double>((n - 1) * (n - 1) - m * m)) / q;
      }
    }
  }
}

GeomagSpherical GeomagField::spherical(double r, double ct, double st, double cp, double sp) const {
  const int N = c_.nmax;
  // Schmidt semi-normalised P_n^m(cos theta) and dP/dtheta (Langel (1987) recursions):
  // P_n^n = d_n sin P_{n-1}^{n-1}; P_n^m = a_nm cos P_{n-1}^m - b_nm P_{n-2}^m
  double P[kGeomagMaxDegree + 1][kGeomagMaxDegree + 1];
  double dP[kGeomagMaxDegree + 1][kGeomagMaxDegree + 1];
  double cm[kGeomagMaxDegree + 1], sm[kGeomagMaxDegree + 1];
  P[0][0] = 1.0;
  dP[0][0] = 0.0;
  cm[0] = 1.0;
  sm[0] = 0.0;
  for (int m = 1; m <= N; ++m) {  // cos m phi, sin m phi by the angle-sum recursion
    cm[m] = cm[m - 1] * cp - sm[m - 1] * sp;
    sm[m] = sm[m - 1] * cp + cm[m - 1] * sp;
  }
  for (int n = 1; n <= N; ++n) {
    P[n][n] = d_[n] * (st * P[n - 1][n - 1]);
    dP[n][n] = d_[n] * (st * dP[n - 1][n - 1] + ct * P[n - 1][n - 1]);
    for (int m = 0; m < n; ++m) {
      const double p2 = n >= m + 2 ? P[n - 2][m] : 0.0;
      const double dp2 = n >= m + 2 ? dP[n - 2][m] : 0.0;
      P[n][m] = a_[n][m] * (ct * P[n - 1][m]) - b_[n][m] * p2;
      dP[n][m] = a_[n][m] * (ct * dP[n - 1][m] - st * P[n - 1][m]) - b_[n][m] * dp2;
    }
  }
  // B = -grad V (Alken et al. 2021 eq. (1)): per degree the sum over orders, then (a/r)^(n+2)
  const double ar = kGeomagRadius / r;
  double rn = ar * ar;
  double Br = 0.0, Bt = 0.0, Bp = 0.0;
  for (int n = 1; n <= N; ++n) {
    rn = rn * ar;  // (a/r)^(n+2)
    double sr = 0.0, st_ = 0.0, sp_ = 0.0;
    for (int m = 0; m <= n; ++m) {
      const double gh = c_.g[n][m] * cm[m] + c_.h[n][m] * sm[m];
      sr = sr + gh * P[n][m];
      st_ = st_ + gh * dP[n][m];
      sp_ = sp_ + m * (c_.g[n][m] * sm[m] - c_.h[n][m] * cm[m]) * P[n][m];
    }
    Br = Br + rn * ((n + 1) * sr);
    Bt = Bt - rn * st_;
    Bp = Bp + rn * sp_;
  }
  return {Br, Bt, Bp / st};
}

namespace {
// r, cos/sin colatitude, cos/sin longitude of an ECEF position (1 mm off the polar axis at least).
void geocentric(const Vec3& r_E, double* r, double* ct, double* st, double* cp, double* sp) {
  const double x = r_E(0), y = r_E(1), z = r_E(2);
  double rho = std::sqrt(x * x + y * y);
  if (rho < 1e-3) {
    rho = 1e-3;
    *cp = 1.0;
    *sp = 0.0;
  } else {
    *cp = x / rho;
    *sp = y / rho;
  }
  *r = std::sqrt(rho * rho + z * z);
  *ct = z / *r;
  *st = rho / *r;
}
}  // namespace

Vec3 GeomagField::B_ecef(const Vec3& r_E) const {
  double r, ct, st, cp, sp;
  geocentric(r_E, &r, &ct, &st, &cp, &sp);
  const GeomagSpherical b = spherical(r, ct, st, cp, sp);
  // B_E = B_r r_hat + B_theta theta_hat + B_phi phi_hat
  return Vec3(b.B_r * (st * cp) + b.B_theta * (ct * cp) - b.B_phi * sp,
              b.B_r * (st * sp) + b.B_theta * (ct * sp) + b.B_phi * cp,
              b.B_r * ct - b.B_theta * st);
}

Vec3 GeomagField::B_ned(const Vec3& r_E) const {
  double r, ct, st, cp, sp;
  geocentric(r_E, &r, &ct, &st, &cp, &sp);
  const GeomagSpherical b = spherical(r, ct, st, cp, sp);
  return Vec3(-b.B_theta, b.B_phi, -b.B_r);
}

Vec3 GeomagField::B_eci(const Vec3& r_N, double jd_day, double t) const {
  const double th = gmst(jd_day, t);
  const double c = std::cos(th), s = std::sin(th);
  const Vec3 r_E(c * r_N(0) + s * r_N(1), c * r_N(1) - s * r_N(0), r_N(2));  // C_EN r_N
  const Vec3 B = B_ecef(r_E);
  return Vec3(c * B(0) - s * B(1), s * B(0) + c * B(1), B(2));  // C_EN' B_E
}

GeomagDipole geomag_dipole(const GeomagCoeffs& c) {
  const double g10 = c.g[1][0], g11 = c.g[1][1], h11 = c.h[1][1];
  const double B0 = std::sqrt(g10 * g10 + g11 * g11 + h11 * h11);
  return {B0, Vec3(g11 / B0, h11 / B0, g10 / B0)};
}

}  // namespace sc_rt
