// The orbit and its environment (sc_rt/orbit.hpp): every expression in the
// order of its Python twin, python/sc_rt/model/orbit.py (bitwise equal).
#include "sc_rt/orbit.hpp"

#include <cmath>

#include "sc_rt/util.hpp"

namespace sc_rt {

namespace {
constexpr double kPi = 3.141592653589793;
constexpr double kTwoPi = 2.0 * kPi;
constexpr double kDeg = kPi / 180.0;  // [rad/deg]

// x modulo m in [0, m).
double wrap(double x, double m) {
  double y = std::fmod(x, m);
  if (y < 0.0) y = y + m;
  return y;
}

// Kepler's equation M = E - e sin E by Newton from E = M (e < 0.8) or pi,
// at most kKeplerIterations steps (Vallado, Algorithm 2); M in [0, 2 pi).
double eccentric_anomaly(double M, double e) {
  double E = e < 0.8 ? M : kPi;
  for (int it = 0; it < kKeplerIterations; ++it) {
    const double dE = (E - e * std::sin(E) - M) / (1.0 - e * std::cos(E));
    E = E - dE;
    if (std::fabs(dE) < 1e-15) break;
  }
  return E;
}

// Days since J2000.0 split as (whole part of the epoch, the rest): D = Dd + f.
void days(double jd_day, double t, double* Dd, double* f) {
  *Dd = jd_day - kJdJ2000;
  *f = t / 86400.0;
}

struct Elements {
  double E, raan, argp;  // [rad]
};

Elements elements_at(const OrbitParams& p, const OrbitRates& k, double t) {
  const double M = wrap(p.M0 + k.M_dot * t, kTwoPi);
  return {eccentric_anomaly(M, p.e), p.raan + k.raan_dot * t, p.argp + k.argp_dot * t};
}

// The perifocal axes P (to perigee) and Q in N: R3(-raan) R1(-i) R3(-argp) (Vallado (2-104)).
void pq_axes(double raan, double argp, double inc, double P[3], double Q[3]) {
  const double cO = std::cos(raan), sO = std::sin(raan);
  const double cw = std::cos(argp), sw = std::sin(argp);
  const double ci = std::cos(inc), si = std::sin(inc);
  P[0] = cO * cw - sO * sw * ci;
  P[1] = sO * cw + cO * sw * ci;
  P[2] = sw * si;
  Q[0] = -cO * sw - sO * cw * ci;
  Q[1] = -sO * sw + cO * cw * ci;
  Q[2] = cw * si;
}
}  // namespace

std::vector<std::string> validate(const OrbitParams& p) {
  std::vector<std::string> errs;
  if (!(std::isfinite(p.mu) && p.mu > 0.0)) errs.push_back("mu must be finite and > 0, got " + format_double(p.mu));
  if (!(std::isfinite(p.R_eq) && p.R_eq > 0.0))
    errs.push_back("R_eq must be finite and > 0, got " + format_double(p.R_eq));
  if (!(std::isfinite(p.J2) && p.J2 >= 0.0)) errs.push_back("J2 must be finite and >= 0, got " + format_double(p.J2));
  if (!(std::isfinite(p.e) && p.e >= 0.0 && p.e < 0.99))
    errs.push_back("e must be in [0, 0.99), got " + format_double(p.e));
  if (!(std::isfinite(p.a) && p.a > 0.0)) errs.push_back("a must be finite and > 0, got " + format_double(p.a));
  else if (std::isfinite(p.e) && std::isfinite(p.R_eq) && !(p.a * (1.0 - p.e) > p.R_eq))
    errs.push_back("the perigee radius a (1 - e) = " + format_double(p.a * (1.0 - p.e)) +
                   " m must be above R_eq = " + format_double(p.R_eq) + " m");
  const double ang[] = {p.i, p.raan, p.argp, p.M0};
  const char* names[] = {"i", "raan", "argp", "M0"};
  for (int j = 0; j < 4; ++j)
    if (!std::isfinite(ang[j])) errs.push_back(std::string(names[j]) + " must be finite, got " + format_double(ang[j]));
  if (!(std::isfinite(p.jd_epoch) && p.jd_epoch > 2415020.5 && p.jd_epoch < 2488069.5))
    errs.push_back("jd_epoch must be a Julian date in 1900-2100, got " + format_double(p.jd_epoch));
  return errs;
}

double mean_anomaly_from_true(double nu, double e) {
  // tan(E/2) = sqrt((1 - e)/(1 + e)) tan(nu/2); M = E - e sin E (Vallado (2-9), (2-4))
  const double E = 2.0 * std::atan2(std::sqrt(1.0 - e) * std::sin(0.5 * nu), std::sqrt(1.0 + e) * std::cos(0.5 * nu));
  return E - e * std::sin(E);
}

OrbitRates orbit_rates(const OrbitParams& p) {
  OrbitRates k{};
  k.n = std::sqrt(p.mu / (p.a * p.a * p.a));
  k.b = p.a * std::sqrt(1.0 - p.e * p.e);
  k.raan_dot = 0.0;
  k.argp_dot = 0.0;
  k.M_dot = k.n;
  if (p.j2) {
    // J2 secular rates (Vallado (9-41)): with p_s = a (1 - e^2), K = 3/2 n J2 (R/p_s)^2,
    // raan_dot = -K cos i, argp_dot = K (2 - 5/2 sin^2 i), M_dot = n + K sqrt(1 - e^2) (1 - 3/2 sin^2 i)
    const double ps = p.a * (1.0 - p.e * p.e);
    const double Rp = p.R_eq / ps;
    const double K = 1.5 * k.n * p.J2 * (Rp * Rp);
    const double si = std::sin(p.i);
    const double s2 = si * si;
    k.raan_dot = -K * std::cos(p.i);
    k.argp_dot = K * (2.0 - 2.5 * s2);
    k.M_dot = k.n + K * std::sqrt(1.0 - p.e * p.e) * (1.0 - 1.5 * s2);
  }
  return k;
}

void orbit_position(const OrbitParams& p, const OrbitRates& k, double t, double r_N[3]) {
  const Elements el = elements_at(p, k, t);
  double P[3], Q[3];
  pq_axes(el.raan, el.argp, p.i, P, Q);
  const double xp = p.a * (std::cos(el.E) - p.e);  // perifocal position (Vallado (2-103) with E)
  const double yp = k.b * std::sin(el.E);
  for (int j = 0; j < 3; ++j) r_N[j] = xp * P[j] + yp * Q[j];
}

OrbitState orbit_state(const OrbitParams& p, double t) {
  const OrbitRates k = orbit_rates(p);
  const Elements el = elements_at(p, k, t);
  double P[3], Q[3];
  pq_axes(el.raan, el.argp, p.i, P, Q);
  const double cE = std::cos(el.E), sE = std::sin(el.E);
  const double xp = p.a * (cE - p.e);
  const double yp = k.b * sE;
  // perifocal velocity: d/dt (a (cos E - e), b sin E) with E_dot = n a / r
  const double f = std::sqrt(p.mu * p.a) / (p.a * (1.0 - p.e * cE));
  const double vxp = -f * sE;
  const double vyp = f * std::sqrt(1.0 - p.e * p.e) * cE;
  OrbitState s;
  for (int j = 0; j < 3; ++j) {
    s.r_N(j) = xp * P[j] + yp * Q[j];
    s.v_N(j) = vxp * P[j] + vyp * Q[j];
  }
  return s;
}

double gmst(double jd_day, double t) {
  // Meeus (12.4): GMST [deg] = 280.46061837 + 360.98564736629 D + 0.000387933 T^2 - T^3 / 38710000,
  // D days since J2000.0 (UT1), T = D / 36525; 360 D taken modulo 360 on its whole days
  double Dd, f;
  days(jd_day, t, &Dd, &f);
  const double D = Dd + f;
  const double T = D / 36525.0;
  const double deg = 280.46061837 + 360.0 * (std::fmod(Dd, 1.0) + f) + 0.98564736629 * D +
                     0.000387933 * (T * T) - (T * T * T) / 38710000.0;
  return wrap(deg, 360.0) * kDeg;
}

Mat3 eci_to_ecef(double jd_day, double t) {
  const double th = gmst(jd_day, t);
  const double c = std::cos(th), s = std::sin(th);
  Mat3 C;
  C << c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0;
  return C;
}

namespace {
// The almanac's mean longitude L, mean anomaly g, ecliptic longitude lambda [rad], obliquity eps [rad].
void sun_angles(double jd_day, double t, double* g, double* lam, double* eps) {
  double Dd, f;
  days(jd_day, t, &Dd, &f);
  const double n = Dd + f;
  const double L = wrap(280.460 + 0.9856474 * n, 360.0);
  *g = wrap(357.528 + 0.9856003 * n, 360.0) * kDeg;
  *lam = (L + 1.915 * std::sin(*g) + 0.020 * std::sin(2.0 * *g)) * kDeg;
  *eps = (23.439 - 0.0000004 * n) * kDeg;
}
}  // namespace

Vec3 sun_direction_N(double jd_day, double t) {
  // Astronomical Almanac (section C, "low precision formulas for the Sun")
  double g, lam, eps;
  sun_angles(jd_day, t, &g, &lam, &eps);
  const double cl = std::cos(lam), sl = std::sin(lam);
  return Vec3(cl, std::cos(eps) * sl, std::sin(eps) * sl);
}

double sun_distance_au(double jd_day, double t) {
  double g, lam, eps;
  sun_angles(jd_day, t, &g, &lam, &eps);
  return 1.00014 - 0.01671 * std::cos(g) - 0.00014 * std::cos(2.0 * g);
}

bool in_eclipse(const Vec3& r_N, const Vec3& s_N, double R_eq) {
  // cylindrical shadow: behind the Earth (r.s < 0) and within R_eq of the Earth-Sun line
  const double rs = r_N(0) * s_N(0) + r_N(1) * s_N(1) + r_N(2) * s_N(2);
  if (!(rs < 0.0)) return false;
  const double rr = r_N(0) * r_N(0) + r_N(1) * r_N(1) + r_N(2) * r_N(2);
  return rr - rs * rs < R_eq * R_eq;
}

namespace detail {
void gg_terms_of(double mu, const double r[3], double g[4]) {
  const double rr = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
  const double rn = std::sqrt(rr);
  g[0] = 3.0 * mu / (rr * rn);  // 3 mu / r^3 = 3 w0^2 on a circular orbit
  g[1] = r[0] / rn;
  g[2] = r[1] / rn;
  g[3] = r[2] / rn;
}

void orbit_gg_terms(const OrbitParams& p, const OrbitRates& k, double t, double g[4]) {
  double r[3];
  orbit_position(p, k, t, r);
  gg_terms_of(p.mu, r, g);
}
}  // namespace detail

Vec3 gravity_gradient_orbit(const Mat3& J, const Vec3& sigma_BN, const Vec3& r_N, double mu) {
  // u_g = 3 mu / r^5 (r_B x J r_B) = 3 mu / r^3 (n_B x J n_B), n = r / |r|
  double Ja[3][3], r[3], g[4], out[3];
  for (int a = 0; a < 3; ++a) {
    r[a] = r_N(a);
    for (int b = 0; b < 3; ++b) Ja[a][b] = J(a, b);
  }
  detail::gg_terms_of(mu, r, g);
  detail::gg_orbit_torque(Ja, sigma_BN(0), sigma_BN(1), sigma_BN(2), g, out);
  return Vec3(out[0], out[1], out[2]);
}

}  // namespace sc_rt
