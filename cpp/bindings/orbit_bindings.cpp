// Bindings of the orbit and environment evaluators (sc_rt/orbit.hpp) and the
// geomagnetic field (sc_rt/geomag.hpp) into
// sc_rt._core, C++ names and argument names. OrbitParams' keyword
// constructor validates (ValueError naming the field). From the Python
// dataclass use sc_rt.model.orbit.orbit_params_to_cpp.
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <utility>
#include <vector>

#include "sc_rt/geomag.hpp"
#include "sc_rt/orbit.hpp"
#include "sc_rt/plant.hpp"
#include "sc_rt/util.hpp"

namespace py = pybind11;
using namespace sc_rt;
using py::arg;

void bind_orbit(py::module_& m) {
  const OrbitParams O;
  py::class_<OrbitParams>(m, "OrbitParams",
                          "A Keplerian orbit (+J2 secular drift) and its epoch; disabled by default. "
                          "The keyword constructor validates and enables it.")
      .def(py::init<>())
      .def(py::init([](double a, double e, double i, double raan, double argp, double M0, double jd_epoch,
                       bool j2) {
             OrbitParams p;
             p.enabled = true;
             p.a = a, p.e = e, p.i = i, p.raan = raan, p.argp = argp, p.M0 = M0;
             p.jd_epoch = jd_epoch, p.j2 = j2;
             throw_if_errors("OrbitParams", validate(p));
             return p;
           }),
           arg("a") = O.a, arg("e") = O.e, arg("i") = O.i, arg("raan") = O.raan, arg("argp") = O.argp,
           arg("M0") = O.M0, arg("jd_epoch") = O.jd_epoch, arg("j2") = O.j2)
      .def_readwrite("enabled", &OrbitParams::enabled, "false: no orbit (the plant's w0 form of (5))")
      .def_readwrite("a", &OrbitParams::a, "[m] semi-major axis")
      .def_readwrite("e", &OrbitParams::e, "[-] eccentricity")
      .def_readwrite("i", &OrbitParams::i, "[rad] inclination")
      .def_readwrite("raan", &OrbitParams::raan, "[rad] right ascension of the ascending node at epoch")
      .def_readwrite("argp", &OrbitParams::argp, "[rad] argument of perigee at epoch")
      .def_readwrite("M0", &OrbitParams::M0, "[rad] mean anomaly at epoch")
      .def_readwrite("jd_epoch", &OrbitParams::jd_epoch, "[day] UTC Julian date at t = 0")
      .def_readwrite("j2", &OrbitParams::j2, "J2 secular drift")
      .def_readwrite("mu", &OrbitParams::mu, "[m^3/s^2] gravitational parameter")
      .def_readwrite("R_eq", &OrbitParams::R_eq, "[m] equatorial radius")
      .def_readwrite("J2", &OrbitParams::J2, "[-] J2");
  m.def("validate", py::overload_cast<const OrbitParams&>(&validate), arg("p"),
        "Every problem with the orbit parameters (empty list: valid).");
  m.def("mean_anomaly_from_true", &mean_anomaly_from_true, arg("nu"), arg("e"),
        "Mean anomaly [rad] of the true anomaly nu [rad].");
  m.def(
      "orbit_rates",
      [](const OrbitParams& p) {
        const OrbitRates k = orbit_rates(p);
        return py::make_tuple(k.n, k.raan_dot, k.argp_dot, k.M_dot, k.b);
      },
      arg("p"), "(n, raan_dot, argp_dot, M_dot [rad/s], b [m]): mean motion, J2 rates, semi-minor axis.");
  m.def(
      "orbit_state",
      [](const OrbitParams& p, double t) {
        const OrbitState s = orbit_state(p, t);
        return std::make_pair(s.r_N, s.v_N);
      },
      arg("p"), arg("t"), "(r_N [m], v_N [m/s]) in ECI at t [s] after the epoch.");
  m.def("gmst", &gmst, arg("jd_day"), arg("t") = 0.0,
        "Greenwich mean sidereal time [rad] at jd_day + t/86400 (IAU-1982, Meeus (12.4)).");
  m.def("eci_to_ecef", &eci_to_ecef, arg("jd_day"), arg("t") = 0.0, "C_EN: ECI (mean of date) -> ECEF.");
  m.def("sun_direction_N", &sun_direction_N, arg("jd_day"), arg("t") = 0.0,
        "Unit vector Earth -> Sun in ECI (Astronomical Almanac, low precision).");
  m.def("sun_distance_au", &sun_distance_au, arg("jd_day"), arg("t") = 0.0, "Earth-Sun distance [AU].");
  m.def("in_eclipse", &in_eclipse, arg("r_N"), arg("s_N"), arg("R_eq") = kREarth,
        "In the cylindrical Earth shadow: r.s < 0 and |r - (r.s) s| < R_eq.");
  m.def("gravity_gradient_orbit", &gravity_gradient_orbit, arg("J"), arg("sigma_BN"), arg("r_N"),
        arg("mu") = kMuEarth, "Gravity-gradient torque [N m] 3 mu / r^5 (r_B x J r_B), r_B = C_BN r_N.");

  // --- the geomagnetic field (geomag.hpp)
  m.attr("GEOMAG_RADIUS") = kGeomagRadius;
  m.def("decimal_year", &decimal_year, arg("jd"), "Decimal year of a Julian date: 2000 + (jd - 2451544.5) / 365.25.");
  py::class_<GeomagCoeffs>(m, "GeomagCoeffs", "Gauss coefficients [nT] of one date, g[n][m], h[n][m].")
      .def_property_readonly("g", [](const GeomagCoeffs& c) { return c.g; }, "[nT] g[n][m] (14 x 14)")
      .def_property_readonly("h", [](const GeomagCoeffs& c) { return c.h; }, "[nT] h[n][m] (14 x 14)")
      .def_readonly("nmax", &GeomagCoeffs::nmax, "highest degree");
  m.def("igrf14_coefficients", &igrf14_coefficients, arg("year"), arg("nmax") = kGeomagMaxDegree,
        "IGRF-14 at a decimal year in [1900, 2030] to degree nmax (1: the tilted dipole).");
  m.attr("WMM_MAX_DEGREE") = kWmmMaxDegree;
  m.def("wmm2025_coefficients", &wmm2025_coefficients, arg("year"), arg("nmax") = kWmmMaxDegree,
        "WMM2025 at a decimal year in [2025, 2030] to degree nmax <= 12: g + (year - 2025) g-dot.");
  m.def("geomag_model_coefficients", &geomag_model_coefficients, arg("model"), arg("year"),
        "The coefficients of a field model by name (\"igrf\", \"dipole\", \"wmm2025\") at a decimal year.");
  py::class_<GeomagField>(m, "GeomagField", "The field of one set of Gauss coefficients [nT].")
      .def(py::init<const GeomagCoeffs&>(), arg("c"))
      .def_property_readonly("coefficients", &GeomagField::coefficients)
      .def(
          "spherical",
          [](const GeomagField& f, double r, double ct, double st, double cp, double sp) {
            const GeomagSpherical b = f.spherical(r, ct, st, cp, sp);
            return py::make_tuple(b.B_r, b.B_theta, b.B_phi);
          },
          arg("r"), arg("ct"), arg("st"), arg("cp"), arg("sp"),
          "(B_r, B_theta, B_phi) [nT] at radius r [m], cos/sin colatitude, cos/sin longitude.")
      .def("B_ecef", &GeomagField::B_ecef, arg("r_E"), "B in ECEF [nT] at an ECEF position [m].")
      .def("B_ned", &GeomagField::B_ned, arg("r_E"), "B in the local geocentric NED [nT].")
      .def("B_eci", &GeomagField::B_eci, arg("r_N"), arg("jd_day"), arg("t"),
           "B in ECI [nT] at an ECI position [m] at jd_day + t/86400.");
  m.def(
      "geomag_dipole",
      [](const GeomagCoeffs& c) {
        const GeomagDipole d = geomag_dipole(c);
        return std::make_pair(d.B0, d.m_E);
      },
      arg("c"), "(B0 [nT], unit dipole axis in ECEF) of the coefficients' degree 1.");

  m.def(
      "time_environment",
      [](const OrbitParams& o, int n, int reps) {
        // What one evaluation costs in C++ (bench/bench_env.py): n evaluations along the
        // orbit, t = 10 s apart, timed reps times each, with the GIL released. The plant
        // steps: the paper's plant with the orbit's gravity gradient and with the w0 form.
        if (n < 1 || reps < 1) throw std::invalid_argument("time_environment: need n >= 1 and reps >= 1");
        throw_if_errors("time_environment: orbit", validate(o));
        const OrbitRates k = orbit_rates(o);
        const GeomagField igrf(igrf14_coefficients(decimal_year(o.jd_epoch)));
        const GeomagField dipole(igrf14_coefficients(decimal_year(o.jd_epoch), 1));
        const GeomagField wmm(wmm2025_coefficients(decimal_year(o.jd_epoch)));
        PlantParams p_orbit, p_w0;
        p_orbit.orbit = o;
        p_orbit.orbit.enabled = true;
        const ActuatorParams a;
        const Vec4 u(0.1, -0.2, 0.3, 0.0);
        std::vector<std::vector<double>> secs(7);
        double sink = 0.0;
        {
          py::gil_scoped_release release;
          for (int r = 0; r < reps; ++r) {
            auto timed = [&](std::size_t slot, auto&& body) {
              const auto t0 = std::chrono::steady_clock::now();
              for (int i = 0; i < n; ++i) sink += body(10.0 * i);
              secs[slot].push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
            };
            timed(0, [&](double t) {
              double g[4];
              detail::orbit_gg_terms(o, k, t, g);
              return g[0];
            });
            timed(1, [&](double t) { return sun_direction_N(o.jd_epoch, t)(0); });
            timed(2, [&](double t) {
              double r[3];
              orbit_position(o, k, t, r);
              return igrf.B_eci(Vec3(r[0], r[1], r[2]), o.jd_epoch, t)(0);
            });
            timed(3, [&](double t) {
              double r[3];
              orbit_position(o, k, t, r);
              return dipole.B_eci(Vec3(r[0], r[1], r[2]), o.jd_epoch, t)(0);
            });
            PlantState x;
            x.omega_BN_B = Vec3(0.01, -0.02, 0.03);
            timed(4, [&](double t) {
              x = plant_rk4_step(p_orbit, a, t, x, 0.1, u);
              return x.omega_BN_B(0);
            });
            x = PlantState{};
            x.omega_BN_B = Vec3(0.01, -0.02, 0.03);
            timed(5, [&](double t) {
              x = plant_rk4_step(p_w0, a, t, x, 0.1, u);
              return x.omega_BN_B(0);
            });
            timed(6, [&](double t) {
              double r[3];
              orbit_position(o, k, t, r);
              return wmm.B_eci(Vec3(r[0], r[1], r[2]), o.jd_epoch, t)(0);
            });
          }
        }
        py::dict d;
        const char* names[] = {"orbit_gg",         "sun",           "igrf_eci",   "dipole_eci",
                               "plant_step_orbit", "plant_step_w0", "wmm2025_eci"};
        for (std::size_t i = 0; i < 7; ++i) d[names[i]] = secs[i];
        d["n"] = n;
        d["sink"] = sink;
        return d;
      },
      arg("orbit"), arg("n"), arg("reps"),
      "Seconds of n evaluations (reps times) of the orbit's gravity-gradient terms, the Sun, the IGRF-14, "
      "dipole and WMM2025 fields in ECI along the orbit (epoch in 2025-2030 for WMM2025), and a plant RK4 "
      "step with the orbit and with w0.");
}
