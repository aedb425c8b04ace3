// Bindings of the C++ plant (sc_rt/plant.hpp) into sc_rt._core, C++ names
// and argument names. The keyword constructors of PlantParams, WheelFault and
// ActuatorParams validate (ValueError naming the field, from
// std::invalid_argument); fields assigned afterwards are not re-checked.
// From the Python dataclasses use sc_rt.model.plant.plant_params_to_cpp and
// sc_rt.model.actuators.actuator_params_to_cpp.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "sc_rt/plant.hpp"
#include "sc_rt/torque_plant.hpp"
#include "sc_rt/util.hpp"
#include "sc_rt/wheels.hpp"
#include "sensor_bindings.hpp"

namespace py = pybind11;
using namespace sc_rt;
using py::arg;

namespace {
using Vec10 = Eigen::Matrix<double, 10, 1>;

Vec10 to_vector(const PlantState& x) {
  Vec10 v;
  v << x.sigma_BN, x.omega_BN_B, x.wheel_speed;
  return v;
}

PlantState from_vector(const Vec10& v) {
  PlantState x;
  x.sigma_BN = v.segment<3>(0);
  x.omega_BN_B = v.segment<3>(3);
  x.wheel_speed = v.segment<4>(6);
  return x;
}

void set_faults(ActuatorParams& a, const std::vector<WheelFault>& faults) {
  if (faults.size() != 4)
    throw std::invalid_argument(
        "ActuatorParams.faults must hold 4 WheelFault (one per wheel), got " +
        std::to_string(faults.size()));
  for (std::size_t i = 0; i < 4; ++i) a.faults[i] = faults[i];
}

// A run's carried wheel state as Python holds it (sc_rt.model.truth.new_motor):
// the 4 motor torques [N m], then with stribeck_switching the 4 switches (0/1).
WheelCarry carry_from(const ActuatorParams& a, const Eigen::VectorXd& v) {
  const Eigen::Index n = a.wheels.stribeck_switching ? 8 : 4;
  if (v.size() != n)
    throw std::invalid_argument("motor: " + std::to_string(n) + " numbers for these wheels (motor torques" +
                                (n == 8 ? ", Stribeck switches" : "") + "), got " + std::to_string(v.size()));
  WheelCarry c;
  for (int i = 0; i < 4; ++i) c.motor(i) = v(i);
  if (n == 8)
    for (int i = 0; i < 4; ++i) c.stribeck[static_cast<std::size_t>(i)] = v(4 + i) != 0.0;
  return c;
}

Eigen::VectorXd carry_to(const ActuatorParams& a, const WheelCarry& c) {
  Eigen::VectorXd v(a.wheels.stribeck_switching ? 8 : 4);
  for (int i = 0; i < 4; ++i) v(i) = c.motor(i);
  if (v.size() == 8)
    for (int i = 0; i < 4; ++i) v(4 + i) = c.stribeck[static_cast<std::size_t>(i)] ? 1.0 : 0.0;
  return v;
}

TorqueWheels torque_wheels(const std::vector<std::array<double, 4>>& limits,
                           const std::vector<std::array<double, 5>>& friction, bool stribeck, bool torque_command) {
  if (limits.size() != 4 || friction.size() != 4) throw std::invalid_argument("TorqueWheels: 4 limits and 4 frictions");
  TorqueWheels w;
  w.enabled = true;
  w.stribeck = stribeck;
  w.torque_command = torque_command;
  for (std::size_t i = 0; i < 4; ++i) {
    const auto& l = limits[i];
    const auto& f = friction[i];
    w.limits[i] = WheelLimits{l[0], l[1], l[2], l[3]};
    w.friction[i] = WheelFriction{f[0], f[1], f[2], f[3], f[4]};
  }
  return w;
}
}  // namespace

void bind_plant(py::module_& m) {
  const PlantParams P;
  const ActuatorParams A;
  const WheelFault F;

  py::class_<PlantParams>(m, "PlantParams",
                          "True plant parameters (C++ engine); defaults are the paper's. "
                          "The keyword constructor validates.")
      .def(py::init([](const Mat3& J0, const Mat3& dJ, const Mat34& Cbar, const Vec4& Jw,
                       double w0, const Vec3& dist_amp, const Vec3& dist_freq,
                       const Vec3& dist_bias, const OrbitParams& orbit, const std::string& field_model,
                       const Vec3& residual_dipole, bool orbit_gravity_gradient,
                       const std::optional<PlantRods>& rods) {
             PlantParams p;
             p.orbit = orbit;
             if (!(field_model == "none" || field_model == "dipole" || field_model == "igrf" ||
                   field_model == "wmm2025"))
               throw py::value_error("PlantParams: field_model must be \"none\", \"dipole\", \"igrf\" or "
                                     "\"wmm2025\", got \"" + field_model + "\"");
             if (field_model != "none" && !orbit.enabled)
               throw py::value_error("PlantParams: field_model = \"" + field_model +
                                     "\" needs an orbit (orbit.enabled)");
             p.field = plant_field(orbit, field_model);
             p.residual_dipole = residual_dipole;
             p.orbit_gravity_gradient = orbit_gravity_gradient;
             if (rods) p.rods = *rods;
             p.J0 = J0;
             p.dJ = dJ;
             p.Cbar = Cbar;
             p.Jw = Jw;
             p.w0 = w0;
             p.dist_amp = dist_amp;
             p.dist_freq = dist_freq;
             p.dist_bias = dist_bias;
             throw_if_errors("PlantParams", validate(p));
             return p;
           }),
           arg("J0") = P.J0, arg("dJ") = P.dJ, arg("Cbar") = P.Cbar, arg("Jw") = P.Jw,
           arg("w0") = P.w0, arg("dist_amp") = P.dist_amp, arg("dist_freq") = P.dist_freq,
           arg("dist_bias") = P.dist_bias, arg("orbit") = P.orbit, arg("field_model") = "none",
           arg("residual_dipole") = P.residual_dipole, arg("orbit_gravity_gradient") = true,
           arg("rods") = py::none())
      .def_readwrite("J0", &PlantParams::J0, "[kg m^2] nominal inertia (3x3)")
      .def_readwrite("dJ", &PlantParams::dJ, "[kg m^2] inertia error; J = J0 + dJ (3x3)")
      .def_readwrite("Cbar", &PlantParams::Cbar, "[-] wheel axes in B (3x4)")
      .def_readwrite("Jw", &PlantParams::Jw, "[kg m^2] wheel spin inertias (4)")
      .def_readwrite("w0", &PlantParams::w0, "[rad/s] orbit rate of (5)")
      .def_readwrite("dist_amp", &PlantParams::dist_amp, "[N m] d(t) = bias + amp cos(freq t)")
      .def_readwrite("dist_freq", &PlantParams::dist_freq, "[rad/s]")
      .def_readwrite("dist_bias", &PlantParams::dist_bias, "[N m]")
      .def_readwrite("orbit", &PlantParams::orbit,
                     "the orbit (enabled: its gravity gradient replaces the w0 form of (5))")
      .def_property_readonly(
          "field_nmax", [](const PlantParams& p) { return p.field ? p.field->coefficients().nmax : 0; },
          "[-] the field's degree along the orbit (0: none, 1: tilted dipole, 12: WMM2025, 13: IGRF-14)")
      .def_property_readonly(
          "field_coefficients",
          [](const PlantParams& p) -> std::optional<GeomagCoeffs> {
            if (!p.field) return std::nullopt;
            return p.field->coefficients();
          },
          "the field's Gauss coefficients [nT] at the orbit's epoch (None: no field)")
      .def_readwrite("residual_dipole", &PlantParams::residual_dipole,
                     "[A m^2] the spacecraft's residual dipole in B (torque m x B)")
      .def_readwrite("orbit_gravity_gradient", &PlantParams::orbit_gravity_gradient,
                     "test-only: false drops the orbit's gravity gradient")
      .def_readwrite("rods", &PlantParams::rods, "the magnetorquer rods (enabled: a step without a dipole "
                     "input holds their dipole for a zero command)");
  m.def("validate", py::overload_cast<const PlantParams&>(&validate), arg("p"),
        "Every problem with the plant parameters (empty list: valid).");

  py::class_<WheelFault>(m, "WheelFault",
                         "One wheel's fault of (16); inactive by default. The keyword "
                         "constructor validates an active fault.")
      .def(py::init([](bool active, double effectiveness, double bias, double onset, double end,
                       double rate, bool stuck, double friction) {
             WheelFault f{active, effectiveness, bias, onset, end, rate, stuck, friction};
             throw_if_errors("WheelFault", validate(f));
             return f;
           }),
           arg("active") = F.active, arg("effectiveness") = F.effectiveness,
           arg("bias") = F.bias, arg("onset") = F.onset, arg("end") = F.end,
           arg("rate") = F.rate, arg("stuck") = F.stuck, arg("friction") = F.friction)
      .def_readwrite("active", &WheelFault::active, "false: healthy wheel")
      .def_readwrite("effectiveness", &WheelFault::effectiveness, "[-] L_i in [0, 1]")
      .def_readwrite("bias", &WheelFault::bias, "[rad/s^2] ubar_i")
      .def_readwrite("onset", &WheelFault::onset, "[s] T_i")
      .def_readwrite("end", &WheelFault::end, "[s] abrupt end (inf: never)")
      .def_readwrite("rate", &WheelFault::rate, "[1/s] a_i")
      .def_readwrite("stuck", &WheelFault::stuck, "zero acceleration while active")
      .def_readwrite("friction", &WheelFault::friction, "[-] friction multiplier as Y -> 1 (torque wheels)");
  m.def("validate", py::overload_cast<const WheelFault&>(&validate), arg("f"),
        "Problems of one fault (none when inactive).");
  m.def("fault_Y", &fault_Y, arg("f"), arg("t"), "Y_i(t) of (16) [-].");

  py::class_<TorqueWheels>(m, "TorqueWheels", "Flight-like torque-commanded wheels (sc_rt.model.wheels.TorqueWheels).")
      .def(py::init(&torque_wheels), arg("limits"), arg("friction"), arg("stribeck") = false,
           arg("torque_command") = false,
           "limits: 4 x (u_max, u_min, p_max, omega_max); friction: 4 x (coulomb, static, beta, viscous,\n"
           "omega_limit_cycle).")
      .def_readonly("enabled", &TorqueWheels::enabled)
      .def_readonly("stribeck", &TorqueWheels::stribeck)
      .def_readonly("torque_command", &TorqueWheels::torque_command)
      .def_readwrite("lag", &TorqueWheels::lag, "[s] motor lag time constants (0: none)")
      .def_readwrite("stribeck_switching", &TorqueWheels::stribeck_switching,
                     "the static (Stribeck) friction switched per wheel by Basilisk's rule (a carried state)");

  py::class_<ActuatorParams>(m, "ActuatorParams",
                             "Wheel limits and faults (C++ engine). The keyword constructor "
                             "validates.")
      .def(py::init([](const Vec4& umin, const Vec4& umax, const Vec4& max_wheel_speed,
                       const std::vector<WheelFault>& faults, const std::optional<TorqueWheels>& wheels) {
             ActuatorParams a;
             a.umin = umin;
             a.umax = umax;
             a.max_wheel_speed = max_wheel_speed;
             set_faults(a, faults);
             if (wheels) a.wheels = *wheels;
             throw_if_errors("ActuatorParams", validate(a));
             return a;
           }),
           arg("umin") = A.umin, arg("umax") = A.umax,
           arg("max_wheel_speed") = A.max_wheel_speed,
           arg("faults") = std::vector<WheelFault>(A.faults.begin(), A.faults.end()),
           arg("wheels") = py::none())
      .def_readwrite("umin", &ActuatorParams::umin, "[rad/s^2] lower limits (4)")
      .def_readwrite("umax", &ActuatorParams::umax, "[rad/s^2] upper limits (4)")
      .def_readwrite("max_wheel_speed", &ActuatorParams::max_wheel_speed,
                     "[rad/s] wheel-speed limits (4; inf: none)")
      .def_property(
          "faults",
          [](py::object self) {
            ActuatorParams& a = self.cast<ActuatorParams&>();
            py::tuple t(4);
            for (std::size_t i = 0; i < 4; ++i)
              t[i] = py::cast(&a.faults[i], py::return_value_policy::reference_internal, self);
            return t;
          },
          &set_faults,
          "The 4 wheels' faults: a tuple of references (assigning their fields edits this "
          "object); assign a sequence of 4 WheelFault to replace them all.")
      .def_readonly("wheels", &ActuatorParams::wheels, "the torque-commanded wheels (enabled false: the paper's)");
  m.def("validate", py::overload_cast<const ActuatorParams&>(&validate), arg("a"),
        "Every problem with the actuator parameters (empty list: valid).");

  py::class_<PlantState>(m, "PlantState",
                         "Plant state; as a vector [sigma_BN, omega_BN_B, wheel_speed].")
      .def(py::init([](const Vec3& sigma_BN, const Vec3& omega_BN_B, const Vec4& wheel_speed) {
             return PlantState{sigma_BN, omega_BN_B, wheel_speed};
           }),
           arg("sigma_BN") = Vec3::Zero().eval(), arg("omega_BN_B") = Vec3::Zero().eval(),
           arg("wheel_speed") = Vec4::Zero().eval())
      .def_readwrite("sigma_BN", &PlantState::sigma_BN, "[-] MRP of B relative to N")
      .def_readwrite("omega_BN_B", &PlantState::omega_BN_B, "[rad/s] body rate in B")
      .def_readwrite("wheel_speed", &PlantState::wheel_speed, "[rad/s] relative to the body")
      .def_static("from_vector", &from_vector, arg("x"),
                  "From x = [sigma_BN (3), omega_BN_B (3), wheel_speed (4)].")
      .def("to_vector", &to_vector, "x = [sigma_BN (3), omega_BN_B (3), wheel_speed (4)].")
      .def("__repr__", [](const PlantState& x) {
        return "PlantState(sigma_BN=" + format_matrix(x.sigma_BN) +
               ", omega_BN_B=" + format_matrix(x.omega_BN_B) +
               ", wheel_speed=" + format_matrix(x.wheel_speed) + ")";
      });

  py::class_<WheelOutput>(m, "WheelOutput")
      .def_readonly("u_sat", &WheelOutput::u_sat, "[rad/s^2] saturated commands")
      .def_readonly("accel", &WheelOutput::accel, "[rad/s^2] actual wheel accelerations")
      .def_readonly("Y", &WheelOutput::Y, "[-] fault activations of (16)");

  m.def("wheel_accel", &wheel_accel, arg("a"), arg("t"), arg("u_cmd"), arg("wheel_speed"),
        "Saturation and faults (15),(16), stuck wheels and the speed limit.");
  m.def("disturbance", &disturbance, arg("p"), arg("t"), "d(t) [N m] in B.");
  m.def(
      "plant_field_B",
      [](const PlantParams& p, double t, const Vec3& sigma_BN) -> std::optional<Vec3> {
        Vec3 B;
        if (!plant_field_B(p, t, sigma_BN, B)) return std::nullopt;
        return B;
      },
      arg("p"), arg("t"), arg("sigma_BN"),
      "The plant's field in B [T] at t [s] for the attitude sigma_BN (None without a field).");
  m.def(
      "plant_derivative",
      [](const PlantParams& p, double t, const PlantState& x, const Vec4& wheel_accel,
         const std::optional<Vec3>& dipole_B) {
        return plant_derivative(p, t, x, wheel_accel, dipole_B ? &*dipole_B : nullptr);
      },
      arg("p"), arg("t"), arg("x"), arg("wheel_accel"), arg("dipole_B") = py::none(),
      "State derivative (1),(2),(7) for the actual wheel accelerations [rad/s^2]\n"
      "(dipole_B: the magnetorquers' body dipole [A m^2]).");
  m.def(
      "plant_rk4_step",
      [](const PlantParams& p, const ActuatorParams& a, double t, const PlantState& x, double h, const Vec4& u_cmd,
         const std::optional<Vec3>& dipole_B) {
        return plant_rk4_step(p, a, t, x, h, u_cmd, dipole_B ? &*dipole_B : nullptr);
      },
      arg("p"), arg("a"), arg("t"), arg("x"), arg("h"), arg("u_cmd"), arg("dipole_B") = py::none(),
      "One RK4 step from t to t + h [s], u_cmd and the magnetorquers' body dipole dipole_B [A m^2]\n"
      "held; then the MRP short set.");
  m.def("lumped_disturbance", &lumped_disturbance, arg("p"), arg("t"), arg("x"), arg("u_sat"),
        arg("accel"), "The true delta_2 of (20),(21) [rad/s^2].");
  // flight-like wheels (issue #28; python/sc_rt/model/wheels.py is the reference)
  m.def(
      "wheel_applied_torque",
      [](double u, double omega, double u_max, double u_min, double p_max, double omega_max) {
        return wheel_applied_torque(u, omega, WheelLimits{u_max, u_min, p_max, omega_max});
      },
      arg("u"), arg("omega"), arg("u_max"), arg("u_min"), arg("p_max"), arg("omega_max"),
      "The motor torque [N m] a wheel applies for the command u at the speed omega [rad/s]\n"
      "(torque limit, deadband, power limit, speed limit; <= 0: none).");
  m.def(
      "wheel_friction_torque",
      [](double omega, double coulomb, double static_, double beta, double viscous, double omega_lc,
         bool stribeck) {
        return wheel_friction_torque(omega, WheelFriction{coulomb, static_, beta, viscous, omega_lc}, stribeck);
      },
      arg("omega"), arg("coulomb"), arg("static"), arg("beta"), arg("viscous"), arg("omega_limit_cycle"),
      arg("stribeck"), "The friction torque [N m] on a wheel at omega [rad/s] (opposing it).");
  m.def(
      "wheel_stribeck_switch",
      [](bool on, double omega, double omega_start, double beta, double omega_lc) {
        return wheel_stribeck_switch(on, omega, omega_start, WheelFriction{0.0, 0.0, beta, 0.0, omega_lc});
      },
      arg("on"), arg("omega"), arg("omega_start"), arg("beta"), arg("omega_limit_cycle"),
      "Basilisk's switch of the static (Stribeck) friction at one evaluation: on near rest\n"
      "(|omega| < 0.1 omega_limit_cycle), off while |omega| decreases from omega_start [rad/s].");
  m.def(
      "plant_row",
      [](const PlantParams& p, const ActuatorParams& a, double t, const PlantState& x, const Vec4& u_cmd,
         const std::optional<Eigen::VectorXd>& motor, const std::optional<Vec3>& dipole_B) {
        const Vec3* m_B = dipole_B ? &*dipole_B : nullptr;
        if (!motor) return plant_row(p, a, t, x, u_cmd, nullptr, m_B);
        const WheelCarry c = carry_from(a, *motor);
        return plant_row(p, a, t, x, u_cmd, &c, m_B);
      },
      arg("p"), arg("a"), arg("t"), arg("x"), arg("u_cmd"), arg("motor") = py::none(), arg("dipole_B") = py::none(),
      "The wheels' output of a row at (t, x) for u_cmd, either wheel model (sc_rt.model.truth.row);\n"
      "motor: what the run carries at t (truth.new_motor): the motor torques of lagged wheels, then\n"
      "with stribeck_switching the Stribeck switches (0/1); dipole_B [A m^2]: the magnetorquers' body\n"
      "dipole the step from t holds (None: the rods' for a zero command).");
  m.def(
      "plant_rk4_step_motor",
      [](const PlantParams& p, const ActuatorParams& a, double t, const PlantState& x, double h, const Vec4& u_cmd,
         const Eigen::VectorXd& motor, const std::optional<Vec3>& dipole_B) {
        WheelCarry c = carry_from(a, motor);
        const PlantState r = plant_rk4_step(p, a, t, x, h, u_cmd, c, dipole_B ? &*dipole_B : nullptr);
        return py::make_tuple(r, carry_to(a, c));
      },
      arg("p"), arg("a"), arg("t"), arg("x"), arg("h"), arg("u_cmd"), arg("motor"), arg("dipole_B") = py::none(),
      "plant_rk4_step carrying the state of torque-commanded wheels (truth.new_motor: the motor torques,\n"
      "then with stribeck_switching the Stribeck switches as 0/1): (state, motor at t + h).");
  m.def("wheel_torque_command", &wheel_torque_command, arg("u"), arg("Jw"), arg("torque_command"),
        "The motor torque [N m] a wheel command asks: Jw u (acceleration) or u (torque).");
  py::class_<TorquePlant>(m, "TorquePlant",
                          "The plant with torque-commanded wheels (sc_rt.model.torque_plant.TorquePlant's\n"
                          "twin, bitwise equal).")
      .def(py::init([](const PlantParams& p, const std::vector<std::array<double, 4>>& limits,
                       const std::vector<std::array<double, 5>>& friction, bool stribeck) {
             if (limits.size() != 4 || friction.size() != 4)
               throw std::invalid_argument("TorquePlant: 4 limits and 4 frictions");
             return std::make_unique<TorquePlant>(p, torque_wheels(limits, friction, stribeck, false));
           }),
           arg("plant"), arg("limits"), arg("friction"), arg("stribeck") = false,
           "limits: 4 x (u_max, u_min, p_max, omega_max); friction: 4 x (coulomb, static, beta,\n"
           "viscous, omega_limit_cycle).")
      .def(
          "step",
          [](const TorquePlant& tp, double t, const Eigen::Matrix<double, 10, 1>& x, double h, const Vec4& u) {
            const PlantState s{x.segment<3>(0), x.segment<3>(3), x.segment<4>(6)};
            const PlantState r = tp.step(t, s, h, u);
            Eigen::Matrix<double, 10, 1> out;
            out << r.sigma_BN, r.omega_BN_B, r.wheel_speed;
            return out;
          },
          arg("t"), arg("x"), arg("h"), arg("u_cmd"), "One RK4 step from t to t + h [s], u_cmd [N m] held.")
      .def_property_readonly("M", &TorquePlant::M, "J - Cbar diag(Jw) Cbar' [kg m^2].");
  sc_rt_bind::bind_sensors(m);  // sensor_bindings.hpp
}
