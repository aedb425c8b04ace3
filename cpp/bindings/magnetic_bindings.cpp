// Bindings of the magnetic actuators and their laws (sc_rt/magnetorquer.hpp,
// momentum.hpp, bdot.hpp) and of the magnetometer (sensors.hpp) into
// sc_rt._core, C++ names and argument names. Rod vectors cross as numpy
// arrays; a size beyond kMaxRods is a ValueError here, before Eigen sees it.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

#include "sc_rt/bdot.hpp"
#include "sc_rt/magnetic_control.hpp"
#include "sc_rt/magnetorquer.hpp"
#include "sc_rt/momentum.hpp"
#include "sc_rt/plant.hpp"
#include "sc_rt/sensors.hpp"

namespace py = pybind11;
using namespace sc_rt;
using py::arg;

namespace {
using VecX = Eigen::VectorXd;
using MatX = Eigen::MatrixXd;

RodVec to_rods(const VecX& v) {
  if (v.size() < 1 || v.size() > kMaxRods)
    throw std::invalid_argument("a rod vector needs 1 to " + std::to_string(kMaxRods) + " entries, got " +
                                std::to_string(v.size()));
  return RodVec(v);
}

RodAxes to_axes(const MatX& g) {
  if (g.rows() != 3 || g.cols() < 1 || g.cols() > kMaxRods)
    throw std::invalid_argument("G_B must be 3 x N with 1 <= N <= " + std::to_string(kMaxRods) + ", got " +
                                std::to_string(g.rows()) + " x " + std::to_string(g.cols()));
  return RodAxes(g);
}

VecX from_rods(const RodVec& v) { return VecX(v); }
}  // namespace

void bind_magnetics(py::module_& m) {
  m.attr("MAX_RODS") = kMaxRods;
  m.def("magnetic_torque", &magnetic_torque, arg("m_B"), arg("B_B"),
        "Torque [N m] of the dipole m_B [A m^2] in the field B_B [T]: m x B (Basilisk's MtbEffector).");
  py::enum_<RodFault>(m, "RodFault", "A magnetorquer rod's fault (magnetorquer.hpp)")
      .value("Healthy", RodFault::Healthy)
      .value("Dead", RodFault::Dead)
      .value("Stuck", RodFault::Stuck)
      .value("Reversed", RodFault::Reversed);
  m.def("rod_fault_name", &rod_fault_name, arg("f"));
  py::class_<MagnetorquerParams>(m, "MagnetorquerParams", "Rod axes and dipole limits (magnetorquer.hpp).")
      .def(py::init<>())
      .def_property(
          "G_B", [](const MagnetorquerParams& p) { return MatX(p.G_B); },
          [](MagnetorquerParams& p, const MatX& g) { p.G_B = to_axes(g); }, "[-] unit rod axes in B (3 x N)")
      .def_property(
          "dipole_max", [](const MagnetorquerParams& p) { return from_rods(p.dipole_max); },
          [](MagnetorquerParams& p, const VecX& v) { p.dipole_max = to_rods(v); }, "[A m^2] per rod (N,)");
  py::class_<PlantRods>(m, "PlantRods", "The plant's magnetorquer rods and their timed faults (plant.hpp).")
      .def(py::init<>())
      .def_readwrite("enabled", &PlantRods::enabled, "false: no rods")
      .def_readwrite("params", &PlantRods::params, "axes G_B and dipole_max")
      .def(
          "set_fault",
          [](PlantRods& r, int rod, RodFault f, double stuck_dipole, double onset, double end) {
            if (rod < 0 || rod >= kMaxRods)
              throw std::invalid_argument("PlantRods.set_fault: rod must be in [0, " + std::to_string(kMaxRods) +
                                          "), got " + std::to_string(rod));
            const auto k = static_cast<std::size_t>(rod);
            r.fault[k] = f;
            r.stuck[k] = stuck_dipole;
            r.onset[k] = onset;
            r.end[k] = end;
          },
          arg("rod"), arg("fault"), arg("stuck_dipole") = 0.0, arg("onset") = 0.0,
          arg("end") = std::numeric_limits<double>::infinity(),
          "Rod `rod`'s (0-based) fault on onset <= t < end [s] (stuck_dipole [A m^2]: RodFault.Stuck's).");
  m.def(
      "rods_dipole_B",
      [](const PlantRods& r, double t, const std::optional<VecX>& d_cmd) {
        if (d_cmd && d_cmd->size() != r.params.G_B.cols())
          throw std::invalid_argument("rods_dipole_B: " + std::to_string(d_cmd->size()) + " dipole commands for " +
                                      std::to_string(r.params.G_B.cols()) + " rods");
        if (!d_cmd) return rods_dipole_B(r, t, nullptr);
        const RodVec d = to_rods(*d_cmd);
        return rods_dipole_B(r, t, &d);
      },
      arg("r"), arg("t"), arg("d_cmd") = py::none(),
      "The body dipole m_B = G d [A m^2] of rod commands d_cmd (None: 0) at t [s]: clipped, faults applied.");
  m.def("validate", py::overload_cast<const MagnetorquerParams&>(&validate), arg("p"));
  py::class_<MagnetorquerOutput>(m, "MagnetorquerOutput")
      .def_property_readonly("dipole", [](const MagnetorquerOutput& o) { return from_rods(o.dipole); },
                             "[A m^2] applied rod dipoles")
      .def_readonly("m_B", &MagnetorquerOutput::m_B, "[A m^2] G_B dipole")
      .def_readonly("torque_B", &MagnetorquerOutput::torque_B, "[N m] m_B x B_B")
      .def_readonly("clipped", &MagnetorquerOutput::clipped, "bit i: rod i's command beyond its limit");
  py::class_<Magnetorquers>(m, "Magnetorquers", "The plant's rods: limits, faults, torque (magnetorquer.hpp).")
      .def(py::init<const MagnetorquerParams&>(), arg("p"))
      .def_property_readonly("n_rods", &Magnetorquers::n_rods)
      .def_property_readonly("params", &Magnetorquers::params)
      .def("set_fault", &Magnetorquers::set_fault, arg("rod"), arg("fault"), arg("stuck_dipole") = 0.0,
           "Rod `rod`'s fault from now on (stuck_dipole [A m^2] for RodFault.Stuck).")
      .def("fault", &Magnetorquers::fault, arg("rod"))
      .def("update",
           [](const Magnetorquers& q, const VecX& d_cmd, const Vec3& B_B) { return q.update(to_rods(d_cmd), B_B); },
           arg("d_cmd"), arg("B_B"), "Rod commands [A m^2] (N,) in the field B_B [T].");
  py::class_<DipoleAllocation>(m, "DipoleAllocation")
      .def_property_readonly("dipole", [](const DipoleAllocation& a) { return from_rods(a.dipole); }, "[A m^2]")
      .def_readonly("m_B", &DipoleAllocation::m_B, "[A m^2]")
      .def_readonly("scale", &DipoleAllocation::scale, "[-] 1: not saturated");
  py::class_<DipoleAllocator>(m, "DipoleAllocator",
                              "A body dipole onto the rods: G+ m, scaled into the limits (magnetorquer.hpp).")
      .def(py::init<const MagnetorquerParams&>(), arg("p"))
      .def_property_readonly("G_pinv", [](const DipoleAllocator& a) { return MatX(a.G_pinv()); })
      .def("allocate", &DipoleAllocator::allocate, arg("m_B"));

  // --- momentum management
  m.def("torque_to_dipole", &torque_to_dipole, arg("tau_B"), arg("B_B"),
        "(B x tau) / |B|^2 [A m^2]: the dipole whose torque is tau's part perpendicular to B (torque2Dipole).");
  m.def("cross_product_dipole", &cross_product_dipole, arg("h_err_B"), arg("B_B"), arg("k"),
        "k (h_err x B) / |B|^2 [A m^2]: its torque is -k (I - b b') h_err.");
  py::enum_<UnloadKind>(m, "UnloadKind")
      .value("CrossProduct", UnloadKind::CrossProduct)
      .value("Continuous", UnloadKind::Continuous);
  m.def("unload_kind_name", &unload_kind_name, arg("kind"));
  py::class_<MomentumParams>(m, "MomentumParams", "Momentum management (momentum.hpp).")
      .def(py::init<>())
      .def_readwrite("kind", &MomentumParams::kind)
      .def_readwrite("gain", &MomentumParams::gain, "[1/s]")
      .def_readwrite("hysteresis", &MomentumParams::hysteresis)
      .def_readwrite("on_fraction", &MomentumParams::on_fraction, "[-]")
      .def_readwrite("off_fraction", &MomentumParams::off_fraction, "[-]")
      .def_readwrite("capacity", &MomentumParams::capacity, "[N m s] (<= 0: min_i Jw_i wheel_speed_max_i)")
      .def_readwrite("null_gain", &MomentumParams::null_gain, "[1/s]")
      .def_readwrite("null_bias", &MomentumParams::null_bias, "[rad/s]");
  m.def("validate", py::overload_cast<const MomentumParams&, const SpacecraftParams&>(&validate), arg("p"),
        arg("wheels"));
  py::class_<MomentumOutput>(m, "MomentumOutput")
      .def_readonly("unloading", &MomentumOutput::unloading)
      .def_readonly("fill", &MomentumOutput::fill, "[-] |h_err_B| / capacity")
      .def_readonly("h_wheels_B", &MomentumOutput::h_wheels_B, "[N m s]")
      .def_readonly("h_err_B", &MomentumOutput::h_err_B, "[N m s]")
      .def_property_readonly("dipole", [](const MomentumOutput& o) { return from_rods(o.dipole); }, "[A m^2]")
      .def_readonly("m_B", &MomentumOutput::m_B, "[A m^2]")
      .def_readonly("scale", &MomentumOutput::scale, "[-]")
      .def_readonly("torque_mag_B", &MomentumOutput::torque_mag_B, "[N m]")
      .def_readonly("torque_ff", &MomentumOutput::torque_ff, "[N m] motor torques")
      .def_readonly("torque_null", &MomentumOutput::torque_null, "[N m] motor torques")
      .def_readonly("wheel_cmd", &MomentumOutput::wheel_cmd, "in the wheels' command unit");
  py::class_<MomentumManager>(m, "MomentumManager", "Unloading, feed-forward, null space (momentum.hpp).")
      .def(py::init<const MomentumParams&, const SpacecraftParams&, const MagnetorquerParams&>(), arg("p"),
           arg("wheels"), arg("rods"))
      .def("update", &MomentumManager::update, arg("wheel_speed"), arg("B_B"), arg("unloading"))
      .def("wheel_command", &MomentumManager::wheel_command, arg("T"))
      .def_property_readonly("params", &MomentumManager::params)
      .def_property_readonly("capacity", &MomentumManager::capacity)
      .def_property_readonly("omega_target", &MomentumManager::omega_target)
      .def_property_readonly("null_vector", &MomentumManager::null_vector)
      .def_property_readonly("Cbar_pinv", &MomentumManager::Cbar_pinv);

  // --- B-dot
  py::enum_<BdotDerivative>(m, "BdotDerivative")
      .value("Difference", BdotDerivative::Difference)
      .value("Analytic", BdotDerivative::Analytic);
  py::enum_<DetumbleMode>(m, "DetumbleMode")
      .value("Detumble", DetumbleMode::Detumble)
      .value("Attitude", DetumbleMode::Attitude);
  m.def("detumble_mode_name", &detumble_mode_name, arg("mode"));
  m.def("detumble_mode", &detumble_mode, arg("previous"), arg("rate"), arg("rate_on"), arg("rate_off"),
        "The mode after a sample of |omega| = rate [rad/s] (hysteresis between rate_off and rate_on).");
  m.def("bdot_gain", &bdot_gain, arg("orbit_rate"), arg("magnetic_inclination"), arg("J_min"),
        "Markley & Crassidis: k = 2 n (1 + sin xi_m) J_min [N m s].");
  py::class_<BdotParams>(m, "BdotParams", "B-dot detumbling (bdot.hpp).")
      .def(py::init<>())
      .def_readwrite("gain", &BdotParams::gain, "[N m s] normalized, [A m^2 s/T] otherwise")
      .def_readwrite("normalized", &BdotParams::normalized)
      .def_readwrite("derivative", &BdotParams::derivative)
      .def_readwrite("filter_tau", &BdotParams::filter_tau, "[s]")
      .def_readwrite("rate_on", &BdotParams::rate_on, "[rad/s]")
      .def_readwrite("rate_off", &BdotParams::rate_off, "[rad/s]");
  m.def("validate", py::overload_cast<const BdotParams&>(&validate), arg("p"));
  py::class_<BdotState>(m, "BdotState")
      .def(py::init<>())
      .def_readwrite("primed", &BdotState::primed)
      .def_readwrite("t", &BdotState::t, "[s]")
      .def_readwrite("B_B", &BdotState::B_B, "[T]")
      .def_readwrite("Bdot_B", &BdotState::Bdot_B, "[T/s]");
  py::class_<BdotOutput>(m, "BdotOutput")
      .def_readonly("Bdot_B", &BdotOutput::Bdot_B, "[T/s]")
      .def_property_readonly("dipole", [](const BdotOutput& o) { return from_rods(o.dipole); }, "[A m^2]")
      .def_readonly("m_B", &BdotOutput::m_B, "[A m^2]")
      .def_readonly("scale", &BdotOutput::scale, "[-]")
      .def_readonly("state", &BdotOutput::state);
  py::class_<Bdot>(m, "Bdot")
      .def(py::init<const BdotParams&, const MagnetorquerParams&>(), arg("p"), arg("rods"))
      .def("update", &Bdot::update, arg("s"), arg("t"), arg("B_B"), arg("omega_BN_B"))
      .def_property_readonly("params", &Bdot::params);

  // --- the controller's magnetic part (magnetic_control.hpp)
  py::class_<MagneticConfig>(m, "MagneticConfig",
                             "The rods as the controller knows them, the momentum manager and B-dot "
                             "(magnetic_control.hpp).")
      .def(py::init<>())
      .def_readwrite("rods_enabled", &MagneticConfig::rods_enabled)
      .def_readwrite("rods", &MagneticConfig::rods, "nominal rods (no faults)")
      .def_readwrite("momentum_enabled", &MagneticConfig::momentum_enabled)
      .def_readwrite("momentum", &MagneticConfig::momentum)
      .def_readwrite("bdot_enabled", &MagneticConfig::bdot_enabled)
      .def_readwrite("bdot", &MagneticConfig::bdot)
      .def("active", &MagneticConfig::active, "either part enabled");
  py::class_<MagneticOutput>(m, "MagneticOutput", "What the controller's magnetic part decided at a step.")
      .def_readonly("rod_dipole_cmd", &MagneticOutput::rod_dipole_cmd, "[A m^2] (6,), 0 beyond the rods")
      .def_readonly("m_B_cmd", &MagneticOutput::m_B_cmd, "[A m^2]")
      .def_readonly("B_B", &MagneticOutput::B_B, "[T]")
      .def_readonly("h_wheels_B", &MagneticOutput::h_wheels_B, "[N m s]")
      .def_readonly("wheel_fill", &MagneticOutput::wheel_fill, "[-]")
      .def_readonly("unloading", &MagneticOutput::unloading, "1, 0; -1 no manager")
      .def_readonly("detumble_mode", &MagneticOutput::detumble_mode, "0 detumble, 1 attitude; -1 no B-dot")
      .def_readonly("switched", &MagneticOutput::switched)
      .def_readonly("wheel_cmd", &MagneticOutput::wheel_cmd, "the manager's wheel command, wheels' unit");

  // --- magnetometer (sensors.hpp)
  py::class_<MagnetometerParams>(m, "MagnetometerParams", "Three-axis magnetometer (SI units; sensors.hpp).")
      .def(py::init<>())
      .def_readwrite("enabled", &MagnetometerParams::enabled)
      .def_readwrite("period_ticks", &MagnetometerParams::period_ticks)
      .def_readwrite("noise", &MagnetometerParams::noise, "[T] 1 sigma per axis")
      .def_readwrite("bias", &MagnetometerParams::bias, "[T] sensor frame")
      .def_readwrite("M", &MagnetometerParams::M, "[-] scale factor and misalignment")
      .def_readwrite("R_SB", &MagnetometerParams::R_SB, "[-] body to sensor")
      .def_readwrite("lsb", &MagnetometerParams::lsb, "[T]")
      .def_readwrite("range", &MagnetometerParams::range, "[T]");
  m.def("validate", py::overload_cast<const MagnetometerParams&>(&validate), arg("p"));
  py::class_<Magnetometer>(m, "Magnetometer")
      .def(py::init<const MagnetometerParams&, std::uint64_t>(), arg("p"), arg("seed"))
      .def("reset", &Magnetometer::reset)
      .def("sample", &Magnetometer::sample, arg("B_B"), "One sample [T], sensor frame, of B_B [T].")
      .def_property_readonly("params", &Magnetometer::params);
}
