// A Python law inside the core's Controller (docs/LAWS.md, "Python laws"):
// the trampoline of ControlLaw that calls a Python object, the law
// interface's types as Python sees them (LawModel, Reference, LawInput), and
// register_python_law, which puts a Python law in the law registry under its
// spec ("python:file.py:Class"). From then on a ControllerConfig naming that
// spec runs it wherever the core runs a law: Controller, the C++ closed
// loops (offline, with sensors), check_law. One policy for every law:
// validation, SAFE, re-engagement and containment are Controller::step's.
//
// The Python side (sc_rt.pylaw) hands a factory(model, rate, items) that
// returns an adapter with names (the telemetry names), used (the parameter
// keys the law read), reset(in), step(in) -> a flat array (kOutSize) and
// after(u_cmd, u_sat) (None when the law has none). The adapter formats the
// law's exceptions; this file turns them into std::runtime_error, which the
// Controller contains like a C++ law's. Every call takes the GIL (the C++
// loops run with it released).
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "sc_rt/controllers.hpp"
#include "sc_rt/law.hpp"
#include "sc_rt/law_registry.hpp"

namespace py = pybind11;
using namespace sc_rt;
using py::arg;

namespace {

// The adapter's step result: u_cmd 4, e1 3, e2 3, z1 3, z2 3, x2d 3, vs 4,
// rho_hat 1, then the named telemetry (kLawMaxTelemetry).
constexpr int kOutSize = 4 + 3 * 5 + 4 + 1 + kLawMaxTelemetry;

// Python is shutting down: _Py_IsFinalizing() until 3.12, removed in 3.13
// for the public Py_IsFinalizing() (added in 3.13).
bool py_finalizing() {
#if PY_VERSION_HEX >= 0x030D0000
  return Py_IsFinalizing() != 0;
#else
  return _Py_IsFinalizing() != 0;
#endif
}

// A Python object the C++ side may copy and drop without the GIL (LawEntry
// and its factory are copied by resolve_law, on any thread): the object is
// released under the GIL, once, by the last owner.
using Held = std::shared_ptr<py::object>;
Held hold(py::object o) {
  return Held(new py::object(std::move(o)), [](py::object* p) {
    if (!Py_IsInitialized() || py_finalizing()) {  // too late to touch Python: left to the OS
      p->release();
      delete p;
      return;
    }
    py::gil_scoped_acquire gil;
    delete p;
  });
}

// The message of a Python exception (the adapter has formatted it as
// "Type: what"), taken under the GIL.
std::string message(py::error_already_set& e) {
  std::string what;
  try {
    what = py::str(e.value());
  } catch (...) {
    what = e.what();
  }
  return what.empty() ? std::string(e.what()) : what;
}

class PythonLaw final : public ControlLaw {
 public:
  PythonLaw(py::object adapter, std::vector<std::string> names)
      : adapter_(hold(std::move(adapter))), names_(std::move(names)) {
    py::object after = adapter_->attr("after");
    has_after_ = !after.is_none();
  }
  void reset(const LawInput& in) override {
    py::gil_scoped_acquire gil;
    try {
      adapter_->attr("reset")(in);
    } catch (py::error_already_set& e) {
      throw std::runtime_error(message(e));
    }
  }
  void step(const LawInput& in, LawOutput& out) override {
    py::gil_scoped_acquire gil;
    try {
      const auto r = adapter_->attr("step")(in).cast<py::array_t<double, py::array::c_style | py::array::forcecast>>();
      if (r.ndim() != 1 || r.shape(0) != kOutSize)
        throw std::runtime_error("the Python law adapter returned a wrong-sized output");
      const double* p = r.data();
      for (int i = 0; i < 4; ++i) out.u_cmd(i) = *p++;
      for (Vec3* v : {&out.e1, &out.e2, &out.z1, &out.z2, &out.x2d})
        for (int i = 0; i < 3; ++i) (*v)(i) = *p++;
      for (int i = 0; i < 4; ++i) out.vs(i) = *p++;
      out.rho_hat = *p++;
      for (int i = 0; i < kLawMaxTelemetry; ++i) out.telemetry[static_cast<std::size_t>(i)] = *p++;
    } catch (py::error_already_set& e) {
      throw std::runtime_error(message(e));
    }
  }
  void after(const Vec4& u_cmd, const Vec4& u_sat) override {
    if (!has_after_) return;
    py::gil_scoped_acquire gil;
    try {
      adapter_->attr("after")(u_cmd, u_sat);
    } catch (py::error_already_set& e) {
      throw std::runtime_error(message(e));
    }
  }
  std::vector<std::string> telemetry_names() const override { return names_; }

 private:
  Held adapter_;
  std::vector<std::string> names_;
  bool has_after_ = false;
};

// The registry's factory of a Python law: the Python factory called with the
// law's model, rate and table; the keys the law read are marked read in the
// table (so that the Controller reports the others as unknown parameters).
LawFactory python_factory(Held factory) {
  return [factory](const LawSetup& s) -> std::unique_ptr<ControlLaw> {
    py::gil_scoped_acquire gil;
    py::object adapter;
    try {
      adapter = (*factory)(s.model, s.control_rate_hz, s.params.items());
      for (const std::string& k : adapter.attr("used").cast<std::vector<std::string>>()) (void)s.params.has(k);
      return std::make_unique<PythonLaw>(adapter, adapter.attr("names").cast<std::vector<std::string>>());
    } catch (py::error_already_set& e) {
      // sc_rt.pylaw.LawParamError carries the key: the core names it laws.NAME.key
      if (py::hasattr(e.value(), "key")) {
        const std::string key = py::str(e.value().attr("key"));
        throw LawParamError(key, key + ": " + std::string(py::str(e.value())));
      }
      throw std::runtime_error(message(e));
    }
  };
}

}  // namespace

void bind_pylaw(py::module_& m) {
  py::class_<LawModel>(m, "LawModel",
                       "What the controller knows of the spacecraft (sc_rt/law.hpp): a law's setup.model.")
      .def_readonly("J0", &LawModel::J0, "[kg m^2] nominal inertia")
      .def_readonly("J0_inv", &LawModel::J0_inv)
      .def_readonly("Cbar", &LawModel::Cbar, "wheel spin axes in B (columns)")
      .def_readonly("Jw", &LawModel::Jw, "[kg m^2] wheel spin inertias")
      .def_readonly("umin", &LawModel::umin, "lower command limits ([rad/s^2]; [N m] on torque-commanded wheels)")
      .def_readonly("umax", &LawModel::umax, "upper command limits (the same unit)")
      .def_readonly("wheel_torque_command", &LawModel::wheel_torque_command,
                    "the wheels take a motor torque [N m], not an acceleration")
      .def_readonly("wheel_speed_max", &LawModel::wheel_speed_max, "[rad/s] the wheels' speed limits (inf: none)")
      .def_readonly("w0", &LawModel::w0, "[rad/s] orbit rate")
      .def_readonly("B", &LawModel::B, "B = -J0^-1 Cbar Jw of (21)")
      .def_readonly("B_pinv", &LawModel::B_pinv, "B+")
      .def("wheels_for_torque", &LawModel::wheels_for_torque, arg("tau"),
           "wheel accelerations [rad/s^2] for the body torque tau [N m]: B+ J0^-1 tau")
      .def("wheel_command", &LawModel::wheel_command, arg("a"),
           "the wheel command for the wheel accelerations a, in the unit the wheels take");
  py::class_<Reference>(m, "Reference", "The guidance at this step.")
      .def_readonly("sigma_DN", &Reference::sigma_DN, "desired attitude")
      .def_readonly("omega_DN_D", &Reference::omega_DN_D, "[rad/s] desired rate in D")
      .def_readonly("omega_dot_DN_D", &Reference::omega_dot_DN_D, "[rad/s^2] its derivative in D");
  py::class_<LawInput>(m, "LawInput", "Everything a law gets at reset and at every step (sc_rt/law.hpp).")
      .def_readonly("t", &LawInput::t, "[s] time of the measurement")
      .def_readonly("t_engaged", &LawInput::t_engaged, "[s] since the engagement (reset)")
      .def_readonly("dt", &LawInput::dt, "[s] since the previous step (0 at reset, when time did not advance)")
      .def_readonly("m", &LawInput::m, "the measurement")
      .def_readonly("ref", &LawInput::ref, "the guidance")
      .def_readonly("e", &LawInput::e, "the tracking errors")
      .def_readonly("ppc", &LawInput::ppc, "the PPC transform of e.sigma_BD")
      .def_readonly("u_sat_prev", &LawInput::u_sat_prev, "the saturated command of the period that just ended");
  m.attr("PYTHON_LAW_OUT_SIZE") = kOutSize;
  m.def("clear_python_laws", &clear_python_laws,
        "Forget every Python law of the registry (sc_rt.pylaw calls it at exit, before the\n"
        "interpreter goes away).");
  m.def(
      "register_python_law",
      [](const std::string& spec, const std::string& name, const std::string& doc, py::object factory,
         const std::string& command) {
        if (command != "acceleration" && command != "torque")
          throw std::invalid_argument("law " + spec + ": command must be \"acceleration\" or \"torque\", got \"" +
                                      command + "\"");
        register_python_law(spec, name, doc, python_factory(hold(std::move(factory))),
                            command == "torque" ? LawCommand::Torque : LawCommand::Acceleration);
      },
      arg("spec"), arg("name"), arg("doc"), arg("factory"), arg("command") = "acceleration",
      "Put a Python law in the registry under spec (\"python:...\"; again: replaced). factory(model,\n"
      "rate, items) returns sc_rt.pylaw's adapter (sc_rt.pylaw.register calls this); command: what\n"
      "its u_cmd is, \"acceleration\" [rad/s^2] or \"torque\" [N m].");
}
