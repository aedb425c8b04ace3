// pybind11 module sc_rt._core: the C++ core, names and argument names as in
// C++. numpy in/out for 3-vectors, 4-vectors and 3x4 matrices.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "defaults.hpp"
#include "sc_rt/guidance.hpp"
#include "sc_rt/mrp.hpp"
#include "sc_rt/neso.hpp"
#include "sc_rt/ppc.hpp"
#include "sc_rt/spacecraft.hpp"

namespace py = pybind11;
using namespace sc_rt;
using py::arg;

// One function per area (the module below only calls them): the core's
// math here; the control laws and controllers (controller_bindings.cpp), the
// plant twin (plant_bindings.cpp), the shell's policy (shell_bindings.cpp).
void bind_controllers(pybind11::module_& m);
void bind_plant(pybind11::module_& m);
void bind_orbit(pybind11::module_& m);
void bind_shell(pybind11::module_& m);
void bind_pylaw(pybind11::module_& m);

namespace {

// MRP, spacecraft, guidance, NESO and PPC (MODEL.md sections 1-7).
void bind_math(py::module_& m) {
  // --- MRP (MODEL.md sections 1, 3)
  m.def("skew", &skew, arg("x"), "Skew matrix x^ with x^ y = x cross y.");
  m.def("mrp_G", &mrp_G, arg("sigma"),
        "G(sigma) of (1),(2): sigma_dot = G(sigma) omega [rad/s -> 1/s].");
  m.def("mrp_G_inverse", &mrp_G_inverse, arg("sigma"), "Inverse of G(sigma).");
  m.def("mrp_to_dcm", &mrp_to_dcm, arg("sigma"),
        "Direction cosine matrix R(sigma) (10): maps N components to B for sigma_BN.");
  m.def("mrp_shadow", &mrp_shadow, arg("sigma"), "Shadow set -sigma/|sigma|^2 (same attitude).");
  m.def("mrp_short", &mrp_short, arg("sigma"), "The shadow set when |sigma| > 1, else sigma.");
  m.def("mrp_subtract", &mrp_subtract, arg("sigma_BN"), arg("sigma_DN"),
        "sigma_BD from sigma_BN and sigma_DN by composition (8), short rotation.");

  // --- spacecraft
  py::class_<SpacecraftParams>(m, "SpacecraftParams",
                               "Parameters the controller knows; defaults are the paper's.")
      .def(py::init<>())
      .def_readwrite("J0", &SpacecraftParams::J0, "[kg m^2] nominal inertia (3x3)")
      .def_readwrite("Cbar", &SpacecraftParams::Cbar, "[-] wheel axes in B (3x4)")
      .def_readwrite("Jw", &SpacecraftParams::Jw, "[kg m^2] wheel spin inertias (4)")
      .def_readwrite("umin", &SpacecraftParams::umin, "[rad/s^2] lower limits (4)")
      .def_readwrite("umax", &SpacecraftParams::umax, "[rad/s^2] upper limits (4)")
      .def_readwrite("wheel_torque_command", &SpacecraftParams::wheel_torque_command,
                     "the wheels take a motor torque [N m] (umin/umax then in N m)")
      .def_readwrite("wheel_speed_max", &SpacecraftParams::wheel_speed_max,
                     "[rad/s] the wheels' speed limits (4; inf: none), for the law")
      .def_readwrite("w0", &SpacecraftParams::w0, "[rad/s] orbit rate")
      .def_readwrite("pinv_damping", &SpacecraftParams::pinv_damping,
                     "[-] damping of B+ (0: exact pseudo-inverse)");
  m.def("validate", py::overload_cast<const SpacecraftParams&>(&validate), arg("p"),
        "Every problem with the parameters (empty list: valid).");
  py::class_<SpacecraftModel>(m, "SpacecraftModel", "Validated parameters with B and B+ of (21).")
      .def(py::init<const SpacecraftParams&>(), arg("p"))
      .def_property_readonly("params", &SpacecraftModel::params)
      .def_property_readonly("B", &SpacecraftModel::B, "B = -J0^-1 Cbar Jw (3x4)")
      .def_property_readonly("B_pinv", &SpacecraftModel::B_pinv, "B+ (4x3)")
      .def("saturate", &SpacecraftModel::saturate, arg("u"), "Saturation of (15) [rad/s^2].");
  m.def("gravity_gradient", &gravity_gradient, arg("J"), arg("sigma_BN"), arg("w0"),
        "Gravity-gradient torque (5),(6) [N m].");

  // --- guidance
  py::enum_<GuidanceKind>(m, "GuidanceKind", "= controller_config_t.GUIDANCE_*")
      .value("Paper", GuidanceKind::Paper)
      .value("Hold", GuidanceKind::Hold)
      .value("Slew", GuidanceKind::Slew)
      .value("Table", GuidanceKind::Table);
  m.def("guidance_kind_name", &guidance_kind_name, arg("kind"));
  m.attr("GUIDANCE_TABLE_MAX") = kGuidanceTableMax;
  py::class_<GuidanceParams>(m, "GuidanceParams",
                             "The desired trajectory: the paper's omega_DN_D(t) = bias + cos_amp "
                             "cos(freq t) + sin_amp sin(freq t) (kind Paper), a hold, a slew or a table")
      .def(py::init<>())
      .def_readwrite("kind", &GuidanceParams::kind)
      .def_readwrite("sigma_d0", &GuidanceParams::sigma_d0,
                     "[-] sigma_DN(0) (Paper), the held attitude (Hold), the start (Slew)")
      .def_readwrite("omega_bias", &GuidanceParams::omega_bias, "[rad/s]")
      .def_readwrite("omega_cos", &GuidanceParams::omega_cos, "[rad/s]")
      .def_readwrite("omega_sin", &GuidanceParams::omega_sin, "[rad/s]")
      .def_readwrite("omega_freq", &GuidanceParams::omega_freq, "[rad/s]")
      .def_readwrite("slew_target", &GuidanceParams::slew_target, "[-] sigma_DN after the slew")
      .def_readwrite("slew_start", &GuidanceParams::slew_start, "[s]")
      .def_readwrite("slew_duration", &GuidanceParams::slew_duration, "[s]")
      .def_readwrite("table_t", &GuidanceParams::table_t, "[s] sample times (n,)")
      .def_readwrite("table_sigma", &GuidanceParams::table_sigma, "[-] sigma_DN samples (n, 3)")
      .def_readwrite("table_omega", &GuidanceParams::table_omega, "[rad/s] omega_DN_D samples (n, 3)");
  m.def("validate", py::overload_cast<const GuidanceParams&>(&validate), arg("p"));
  m.def("omega_d", &omega_d, arg("p"), arg("t"), "omega_DN_D(t) [rad/s].");
  m.def("omega_d_dot", &omega_d_dot, arg("p"), arg("t"), "d omega_DN_D / dt [rad/s^2].");
  m.def("guidance_integrated", &guidance_integrated, arg("p"),
        "True for the paper's kind (sigma_DN integrated), False for the closed forms.");
  m.def("sigma_d", &sigma_d, arg("p"), arg("t"),
        "sigma_DN(t) of a closed-form kind (Hold, Slew, Table); ValueError for Paper.");
  m.def("slew_axis", &slew_axis, arg("p"), "Eigenaxis of the slew (zero for no rotation).");
  m.def("slew_angle", &slew_angle, arg("p"), "[rad] angle of the slew, in [0, pi].");
  m.def("guidance_rk4_step", &guidance_rk4_step, arg("p"), arg("sigma"), arg("t"), arg("h"),
        "One RK4 step of the desired attitude from t to t + h [s].");
  m.attr("GUIDANCE_MAX_CATCH_UP") = kGuidanceMaxCatchUp;
  m.attr("GUIDANCE_PERIOD_STEPS_MAX") = kGuidancePeriodStepsMax;
  py::class_<GuidancePeriodTable>(m, "GuidancePeriodTable",
                                  "How the paper's reference is evaluated far from its time line")
      .def_property_readonly("kind", [](const GuidancePeriodTable& t) {
        return t.kind == GuidancePeriodTable::Periodic ? "periodic"
               : t.kind == GuidancePeriodTable::Constant ? "constant" : "closed_form";
      }, "closed_form (hold, slew, table), constant (the paper's kind with a constant rate: closed form)\n"
         "or periodic (the paper's kind: a table over one period)")
      .def_readonly("omega", &GuidancePeriodTable::omega, "[rad/s] the constant rate (constant)")
      .def_readonly("period", &GuidancePeriodTable::period, "[s] 2 pi / |freq| (periodic)")
      .def_readonly("n_steps", &GuidancePeriodTable::n_steps, "RK4 steps over one period (periodic)")
      .def_readonly("stride", &GuidancePeriodTable::stride, "RK4 steps between anchors (periodic)")
      .def_readonly("anchors", &GuidancePeriodTable::anchors, "anchors after t = 0 (periodic)")
      .def_readonly("h", &GuidancePeriodTable::h, "[s] the table's RK4 step (periodic)");
  m.def("guidance_period_table", &guidance_period_table, arg("p"));
  py::class_<Guidance>(m, "Guidance", "Desired attitude on the controller's time line.")
      .def(py::init<const GuidanceParams&, double>(), arg("p"), arg("max_step") = 0.1)
      .def("reset", &Guidance::reset, arg("t0"))
      .def("advance", &Guidance::advance, arg("t"),
           "Along the time line (at most GUIDANCE_MAX_CATCH_UP RK4 steps), else seek(t).")
      .def("seek", &Guidance::seek, arg("t"), "sigma_DN(t) from the definition at any t (bounded work).")
      .def("prepare", &Guidance::prepare, "Build the period table now (else at the first seek).")
      .def_property_readonly("t", &Guidance::t)
      .def_property_readonly("sigma_DN", &Guidance::sigma_DN)
      .def_property_readonly("params", &Guidance::params)
      .def_property_readonly("period_table", &Guidance::period_table)
      .def_property_readonly("prepared", &Guidance::prepared, "the period table is built")
      .def_property_readonly("rk4_steps", &Guidance::rk4_steps,
                             "RK4 steps taken since construction (the period table's included)")
      .def_property_readonly("seeks", &Guidance::seeks, "evaluations from the definition (seek) so far");

  // --- NESO (22)
  py::class_<NesoParams>(m, "NesoParams", "Observer (22) gains; defaults are the paper's.")
      .def(py::init<>())
      .def_readwrite("k1", &NesoParams::k1)
      .def_readwrite("k2", &NesoParams::k2)
      .def_readwrite("k3", &NesoParams::k3)
      .def_readwrite("k4", &NesoParams::k4)
      .def_readwrite("alpha", &NesoParams::alpha)
      .def_readwrite("substeps", &NesoParams::substeps, "RK4 steps per control period")
      .def_readwrite("init_from_measurement", &NesoParams::init_from_measurement);
  m.def("validate", py::overload_cast<const NesoParams&>(&validate), arg("p"));
  m.def("neso_condition_26", &neso_condition_26, arg("p"),
        "Per-axis margin of condition (26), stricter reading (> 0 holds).");
  m.def("sig_pow", &sig_pow, arg("v"), arg("a"), "sig^a(v) = |v|^a sign(v), element-wise.");
  py::class_<Neso>(m, "Neso")
      .def(py::init<const NesoParams&>(), arg("p"))
      .def("reset", &Neso::reset, arg("z1"), arg("z2"))
      .def("update", &Neso::update, arg("h"), arg("A0"), arg("A1"), arg("x20"), arg("x21"),
           arg("Bu"), "Propagate over one period h [s]; A, x2 linear, Bu held.")
      .def_property_readonly("z1", &Neso::z1)
      .def_property_readonly("z2", &Neso::z2);

  // --- PPC (29)-(35)
  py::class_<PpcParams>(m, "PpcParams", "Prescribed performance; defaults are Table 1.")
      .def(py::init<>())
      .def_readwrite("chi0", &PpcParams::chi0)
      .def_readwrite("chiinf", &PpcParams::chiinf)
      .def_readwrite("gamma", &PpcParams::gamma, "[1/s]")
      .def_readwrite("dmin", &PpcParams::dmin)
      .def_readwrite("dmax", &PpcParams::dmax)
      .def_readwrite("clamp_margin", &PpcParams::clamp_margin);
  m.def("validate", py::overload_cast<const PpcParams&>(&validate), arg("p"));
  py::class_<PpcResult>(m, "PpcResult")
      .def_readonly("chi", &PpcResult::chi)
      .def_readonly("chi_dot", &PpcResult::chi_dot)
      .def_readonly("lambda_", &PpcResult::lambda)
      .def_readonly("eps", &PpcResult::eps)
      .def_readonly("e1", &PpcResult::e1)
      .def_readonly("r", &PpcResult::r)
      .def_readonly("violated", &PpcResult::violated, "bit i: axis i outside its bound");
  m.def("ppc_chi", &ppc_chi, arg("p"), arg("t"));
  m.def("ppc_chi_dot", &ppc_chi_dot, arg("p"), arg("t"));
  m.def("ppc_transform", &ppc_transform, arg("p"), arg("x1"), arg("t"));
  m.def("ppc_inverse", &ppc_inverse, arg("p"), arg("e1"), arg("t"));
}

}  // namespace

namespace {
// Offline runs allocate their columns afresh each run (a few MB at 10 Hz).
// glibc's defaults hand freed memory back to the kernel (trim above 128 kB,
// mmap for blocks above 128 kB-32 MB), so every run faulted its pages in
// again: 1.8x the bare loop's time at 10 Hz, against 1.1-1.3x with the
// memory kept (measured, docs/PERFORMANCE.md). Keep up to 128 MB of freed
// heap for reuse and serve blocks up to 32 MB from the heap: bounded, and
// the interpreter's own (pymalloc) arenas are unaffected.
void keep_freed_memory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 128 * 1024 * 1024);
#endif
}
}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "sc-rt control core (C++, Eigen), see docs/CORE.md";
  keep_freed_memory();
  m.attr("__version__") = SCRT_VERSION;
  m.attr("DEFAULT_LCM_URL") = SCRT_DEFAULT_LCM_URL;  // cpp/shell/defaults.hpp, the processes' default

  bind_math(m);
  bind_controllers(m);
  bind_pylaw(m);
  bind_orbit(m);  // before bind_plant: PlantParams' orbit
  bind_plant(m);
  bind_shell(m);
}
