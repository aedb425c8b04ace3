// The orbit and its environment (docs/MODEL.md section 11): a Keplerian orbit
// with optional J2 secular drift, Earth rotation (GMST, IAU-1982), the Sun
// direction (the Astronomical Almanac's low-precision formulae) and a
// cylindrical Earth shadow; the gravity-gradient torque of the orbit's actual
// radius and nadir.
//
// Frames: N = ECI, here the mean equator and equinox of date (the frame GMST
// and the almanac's Sun are referred to; precession over a run is ignored);
// E = ECEF (N rotated by GMST about z); B = body.
//
// Pure functions of time, no I/O, no allocation, a bounded cost whatever t
// (the mean anomaly is reduced modulo 2 pi before a Kepler solve of at most
// kKeplerIterations Newton steps). The Python twin, sc_rt.model.orbit, repeats
// every scalar operation in the same order: the two give the same bits
// (tests/test_orbit.py), with IEEE double without contraction and glibc's
// sin/cos/atan2/fmod/sqrt, which Python's math module calls too.
#pragma once
#include <string>
#include <vector>

#include "sc_rt/types.hpp"

namespace sc_rt {

constexpr double kMuEarth = 3.986004418e14;  //!< [m^3/s^2] GM of the Earth (WGS-84 / EGM-96)
constexpr double kREarth = 6378137.0;        //!< [m] equatorial radius (WGS-84), J2's reference
constexpr double kJ2Earth = 1.08262668e-3;   //!< [-] J2 (EGM-96, unnormalised)
constexpr double kJdJ2000 = 2451545.0;       //!< [day] Julian date of J2000.0 (2000-01-01 12:00)
constexpr int kKeplerIterations = 30;         //!< Newton steps at most (e < 0.99)

struct OrbitParams {
  bool enabled = false;         //!< false: no orbit (the plant keeps the constant-rate form (5))
  double a = 6778137.0;         //!< [m] semi-major axis (default: 400 km circular)
  double e = 0.0;               //!< [-] eccentricity, 0 <= e < 0.99
  double i = 0.0;               //!< [rad] inclination
  double raan = 0.0;            //!< [rad] right ascension of the ascending node at epoch
  double argp = 0.0;            //!< [rad] argument of perigee at epoch
  double M0 = 0.0;              //!< [rad] mean anomaly at epoch
  double jd_epoch = 2461041.5;  //!< [day] UTC Julian date at t = 0 (default 2026-01-01 00:00)
  bool j2 = false;              //!< J2 secular drift of raan, argp and the mean anomaly
  double mu = kMuEarth;         //!< [m^3/s^2] gravitational parameter
  double R_eq = kREarth;        //!< [m] equatorial radius (J2 and the shadow)
  double J2 = kJ2Earth;         //!< [-] J2
};

// Every problem with the parameters, each naming the field and the value.
std::vector<std::string> validate(const OrbitParams& p);

// Mean anomaly [rad] of the true anomaly nu [rad] at eccentricity e.
double mean_anomaly_from_true(double nu, double e);

// The orbit's constants, derived once (no validation: check validate() first).
struct OrbitRates {
  double n;         //!< [rad/s] Keplerian mean motion sqrt(mu / a^3)
  double raan_dot;  //!< [rad/s] J2 node regression (0 without J2)
  double argp_dot;  //!< [rad/s] J2 apsidal rotation (0 without J2)
  double M_dot;     //!< [rad/s] mean-anomaly rate (n plus J2's secular term)
  double b;         //!< [m] semi-minor axis a sqrt(1 - e^2)
};
OrbitRates orbit_rates(const OrbitParams& p);

struct OrbitState {
  Vec3 r_N;  //!< [m] position in N (ECI)
  Vec3 v_N;  //!< [m/s] velocity in N (ECI), of the osculating Keplerian ellipse
};

// Position and velocity at t [s] after the epoch.
OrbitState orbit_state(const OrbitParams& p, double t);

// The position alone as plain doubles (the plant's kernel; orbit_state's r_N bits).
void orbit_position(const OrbitParams& p, const OrbitRates& k, double t, double r_N[3]);

// Greenwich mean sidereal time [rad] in [0, 2 pi) at UT1 Julian date
// jd_day + t / 86400 (IAU-1982 expression, Meeus (12.4); UTC taken as UT1).
double gmst(double jd_day, double t);

// C_EN: ECI (mean of date) -> ECEF, a rotation by gmst about z.
Mat3 eci_to_ecef(double jd_day, double t);

// Unit vector from the Earth to the Sun in N at jd_day + t / 86400
// (Astronomical Almanac, low precision: ~0.01 deg 1950-2050).
Vec3 sun_direction_N(double jd_day, double t);

// Earth-Sun distance [AU] at the same time (the same almanac formula).
double sun_distance_au(double jd_day, double t);

// true when r_N [m] is in the Earth's cylindrical shadow of radius R_eq [m]
// for the Sun direction s_N (unit): r.s < 0 and |r - (r.s) s| < R_eq.
bool in_eclipse(const Vec3& r_N, const Vec3& s_N, double R_eq = kREarth);

// Gravity-gradient torque [N m] in B of the inertia J [kg m^2] at the
// attitude sigma_BN for the position r_N [m]:
// u_g = 3 mu / |r|^5 (r_B x J r_B), r_B = C_BN(sigma) r_N (Schaub & Junkins
// (4.53) / Hughes). For a circular orbit with r_N along e3 of N it equals
// gravity_gradient(J, sigma_BN, w0) with w0^2 = mu / |r|^3.
Vec3 gravity_gradient_orbit(const Mat3& J, const Vec3& sigma_BN, const Vec3& r_N, double mu = kMuEarth);

namespace detail {
// g = (3 mu / |r|^3, r / |r|) of a position r [m].
void gg_terms_of(double mu, const double r[3], double g[4]);
// The plant's kernel: g = (3 mu / r^3, r_N / r) at t, four doubles, in the
// order of sc_rt.model.orbit.gg_terms.
void orbit_gg_terms(const OrbitParams& p, const OrbitRates& k, double t, double g[4]);
}  // namespace detail

}  // namespace sc_rt

namespace sc_rt::detail {
// r = C_BN(sigma) n, on scalars (sc_rt.model.orbit.rotate_to_B, the same operations):
// C_BN(sigma) n = n + [8 (s (s.n) - |s|^2 n) - 4 (1 - |s|^2) (s x n)] / (1 + |s|^2)^2 (Schaub & Junkins (3.153)).
inline void rotate_to_B(double s1, double s2, double s3, double n1, double n2, double n3, double r[3]) {
  const double ss = s1 * s1 + s2 * s2 + s3 * s3;
  const double q = 1.0 / ((1.0 + ss) * (1.0 + ss));
  const double m4 = 4.0 * (1.0 - ss);
  const double sn = s1 * n1 + s2 * n2 + s3 * n3;
  const double c1 = s2 * n3 - s3 * n2;
  const double c2 = s3 * n1 - s1 * n3;
  const double c3 = s1 * n2 - s2 * n1;
  r[0] = n1 + (8.0 * (s1 * sn - ss * n1) - m4 * c1) * q;
  r[1] = n2 + (8.0 * (s2 * sn - ss * n2) - m4 * c2) * q;
  r[2] = n3 + (8.0 * (s3 * sn - ss * n3) - m4 * c3) * q;
}

// u_g = g0 (r x J r), r = C_BN(sigma) n, of the kernel's g = (g0, n) [N m]
// (the plant's Rhs and gravity_gradient_orbit; sc_rt.model.orbit.gg_torque).
inline void gg_orbit_torque(const double J[3][3], double s1, double s2, double s3, const double g[4],
                            double out[3]) {
  double r[3];
  rotate_to_B(s1, s2, s3, g[1], g[2], g[3], r);
  const double r1 = r[0], r2 = r[1], r3 = r[2];
  const double j1 = J[0][0] * r1 + J[0][1] * r2 + J[0][2] * r3;
  const double j2 = J[1][0] * r1 + J[1][1] * r2 + J[1][2] * r3;
  const double j3 = J[2][0] * r1 + J[2][1] * r2 + J[2][2] * r3;
  out[0] = g[0] * (r2 * j3 - r3 * j2);
  out[1] = g[0] * (r3 * j1 - r1 * j3);
  out[2] = g[0] * (r1 * j2 - r2 * j1);
}
}  // namespace sc_rt::detail
