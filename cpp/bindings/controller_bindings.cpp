// pybind11 bindings of the control laws, their registry and the
// controllers (sc_rt._core), with the offline closed loop and the packed
// telemetry of the simulator's hot path. Called from core.cpp's module.
#include <optional>
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <string>
#include <type_traits>

#include "closed_loop_dict.hpp"
#include "defaults.hpp"
#include "sc_rt/closed_loop.hpp"
#include "sc_rt/controllers.hpp"
#include "translate.hpp"

namespace py = pybind11;
using namespace sc_rt;
using py::arg;

namespace {

// step_packed's row: the table's packed fields (fields.hpp) in table order,
// written by the core's producer (closed_loop.hpp for_each_command_field).
constexpr int kPackedSize = packed_size();
static_assert(kPackedSize == 63 + kLawMaxTelemetry, "step_packed's row changed size: update its docstring");

template <typename T>
py::bytes encode_lcm(const T& msg) {
  std::string buf(static_cast<std::size_t>(msg.getEncodedSize()), '\0');
  msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
  return py::bytes(buf);
}

using RowsD = py::array_t<double, py::array::c_style | py::array::forcecast>;

// Measurements from arrays: t (N,), sigma_BN (N,3), omega_BN_B (N,3), wheel_speed (N,4).
std::vector<Measurement> measurements(const RowsD& t, const RowsD& sigma, const RowsD& omega,
                                      const RowsD& wheel) {
  const auto n = t.shape(0);
  if (sigma.ndim() != 2 || sigma.shape(0) != n || sigma.shape(1) != 3 || omega.ndim() != 2 ||
      omega.shape(0) != n || omega.shape(1) != 3 || wheel.ndim() != 2 || wheel.shape(0) != n ||
      wheel.shape(1) != 4)
    throw std::invalid_argument(
        "expected t (N,), sigma_BN (N,3), omega_BN_B (N,3), wheel_speed (N,4)");
  auto T = t.unchecked<1>();
  auto S = sigma.unchecked<2>();
  auto W = omega.unchecked<2>();
  auto O = wheel.unchecked<2>();
  std::vector<Measurement> ms(static_cast<std::size_t>(n));
  for (py::ssize_t k = 0; k < n; ++k) {
    Measurement& m = ms[static_cast<std::size_t>(k)];
    m.t = T(k);
    for (int i = 0; i < 3; ++i) {
      m.sigma_BN(i) = S(k, i);
      m.omega_BN_B(i) = W(k, i);
    }
    for (int i = 0; i < 4; ++i) m.wheel_speed(i) = O(k, i);
  }
  return ms;
}

}  // namespace

void bind_controllers(py::module_& m) {
  // --- controllers
  // --- the law registry (docs/LAWS.md)
  py::register_exception<LawError>(m, "LawError", PyExc_ValueError);
  m.attr("LAW_API_VERSION") = SC_RT_LAW_API_VERSION;
  m.attr("LAW_FINGERPRINT") = SC_RT_LAW_FINGERPRINT;
  m.attr("LAW_MAX_TELEMETRY") = kLawMaxTelemetry;
  m.attr("DEFAULT_LAW") = kDefaultLaw;
  m.def("law_names", &law_names, "Every registered law name, registry order (the built-ins first).");
  m.def("load_law_plugin", &load_law_plugin, arg("path_or_name"),
        "Load a law plugin library (a path, or a name searched in SCRT_LAW_PATH); returns its\n"
        "law name. LawError (a ValueError) names the plugin and the problem.");
  m.def("plugin_file_problem", &plugin_file_problem, arg("path"),
        "Why the file at path cannot be loaded as a plugin (\"\" when it can), read before dlopen:\n"
        "a regular ELF shared library of this process's kind whose header tables and mapped\n"
        "segments lie within the file (a truncated one would die of SIGBUS in dlopen).");
  m.def(
      "law_info",
      [](const std::string& spec) {
        const LawEntry e = resolve_law(spec);
        py::dict d;
        d["name"] = e.name;
        d["doc"] = e.doc;
        d["source"] = e.source;
        d["code"] = e.code;
        d["defaults"] = e.defaults;
        d["command"] = law_command_name(e.command);
        return d;
      },
      arg("spec"),
      "name, doc, source (\"built-in\" or the library), code, defaults (its parameters'\n"
      "values when its table omits them: [(key, [numbers])], empty for a plugin) and command\n"
      "(what its u_cmd is: \"acceleration\" [rad/s^2] or \"torque\" [N m]) of a law spec.");
  m.attr("LAW_API_REVISION") = SC_RT_LAW_API_REVISION;
  m.def("check_law", &check_law, arg("c"),
        "Construct the configured law once and probe one step at rest, without running:\n"
        "[(key, message)] per problem; key \"law\" or \"params.<key>\" (empty: fine).");
  for (auto [name, v] : std::initializer_list<std::pair<const char*, int>>{
           {"MODE_INIT", MODE_INIT}, {"MODE_NORMAL", MODE_NORMAL}, {"MODE_SAFE", MODE_SAFE},
           {"FLAG_BOUND_X", FLAG_BOUND_X}, {"FLAG_BOUND_Y", FLAG_BOUND_Y},
           {"FLAG_BOUND_Z", FLAG_BOUND_Z}, {"FLAG_SAT_1", FLAG_SAT_1},
           {"FLAG_INVALID_STATE", FLAG_INVALID_STATE}, {"FLAG_STALE_STATE", FLAG_STALE_STATE},
           {"FLAG_TIME_NOT_ADVANCING", FLAG_TIME_NOT_ADVANCING},
           {"FLAG_LAW_INVALID", FLAG_LAW_INVALID}, {"FLAG_TIME_JUMP", FLAG_TIME_JUMP},
           {"FLAG_MODE_SWITCH", FLAG_MODE_SWITCH}})
    m.attr(name) = v;
  m.attr("MAX_DT_PERIODS") = kMaxDtPeriods;
  py::class_<SafetyLimits>(m, "SafetyLimits")
      .def(py::init<>())
      .def_readwrite("max_rate", &SafetyLimits::max_rate, "[rad/s]")
      .def_readwrite("max_wheel_speed", &SafetyLimits::max_wheel_speed, "[rad/s]")
      .def_readwrite("stale_periods", &SafetyLimits::stale_periods);
  py::class_<ControllerConfig>(m, "ControllerConfig", "Everything a controller needs.")
      .def(py::init<>())
      .def_readwrite("law", &ControllerConfig::law,
                     "law spec: a registered name or \"plugin:PATH_OR_NAME\"")
      .def_readwrite("law_params", &ControllerConfig::law_params,
                     "the law's own table ([laws.NAME]): [(key, [numbers])]")
      .def_readwrite("control_rate_hz", &ControllerConfig::control_rate_hz)
      .def_readwrite("spacecraft", &ControllerConfig::spacecraft)
      .def_readwrite("guidance", &ControllerConfig::guidance)
      .def_readwrite("ppc", &ControllerConfig::ppc)
      .def_readwrite("safety", &ControllerConfig::safety)
      .def_readwrite("magnetic", &ControllerConfig::magnetic,
                     "the rods, momentum manager and B-dot (MagneticConfig; controller_config_t mag_*, bdot_*)")
      .def_static("from_lcm_bytes",
                  [](const py::bytes& b) {
                    const std::string s = b;
                    return config_from_bytes(s.data(), static_cast<int>(s.size()));
                  },
                  arg("data"), "Decode an LCM-encoded controller_config_t.")
      .def("to_lcm_bytes",
           [](const ControllerConfig& c, const std::string& scenario) {
             return encode_lcm(config_to_lcm(c, scenario));
           },
           arg("scenario") = "", "Encode as controller_config_t.");
  m.def("validate", py::overload_cast<const ControllerConfig&>(&validate), arg("c"));

  py::class_<Measurement>(m, "Measurement")
      .def(py::init([](double t, const Vec3& s, const Vec3& w, const Vec4& o) {
             return Measurement{t, s, w, o};
           }),
           arg("t"), arg("sigma_BN"), arg("omega_BN_B"), arg("wheel_speed"))
      .def_readwrite("t", &Measurement::t, "[s]")
      .def_readwrite("sigma_BN", &Measurement::sigma_BN)
      .def_readwrite("omega_BN_B", &Measurement::omega_BN_B, "[rad/s]")
      .def_readwrite("wheel_speed", &Measurement::wheel_speed, "[rad/s]");
  py::class_<Command>(m, "Command")
      .def_readonly("t", &Command::t)
      .def_readonly("u_cmd", &Command::u_cmd, "[rad/s^2] before saturation")
      .def_readonly("u_sat", &Command::u_sat, "[rad/s^2] after saturation")
      .def_readonly("mode", &Command::mode)
      .def_property_readonly("ctrl_mode", [](const Command& c) { return c.mode; },
                             "mode under its field-table name (FIELD_TABLE: ctrl_mode)")
      .def_readonly("flags", &Command::flags)
      .def_readonly("sigma_DN", &Command::sigma_DN)
      .def_readonly("sigma_BD", &Command::sigma_BD)
      .def_readonly("omega_BD_B", &Command::omega_BD_B)
      .def_readonly("e1", &Command::e1)
      .def_readonly("e2", &Command::e2)
      .def_readonly("z1", &Command::z1)
      .def_readonly("z2", &Command::z2)
      .def_readonly("chi", &Command::chi)
      .def_readonly("lam", &Command::lam)
      .def_readonly("x2d", &Command::x2d)
      .def_readonly("vs", &Command::vs)
      .def_readonly("rho_hat", &Command::rho_hat)
      .def_readonly("telemetry", &Command::telemetry, "the law's named telemetry (Controller.telemetry_names)")
      .def_readonly("magnetic", &Command::magnetic, "the magnetic part's decision (MagneticOutput)")
      // the magnetic part's fields under their field-table names (FIELD_TABLE)
      .def_property_readonly("rod_dipole_cmd", [](const Command& c) { return c.magnetic.rod_dipole_cmd; },
                             "[A m^2] (6,)")
      .def_property_readonly("m_B_cmd", [](const Command& c) { return c.magnetic.m_B_cmd; }, "[A m^2]")
      .def_property_readonly("B_B", [](const Command& c) { return c.magnetic.B_B; }, "[T]")
      .def_property_readonly("h_wheels_B", [](const Command& c) { return c.magnetic.h_wheels_B; }, "[N m s]")
      .def_property_readonly("wheel_fill", [](const Command& c) { return c.magnetic.wheel_fill; }, "[-]")
      .def_property_readonly("unloading", [](const Command& c) { return c.magnetic.unloading; })
      .def_property_readonly("detumble_mode", [](const Command& c) { return c.magnetic.detumble_mode; });
  py::class_<TrackingErrors>(m, "TrackingErrors")
      .def_readonly("sigma_BD", &TrackingErrors::sigma_BD)
      .def_readonly("omega_BD_B", &TrackingErrors::omega_BD_B)
      .def_readonly("R_BD", &TrackingErrors::R_BD)
      .def_readonly("omega_DN_B", &TrackingErrors::omega_DN_B)
      .def_readonly("A", &TrackingErrors::A)
      .def_readonly("u_g0", &TrackingErrors::u_g0);
  m.def("tracking_errors", &tracking_errors, arg("sc"), arg("m"), arg("sigma_DN"),
        arg("omega_DN_D"), arg("omega_dot_DN_D"), "Errors (8)-(11) and A of (21).");
  m.def("measurement_valid", &measurement_valid, arg("m"), arg("lim"));

  py::class_<ControllerCounts>(m, "ControllerCounts",
                              "A controller's steps, law calls and refused time jumps since construction.")
      .def_readonly("steps", &ControllerCounts::steps, "step() calls")
      .def_readonly("engagements", &ControllerCounts::engagements, "(re-)engagements of the law")
      .def_readonly("law_resets", &ControllerCounts::law_resets, "calls of the law's reset")
      .def_readonly("law_steps", &ControllerCounts::law_steps, "calls of the law's step")
      .def_readonly("law_afters", &ControllerCounts::law_afters, "calls of the law's after")
      .def_readonly("jumps_ahead", &ControllerCounts::jumps_ahead,
                    "states stamped more than MAX_DT_PERIODS periods ahead (SAFE, FLAG_TIME_JUMP)")
      .def_readonly("steps_back", &ControllerCounts::steps_back,
                    "states stamped before the previous step (SAFE, FLAG_TIME_JUMP)")
      .def_property_readonly("law_calls", &ControllerCounts::law_calls, "resets + steps + afters")
      .def_property_readonly("time_jumps", &ControllerCounts::time_jumps, "jumps_ahead + steps_back");

  py::class_<Controller>(m, "Controller", "One control law behind reset/step.")
      .def(py::init(&Controller::create), arg("c"))
      .def("reset", &Controller::reset, arg("m"))
      .def("step", py::overload_cast<const Measurement&>(&Controller::step), arg("m"))
      .def("step", py::overload_cast<const Measurement&, const Vec3&>(&Controller::step), arg("m"), arg("B_B"),
           "One step with the field in B, B_B [T] (for the magnetic part only; NaN: none known).")
      .def("safe_command", &Controller::safe_command, arg("t"), arg("flags"))
      .def_property_readonly("law_name", &Controller::law_name, "the law's registry name")
      .def_property_readonly(
          "law_command", [](const Controller& c) { return std::string(law_command_name(c.law_command())); },
          "what the law's u_cmd is: \"acceleration\" [rad/s^2] or \"torque\" [N m]")
      .def_property_readonly("command_converted", &Controller::command_converted,
                             "whether the law's u_cmd is converted to the wheels' unit (Jw a or tau / Jw)")
      .def_property_readonly("law_code", &Controller::law_code, "its registry code")
      .def_property_readonly("telemetry_names", &Controller::telemetry_names)
      .def_property_readonly("config", &Controller::config)
      .def_property_readonly("model", &Controller::model)
      .def_property_readonly("t0", &Controller::t0)
      .def_property_readonly("guidance", &Controller::guidance, py::return_value_policy::reference_internal)
      .def_property_readonly(
          "law_failures", [](const Controller& c) { return sc_rt_bind::law_failures_dict(c.law_failures()); },
          "the law's contained failures: reset, step, after (counts) and last (None or {call, t, what})")
      .def_property_readonly(
          "counts", [](const Controller& c) { return c.counts(); }, "steps, law calls and time jumps so far (a copy)")
      .def_property_readonly("max_dt", &Controller::max_dt, "[s] the most dt a law is handed: MAX_DT_PERIODS periods")
      .def("prepare", &Controller::prepare,
           "Build the guidance's period table now (else at the first evaluation far from its time line).");

  // Packed telemetry of one step, one numpy allocation (the offline
  // simulator's hot path). Layout: PACKED_FIELDS (sc_rt.sim.engines.PACKED).
  {
    py::list fields;
    for (const FieldSpec& f : kFields)
      if (f.packed) fields.append(py::make_tuple(std::string(f.name), f.width));
    m.attr("PACKED_SIZE") = kPackedSize;
    m.attr("PACKED_FIELDS") = fields;
    m.attr("FIELD_TABLE") = sc_rt_bind::field_table();
  }
  m.def(
      "step_packed",
      [](Controller& c, double t, const Eigen::Matrix<double, 10, 1>& x, const std::optional<Vec3>& B_B) {
        Measurement m{t, x.segment<3>(0), x.segment<3>(3), x.segment<4>(6)};
        const Command cmd = B_B ? c.step(m, *B_B) : c.step(m);
        py::array_t<double> out(kPackedSize);
        double* o = out.mutable_data();
        for_each_command_field(cmd, [o](FieldId f, const auto& v) {
          double* d = o + packed_offset(f);
          if constexpr (std::is_arithmetic_v<std::decay_t<decltype(v)>>)
            *d = v;
          else
            for (int i = 0; i < v.size(); ++i) d[i] = v(i);
        });
        return out;
      },
      arg("controller"), arg("t"), arg("x"), arg("B_B") = py::none(),
      "One step from the plant state x = [sigma_BN, omega_BN_B, wheel_speed] (10,) at t [s]\n"
      "(B_B: the field in B [T] for the controller's magnetic part, None: step(m));\n"
      "returns the packed telemetry (71,): the field table's packed fields in table order\n"
      "(PACKED_FIELDS: (name, width) in this order).");

  m.attr("CLOSED_LOOP_FIELDS") = sc_rt_bind::loop_columns(kLoop);

  m.def(
      "simulate_closed_loop",
      [](const ControllerConfig& cfg, const PlantParams& plant, const ActuatorParams& act,
         const Eigen::Matrix<double, 10, 1>& x0, int n_ctrl, int n_sub, double rate) {
        PlantState x{x0.segment<3>(0), x0.segment<3>(3), x0.segment<4>(6)};
        ClosedLoopResult r;
        {
          py::gil_scoped_release release;
          r = simulate_closed_loop(cfg, plant, act, x, n_ctrl, n_sub, rate);
        }
        return sc_rt_bind::closed_loop_dict(r);
      },
      arg("c"), arg("plant"), arg("act"), arg("x0"), arg("n_ctrl"), arg("n_sub"), arg("rate"),
      "The whole offline closed loop in C++ (sc-rt sim --engine cpp): n_ctrl periods at rate [Hz],\n"
      "n_sub plant RK4 steps each; returns rows, diverged and the trajectory arrays (one row per\n"
      "control instant; CLOSED_LOOP_FIELDS: (name, width) in dict order).");

  // The resumable loop, a chunk of rows per call (sc_rt.sim.engines: a long run
  // written to disk as it runs, in memory that does not grow with it).
  struct ChunkedLoop {
    std::unique_ptr<ClosedLoop> loop;
    ClosedLoopResult buf;
    int capacity = 0;
  };
  py::class_<ChunkedLoop>(m, "ClosedLoop",
                          "simulate_closed_loop's loop, resumable: run(rows) advances it by up to rows\n"
                          "control instants and returns their columns as simulate_closed_loop does.")
      .def(py::init([](const ControllerConfig& cfg, const PlantParams& plant, const ActuatorParams& act,
                       const Eigen::Matrix<double, 10, 1>& x0, int n_ctrl, int n_sub, double rate) {
             PlantState x{x0.segment<3>(0), x0.segment<3>(3), x0.segment<4>(6)};
             auto c = std::make_unique<ChunkedLoop>();
             c->loop = std::make_unique<ClosedLoop>(cfg, plant, act, x, n_ctrl, n_sub, rate);
             c->buf.telemetry_names = c->loop->telemetry_names();
             return c;
           }),
           arg("c"), arg("plant"), arg("act"), arg("x0"), arg("n_ctrl"), arg("n_sub"), arg("rate"))
      .def(
          "run",
          [](ChunkedLoop& c, int rows) {
            if (rows <= 0) throw std::invalid_argument("ClosedLoop.run: rows must be > 0");
            if (rows > c.capacity) {  // sized once for the largest chunk asked
              c.buf.reserve_rows(static_cast<std::size_t>(rows), false);
              c.capacity = rows;
            }
            {
              py::gil_scoped_release release;
              c.loop->run(rows, &c.buf);
            }
            c.buf.diverged = c.loop->diverged();
            c.buf.law_failures = c.loop->law_failures();
            return sc_rt_bind::closed_loop_dict(c.buf);
          },
          arg("rows"),
          "Up to rows more control instants (fewer at the end or where the plant diverged): a dict\n"
          "as simulate_closed_loop's, of these rows only.")
      .def_property_readonly("done", [](const ChunkedLoop& c) { return c.loop->done(); })
      .def_property_readonly("telemetry_names", [](const ChunkedLoop& c) { return c.loop->telemetry_names(); },
                             "the law's telemetry names: the columns of its telemetry")
      .def_property_readonly("next_row", [](const ChunkedLoop& c) { return c.loop->next_row(); });

  m.def(
      "bare_closed_loop",
      [](const ControllerConfig& cfg, const PlantParams& plant, const ActuatorParams& act,
         const Eigen::Matrix<double, 10, 1>& x0, int n_ctrl, int n_sub, double rate) {
        PlantState x{x0.segment<3>(0), x0.segment<3>(3), x0.segment<4>(6)};
        int rows = 0;
        Eigen::Matrix<double, 10, 1> last;
        bool diverged = false;
        {
          py::gil_scoped_release release;
          ClosedLoop loop(cfg, plant, act, x, n_ctrl, n_sub, rate);
          rows = loop.run(n_ctrl + 1, nullptr);
          diverged = loop.diverged();
          const PlantState& xf = loop.state();
          last << xf.sigma_BN, xf.omega_BN_B, xf.wheel_speed;
        }
        return py::make_tuple(rows, diverged, last);
      },
      arg("c"), arg("plant"), arg("act"), arg("x0"), arg("n_ctrl"), arg("n_sub"), arg("rate"),
      "simulate_closed_loop's loop without recording (bench/bench_sim.py's bare loop: the law,\n"
      "the wheels and the plant, nothing written): (rows, diverged, the plant state of the\n"
      "last row, (10,)).");

  m.def(
      "run_steps",
      [](Controller& c, const RowsD& t, const RowsD& sigma, const RowsD& omega,
         const RowsD& wheel) {
        const auto ms = measurements(t, sigma, omega, wheel);
        const py::ssize_t n = static_cast<py::ssize_t>(ms.size());
        py::array_t<double> u_cmd({n, py::ssize_t(4)}), u_sat({n, py::ssize_t(4)});
        py::array_t<double> z2({n, py::ssize_t(3)});
        py::array_t<int> flags(n);
        auto U = u_cmd.mutable_unchecked<2>();
        auto S = u_sat.mutable_unchecked<2>();
        auto Z = z2.mutable_unchecked<2>();
        auto F = flags.mutable_unchecked<1>();
        {
          py::gil_scoped_release release;
          for (py::ssize_t k = 0; k < n; ++k) {
            const Command cmd = c.step(ms[static_cast<std::size_t>(k)]);
            for (int i = 0; i < 4; ++i) {
              U(k, i) = cmd.u_cmd(i);
              S(k, i) = cmd.u_sat(i);
            }
            for (int i = 0; i < 3; ++i) Z(k, i) = cmd.z2(i);
            F(k) = cmd.flags;
          }
        }
        py::dict out;
        out["u_cmd"] = u_cmd;
        out["u_sat"] = u_sat;
        out["z2"] = z2;
        out["flags"] = flags;
        return out;
      },
      arg("controller"), arg("t"), arg("sigma_BN"), arg("omega_BN_B"), arg("wheel_speed"),
      "Run N steps inside C++ on recorded measurements; returns u_cmd, u_sat, z2, flags.");

  m.def(
      "time_steps",
      [](Controller& c, const RowsD& t, const RowsD& sigma, const RowsD& omega,
         const RowsD& wheel) {
        const auto ms = measurements(t, sigma, omega, wheel);
        py::array_t<double> ns(static_cast<py::ssize_t>(ms.size()));
        auto N = ns.mutable_unchecked<1>();
        double sink = 0.0;
        {
          py::gil_scoped_release release;
          using clk = std::chrono::steady_clock;
          for (std::size_t k = 0; k < ms.size(); ++k) {
            const auto a = clk::now();
            const Command cmd = c.step(ms[k]);
            const auto b = clk::now();
            sink += cmd.u_cmd(0);
            N(static_cast<py::ssize_t>(k)) =
                static_cast<double>(std::chrono::duration_cast<std::chrono::nanoseconds>(b - a).count());
          }
        }
        return py::make_tuple(ns, sink);
      },
      arg("controller"), arg("t"), arg("sigma_BN"), arg("omega_BN_B"), arg("wheel_speed"),
      "Benchmark helper: per-step wall time [ns] of N steps inside C++ (bindings-side clock).");
}
