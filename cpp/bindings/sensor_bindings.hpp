// Bindings of the sensors and the estimator (sc_rt/sensors.hpp, mekf.hpp)
// into sc_rt._core, C++ names. Included once by plant_bindings.cpp
// (bind_plant calls bind_sensors): the sensors are the plant side's.
#pragma once
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <vector>

#include "closed_loop_dict.hpp"
#include "sc_rt/closed_loop.hpp"
#include "sc_rt/mekf.hpp"
#include "sc_rt/sensors.hpp"

namespace sc_rt_bind {
namespace py = pybind11;
using namespace sc_rt;
using py::arg;
using Vec10 = Eigen::Matrix<double, 10, 1>;

inline PlantState state_of(const Vec10& v) {
  return PlantState{v.segment<3>(0), v.segment<3>(3), v.segment<4>(6)};
}

// The navigation telemetry of a row (NAV_FIELDS): the table's kNav fields in
// table order (fields.hpp nav_offset), then nav_flags; written by the core's
// producer (closed_loop.hpp for_each_nav_field).
constexpr int kNavSize = nav_size();

inline Eigen::Matrix<double, kNavSize, 1> pack(const NavTelemetry& t) {
  Eigen::Matrix<double, kNavSize, 1> v;
  for_each_nav_field(t, [&v](FieldId f, const auto& x) {
    if constexpr (std::is_arithmetic_v<std::decay_t<decltype(x)>>)
      v(nav_offset(f)) = x;
    else
      v.segment(nav_offset(f), x.size()) = x;
  });
  v(kNavSize - 1) = static_cast<double>(t.flags);
  return v;
}

// Mekf (N = 6) and MekfCal (N = 15), and their states.
template <int N>
void bind_mekf(py::module_& m, const char* name, const char* state_name, const char* doc) {
  using F = MekfT<N>;
  using S = MekfStateT<N>;
  auto st = py::class_<S>(m, state_name)
                .def_readonly("t", &S::t)
                .def_readonly("sigma", &S::sigma)
                .def_readonly("bias", &S::bias)
                .def_readonly("P", &S::P);
  if constexpr (N == 15) st.def_readonly("cal", &S::cal, "[s1 s2 s3, ku1 ku2 ku3, kl1 kl2 kl3]");
  py::class_<F>(m, name, doc)
      .def(py::init<const MekfParams&>(), arg("p"))
      .def("reset", &F::reset, arg("t"), arg("sigma"), arg("bias"))
      .def("gyro", &F::gyro, arg("t"), arg("omega_m"), arg("output") = kGyroRate,
           "A gyro sample at t: output GYRO_RATE (the rate at t) or GYRO_MEAN_RATE (the mean rate over\n"
           "the interval since the previous sample, an integrating gyro's).")
      .def("star", &F::star, arg("t_exposure"), arg("sigma_m"))
      .def("predict", &F::predict, arg("t"))
      .def("rate_estimate", &F::rate_estimate, arg("s"), "(I + S)^-1 (held sample - b) of the state s")
      .def_property_readonly("state", &F::state)
      .def_property_readonly("innovation", &F::innovation)
      .def_property_readonly("nis", &F::nis)
      .def_property_readonly("updates", &F::updates)
      .def_property_readonly("dropped", &F::dropped);
}

inline void bind_sensors(py::module_& m) {
  py::class_<GyroParams>(m, "GyroParams", "Rate gyro (SI units; sensors.hpp).")
      .def(py::init<>())
      .def_readwrite("enabled", &GyroParams::enabled)
      .def_readwrite("period_ticks", &GyroParams::period_ticks, "plant steps per sample")
      .def_readwrite("arw", &GyroParams::arw, "[rad/sqrt(s)]")
      .def_readwrite("bias_sigma", &GyroParams::bias_sigma, "[rad/s]")
      .def_readwrite("bias_tau", &GyroParams::bias_tau, "[s]")
      .def_readwrite("rrw", &GyroParams::rrw, "[rad/s^(3/2)]")
      .def_readwrite("bias0", &GyroParams::bias0, "[rad/s]")
      .def_readwrite("scale_factor", &GyroParams::scale_factor, "[-]")
      .def_readwrite("misalignment", &GyroParams::misalignment, "[rad]")
      .def_readwrite("quantization", &GyroParams::quantization, "[rad]")
      .def_readwrite("saturation", &GyroParams::saturation, "[rad/s]")
      .def_readwrite("output", &GyroParams::output,
                     "GYRO_RATE (the rate at the sample instant) or GYRO_MEAN_RATE (an integrating gyro)");
  m.attr("GYRO_RATE") = kGyroRate;
  m.attr("GYRO_MEAN_RATE") = kGyroMeanRate;
  py::class_<StarTrackerParams>(m, "StarTrackerParams", "Star tracker (SI units; sensors.hpp).")
      .def(py::init<>())
      .def_readwrite("enabled", &StarTrackerParams::enabled)
      .def_readwrite("period_ticks", &StarTrackerParams::period_ticks)
      .def_readwrite("sigma_cross", &StarTrackerParams::sigma_cross, "[rad]")
      .def_readwrite("sigma_boresight", &StarTrackerParams::sigma_boresight, "[rad]")
      .def_readwrite("boresight", &StarTrackerParams::boresight)
      .def_readwrite("latency_ticks", &StarTrackerParams::latency_ticks)
      .def_readwrite("loss_probability", &StarTrackerParams::loss_probability)
      .def_readwrite("blackouts", &StarTrackerParams::blackouts, "[s] [(start, end)]");
  py::class_<TachometerParams>(m, "TachometerParams", "Wheel tachometer (sensors.hpp).")
      .def(py::init<>())
      .def_readwrite("enabled", &TachometerParams::enabled)
      .def_readwrite("period_ticks", &TachometerParams::period_ticks)
      .def_readwrite("counts_per_rev", &TachometerParams::counts_per_rev)
      .def_readwrite("period", &TachometerParams::period, "[s]");
  py::class_<SensorParams>(m, "SensorParams")
      .def(py::init<>())
      .def_readwrite("gyro", &SensorParams::gyro)
      .def_readwrite("star_tracker", &SensorParams::star_tracker)
      .def_readwrite("tachometer", &SensorParams::tachometer)
      .def_readwrite("magnetometer", &SensorParams::magnetometer, "MagnetometerParams (SI units)")
      .def_readwrite("seed", &SensorParams::seed)
      .def_readwrite("dt", &SensorParams::dt, "[s] plant step (one tick)");
  py::class_<MekfParams>(m, "MekfParams", "The MEKF's noise model and start (mekf.hpp).")
      .def(py::init<>())
      .def_readwrite("arw", &MekfParams::arw)
      .def_readwrite("rrw", &MekfParams::rrw)
      .def_readwrite("bias_sigma", &MekfParams::bias_sigma)
      .def_readwrite("bias_tau", &MekfParams::bias_tau)
      .def_readwrite("quantization", &MekfParams::quantization)
      .def_readwrite("sigma_cross", &MekfParams::sigma_cross)
      .def_readwrite("sigma_boresight", &MekfParams::sigma_boresight)
      .def_readwrite("boresight", &MekfParams::boresight)
      .def_readwrite("initial_attitude_sigma", &MekfParams::initial_attitude_sigma)
      .def_readwrite("initial_bias_sigma", &MekfParams::initial_bias_sigma)
      .def_readwrite("degraded_after", &MekfParams::degraded_after)
      .def_readwrite("calibrate", &MekfParams::calibrate, "the 15-state calibrating filter")
      .def_readwrite("initial_scale_factor_sigma", &MekfParams::initial_scale_factor_sigma, "[-]")
      .def_readwrite("initial_misalignment_sigma", &MekfParams::initial_misalignment_sigma, "[rad]")
      .def_readwrite("initial_calibration", &MekfParams::initial_calibration,
                     "[-, rad] initial [s1 s2 s3, ku1 ku2 ku3, kl1 kl2 kl3] estimate (calibrate)")
      .def_readwrite("history", &MekfParams::history);
  py::class_<NavConfig>(m, "NavConfig")
      .def(py::init<>())
      .def_readwrite("sensors", &NavConfig::sensors)
      .def_readwrite("mekf", &NavConfig::mekf)
      .def_readwrite("use_estimate", &NavConfig::use_estimate);

  py::class_<Rng>(m, "Rng", "SplitMix64 stream with Box-Muller normals (sensors.hpp).")
      .def(py::init<std::uint64_t, std::uint64_t>(), arg("seed") = 0, arg("stream") = 0)
      .def("uniform", &Rng::uniform)
      .def("normal", &Rng::normal)
      .def("next_u64", &Rng::next_u64);
  m.def("boresight_frame", &boresight_frame, arg("boresight"));
  m.def("mrp_compose", &mrp_compose, arg("s1"), arg("s2"), "R(result) = R(s2) R(s1).");
  m.def("mrp_rotate_body", &mrp_rotate_body, arg("sigma_BN"), arg("v"),
        "R(result) = exp(-v^) R(sigma_BN), v [rad].");
  m.def("mrp_error_vector", &mrp_error_vector, arg("s1"), arg("s2"),
        "Rotation vector [rad] of R(s1) R(s2)'.");

  m.def("magnetometer_field_B", &magnetometer_field_B, arg("R_SB"), arg("B_S"),
        "The controller's field in B [T] from a magnetometer sample B_S [T]: R_SB' B_S.");
  py::class_<SensorSuite>(m, "SensorSuite", "Gyro, star tracker, tachometers and magnetometer (sensors.hpp).")
      .def(py::init<const SensorParams&>(), arg("p"))
      .def("reset", &SensorSuite::reset)
      .def("tick", [](SensorSuite& s, std::int64_t i, double t, const Vec10& x,
                      const std::optional<Vec3>& B_B) { s.tick(i, t, state_of(x), B_B ? &*B_B : nullptr); },
           arg("i"), arg("t"), arg("x"), arg("B_B") = py::none(),
           "B_B [T]: the true field in B at t, for the magnetometer when it is due (None: a sample of NaN).")
      .def("next_tick", &SensorSuite::next_tick, arg("i"))
      .def("magnetometer_due", &SensorSuite::magnetometer_due, arg("i"))
      .def_property_readonly("gyro_new", &SensorSuite::gyro_new)
      .def_property_readonly("star_new", &SensorSuite::star_new)
      .def_property_readonly("tach_new", &SensorSuite::tach_new)
      .def_property_readonly("mag_new", &SensorSuite::mag_new)
      .def_property_readonly("mag", [](const SensorSuite& s) {
        return py::make_tuple(s.mag().t, s.mag().B_S);
      }, "(t, B_S [T], sensor frame)")
      .def_property_readonly("gyro", [](const SensorSuite& s) {
        return py::make_tuple(s.gyro().t, s.gyro().omega, s.gyro().output);
      }, "(t, omega_m)")
      .def_property_readonly("star", [](const SensorSuite& s) {
        return py::make_tuple(s.star().t_exposure, s.star().t_delivery, s.star().sigma_BN);
      }, "(t_exposure, t_delivery, sigma_BN)")
      .def_property_readonly("tach", [](const SensorSuite& s) {
        return py::make_tuple(s.tach().t, s.tach().wheel_speed);
      }, "(t, wheel_speed)")
      .def_property_readonly("gyro_bias", &SensorSuite::gyro_bias, "[rad/s] true bias now")
      .def_property_readonly("lost", &SensorSuite::lost)
      .def_property_readonly("blacked_out", &SensorSuite::blacked_out)
      .def_property_readonly("delivered", &SensorSuite::delivered);
  m.def(
      "run_sensors",
      [](const SensorParams& p, std::int64_t n_ticks, const Vec10& x) {
        // Every sample of n_ticks plant steps from one constant state (t = i dt).
        SensorSuite s(p);
        const PlantState st = state_of(x);
        std::vector<double> gt, g, bias, se, sd, ss, tt, tw;
        {
          py::gil_scoped_release release;
          for (std::int64_t i = 0; i < n_ticks; ++i) {
            const double t = static_cast<double>(i) * p.dt;
            s.tick(i, t, st);
            if (s.gyro_new()) {
              gt.push_back(t);
              for (int k = 0; k < 3; ++k) g.push_back(s.gyro().omega(k));
              for (int k = 0; k < 3; ++k) bias.push_back(s.gyro_bias()(k));
            }
            if (s.star_new()) {
              se.push_back(s.star().t_exposure);
              sd.push_back(s.star().t_delivery);
              for (int k = 0; k < 3; ++k) ss.push_back(s.star().sigma_BN(k));
            }
            if (s.tach_new()) {
              tt.push_back(t);
              for (int k = 0; k < 4; ++k) tw.push_back(s.tach().wheel_speed(k));
            }
          }
        }
        auto arr = [](const std::vector<double>& v, py::ssize_t w) {
          const py::ssize_t n = static_cast<py::ssize_t>(v.size()) / w;
          py::array_t<double> a = w == 1 ? py::array_t<double>(n) : py::array_t<double>({n, w});
          std::copy(v.begin(), v.end(), a.mutable_data());
          return a;
        };
        py::dict d;
        d["gyro_t"] = arr(gt, 1);
        d["gyro"] = arr(g, 3);
        d["gyro_bias"] = arr(bias, 3);
        d["star_t_exposure"] = arr(se, 1);
        d["star_t_delivery"] = arr(sd, 1);
        d["star_sigma"] = arr(ss, 3);
        d["tach_t"] = arr(tt, 1);
        d["tach"] = arr(tw, 4);
        d["lost"] = s.lost();
        d["blacked_out"] = s.blacked_out();
        d["delivered"] = s.delivered();
        return d;
      },
      arg("p"), arg("n_ticks"), arg("x"),
      "Every sensor sample of n_ticks plant steps (t = i p.dt) from the constant state x (10,).");

  m.def(
      "time_estimator",
      [](const NavConfig& c, double rate, int n_ctrl, const Vec10& x, int reps) {
        // The controller's per-step estimator work (issue #15), timed apart from the sensors: the
        // samples of n_ctrl control periods drawn first (the SensorSuite from the constant state x,
        // as run_sensors), then replayed reps times into a fresh Estimator, each control step as
        // the controller sees it: the period's samples in tick order (gyro, star, tach), then
        // measure() with the telemetry at t_k = k / rate.
        const std::int64_t n_sub = static_cast<std::int64_t>(std::llround(1.0 / (rate * c.sensors.dt)));
        if (n_ctrl < 0 || n_sub < 1 || reps < 1)
          throw std::invalid_argument("time_estimator: need n_ctrl >= 0, rate * dt <= 1, reps >= 1");
        struct Event {
          int kind;  // 0 gyro, 1 star, 2 tach
          GyroSample g;
          StarSample s;
          TachSample w;
        };
        std::vector<Event> ev;
        std::vector<std::size_t> end(static_cast<std::size_t>(n_ctrl) + 1);  // events of steps <= k
        const PlantState st = state_of(x);
        std::vector<double> secs, sensor_secs;
        long gyro = 0, star = 0, tach = 0, updates = 0;
        double sink = 0.0;
        {
          py::gil_scoped_release release;
          SensorSuite sensors(c.sensors);
          for (int k = 0; k <= n_ctrl; ++k) {
            for (std::int64_t i = k == 0 ? 0 : (k - 1) * n_sub + 1; i <= k * n_sub; ++i) {
              sensors.tick(i, static_cast<double>(i) * c.sensors.dt, st);
              if (sensors.gyro_new()) ev.push_back(Event{0, sensors.gyro(), {}, {}}), ++gyro;
              if (sensors.star_new()) ev.push_back(Event{1, {}, sensors.star(), {}}), ++star;
              if (sensors.tach_new()) ev.push_back(Event{2, {}, {}, sensors.tach()}), ++tach;
            }
            end[static_cast<std::size_t>(k)] = ev.size();
          }
          const Vec3 sigma0 = initial_estimate(c.sensors.seed, c.mekf.initial_attitude_sigma, st.sigma_BN);
          for (int r = 0; r < reps; ++r) {
            Estimator e(c.mekf, c.use_estimate);
            e.reset(sigma0);
            NavTelemetry tel;
            std::size_t j = 0;
            const auto a = std::chrono::steady_clock::now();
            for (int k = 0; k <= n_ctrl; ++k) {
              for (; j < end[static_cast<std::size_t>(k)]; ++j) {
                const Event& v = ev[j];
                if (v.kind == 0) e.gyro(v.g);
                else if (v.kind == 1) e.star(v.s);
                else e.tach(v.w);
              }
              const double t = k / rate;
              const Measurement m = e.measure(Measurement{t, st.sigma_BN, st.omega_BN_B, st.wheel_speed}, &tel);
              sink += m.sigma_BN(0) + tel.P_diag(0);
            }
            const auto b = std::chrono::steady_clock::now();
            secs.push_back(std::chrono::duration<double>(b - a).count());
            updates = e.updates();
          }
          for (int r = 0; r < reps; ++r) {  // the sensors alone, every tick, nothing stored
            SensorSuite sn(c.sensors);
            const auto a = std::chrono::steady_clock::now();
            for (std::int64_t i = 0; i <= n_ctrl * n_sub; ++i) {
              sn.tick(i, static_cast<double>(i) * c.sensors.dt, st);
              if (sn.gyro_new()) sink += sn.gyro().omega(0);
            }
            const auto b = std::chrono::steady_clock::now();
            sensor_secs.push_back(std::chrono::duration<double>(b - a).count());
          }
        }
        py::dict d;
        d["seconds"] = secs;
        d["sensor_seconds"] = sensor_secs;
        d["control_steps"] = n_ctrl + 1;
        d["gyro_samples"] = gyro;
        d["star_samples"] = star;
        d["tach_samples"] = tach;
        d["updates"] = updates;
        d["sink"] = sink;
        return d;
      },
      arg("c"), arg("rate"), arg("n_ctrl"), arg("x"), arg("reps"),
      "Benchmark helper: wall time [s] of each of reps replays of n_ctrl + 1 control steps of the\n"
      "Estimator alone (the samples drawn beforehand from the constant state x (10,)); sensor_seconds:\n"
      "the SensorSuite alone ticked over the same plant steps, reps times.");

  bind_mekf<6>(m, "Mekf", "MekfState", "Multiplicative EKF, attitude error + gyro bias (mekf.hpp).");
  bind_mekf<15>(m, "MekfCal", "MekfCalState",
                "The calibrating MEKF: attitude error, gyro bias, scale factors and misalignments (mekf.hpp).");
  m.def("gyro_calibration_matrix", &gyro_calibration_matrix, arg("c"),
        "S of a calibrating filter's cal = [s1 s2 s3, ku1 ku2 ku3, kl1 kl2 kl3]: [[s1 ku1 ku2], [kl1 s2 ku3],\n"
        "[kl2 kl3 s3]] (the gyro measures (I + S) omega + b).");

  {
    py::list cols;
    for (const FieldSpec& f : kFields)
      if (f.group == kNav) cols.append(py::make_tuple(std::string(f.name), f.width));
    cols.append(py::make_tuple("nav_flags", 1));
    m.attr("NAV_FIELDS") = cols;
    m.attr("NAV_SIZE") = kNavSize;
    m.attr("FLAG_NAV_DEGRADED") = FLAG_NAV_DEGRADED;
  }
  py::class_<Navigation>(m, "Navigation", "Sensors + MEKF -> the law's Measurement (mekf.hpp).")
      .def(py::init<const NavConfig&>(), arg("c"))
      .def("reset", [](Navigation& n, const Vec10& x) { n.reset(state_of(x)); }, arg("x0"))
      .def("tick", [](Navigation& n, std::int64_t i, double t, const Vec10& x,
                      const std::optional<Vec3>& B_B) { n.tick(i, t, state_of(x), B_B ? &*B_B : nullptr); },
           arg("i"), arg("t"), arg("x"), arg("B_B") = py::none(),
           "B_B [T]: the true field in B at t, for the magnetometer when it is due (magnetometer_due).")
      .def("next_tick", &Navigation::next_tick, arg("i"))
      .def("magnetometer_due", &Navigation::magnetometer_due, arg("i"))
      .def_property_readonly("field_B", &Navigation::field_B,
                             "[T] the magnetometer's latest sample rotated to B (NaN: none yet)")
      .def("measure", [](Navigation& n, double t, const Vec10& x) {
             NavTelemetry tel;
             const Measurement m = n.measure(t, state_of(x), &tel);
             return py::make_tuple(m, pack(tel));
           }, arg("t"), arg("x"),
           "(Measurement, telemetry (NAV_SIZE,)) at t from the plant state x (10,).")
      .def("measure_only", [](Navigation& n, double t, const Vec10& x) {
             return n.measure(t, state_of(x));
           }, arg("t"), arg("x"), "The Measurement at t, no telemetry consumed.")
      .def_property_readonly("filter", &Navigation::filter, py::return_value_policy::reference_internal)
      .def_property_readonly("sensors", &Navigation::sensors, py::return_value_policy::reference_internal);

  m.def("initial_estimate", &initial_estimate, arg("seed"), arg("sigma"), arg("sigma_true0"),
        "The run's initial attitude estimate: sigma_true0 rotated by a draw of N(0, sigma^2 I) [rad].");
  py::class_<Estimator>(m, "Estimator",
                        "The controller's half of the navigation: MEKF fed with sensor samples (mekf.hpp).")
      .def(py::init<const MekfParams&, bool>(), arg("p"), arg("use_estimate"))
      .def("reset", &Estimator::reset, arg("sigma0"))
      .def("gyro",
           [](Estimator& e, double t, const Vec3& w, int output) { return e.gyro(GyroSample{t, w, output}); },
           arg("t"), arg("omega"), arg("output") = kGyroRate)
      .def("star", [](Estimator& e, double te, double td, const Vec3& s) {
             return e.star(StarSample{te, td, s});
           }, arg("t_exposure"), arg("t_delivery"), arg("sigma_BN"))
      .def("tach", [](Estimator& e, double t, const Vec4& w) { e.tach(TachSample{t, w}); },
           arg("t"), arg("wheel_speed"))
      .def("measure", [](Estimator& e, const Measurement& truth) {
             NavTelemetry tel;
             tel.bias_true.setConstant(std::numeric_limits<double>::quiet_NaN());
             tel.att_error.setConstant(std::numeric_limits<double>::quiet_NaN());
             const Measurement m = e.measure(truth, &tel);
             return py::make_tuple(m, pack(tel));
           }, arg("truth"),
           "(Measurement, telemetry (NAV_SIZE,); bias_true and att_est_error NaN: they need the truth).")
      .def("measure_only", [](Estimator& e, const Measurement& truth) { return e.measure(truth); },
           arg("truth"))
      .def_property_readonly("filter", &Estimator::filter, py::return_value_policy::reference_internal)
      .def_property_readonly("use_estimate", &Estimator::use_estimate);

  m.def(
      "simulate_closed_loop_sensed",
      [](const ControllerConfig& cfg, const PlantParams& plant, const ActuatorParams& act,
         const Vec10& x0, int n_ctrl, int n_sub, double rate, const NavConfig& nav) {
        ClosedLoopResult r;
        {
          py::gil_scoped_release release;
          r = simulate_closed_loop(cfg, plant, act, state_of(x0), n_ctrl, n_sub, rate, &nav);
        }
        return closed_loop_dict(r);
      },
      arg("c"), arg("plant"), arg("act"), arg("x0"), arg("n_ctrl"), arg("n_sub"), arg("rate"),
      arg("nav"),
      "simulate_closed_loop with sensors and the estimator (nav): the same columns, then the\n"
      "navigation's (sigma_BN_est, bias_est, bias_true, P_diag, att_est_error, innovation, nis).");
}

}  // namespace sc_rt_bind
