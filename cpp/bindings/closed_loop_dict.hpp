// The columns of simulate_closed_loop's result and their conversion to the
// dict the Python engines read, once for the plain and the sensed loop.
#pragma once
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstddef>
#include <iterator>
#include <vector>

#include "sc_rt/closed_loop.hpp"

namespace sc_rt_bind {
namespace py = pybind11;

struct LoopColumn {
  const char* name;
  py::ssize_t width;
  std::vector<double> sc_rt::ClosedLoopResult::*v;
};
using R = sc_rt::ClosedLoopResult;
// The plain loop's columns (CLOSED_LOOP_FIELDS, then "flags" and "ctrl_mode",
// int), then the navigation's (the sensed loop only).
inline const LoopColumn kLoopColumns[] = {
    {"t", 1, &R::t},
    {"sigma_BN", 3, &R::sigma_BN},
    {"omega_BN_B", 3, &R::omega_BN_B},
    {"sigma_DN", 3, &R::sigma_DN},
    {"sigma_BD", 3, &R::sigma_BD},
    {"omega_BD_B", 3, &R::omega_BD_B},
    {"z1", 3, &R::z1},
    {"z2", 3, &R::z2},
    {"delta2", 3, &R::delta2},
    {"chi", 3, &R::chi},
    {"lam", 3, &R::lam},
    {"e1", 3, &R::e1},
    {"e2", 3, &R::e2},
    {"wheel_speed", 4, &R::wheel_speed},
    {"u_cmd", 4, &R::u_cmd},
    {"u_sat", 4, &R::u_sat},
    {"wheel_accel", 4, &R::wheel_accel},
    {"vs", 4, &R::vs},
    {"x2d", 3, &R::x2d},
    {"rho_hat", 1, &R::rho_hat},
    {"telemetry", sc_rt::kLawMaxTelemetry, &R::telemetry},
    // navigation (simulate_closed_loop_sensed)
    {"sigma_BN_est", 3, &R::sigma_BN_est},
    {"bias_est", 3, &R::bias_est},
    {"bias_true", 3, &R::bias_true},
    {"P_diag", 6, &R::P_diag},
    {"att_est_error", 3, &R::att_est_error},
    {"innovation", 3, &R::innovation},
    {"nis", 1, &R::nis},
};
constexpr std::size_t kPlainLoopColumns = 21;  // the columns before the navigation's
constexpr std::size_t kAllLoopColumns = std::size(kLoopColumns);

// A law's contained failures as a dict: reset, step, after (counts) and last
// (None, or {call, t, what}).
inline py::dict law_failures_dict(const sc_rt::LawFailures& f) {
  py::dict d;
  d["reset"] = f.reset;
  d["step"] = f.step;
  d["after"] = f.after;
  if (f.total() > 0) {
    py::dict last;
    last["call"] = std::string(f.last_call);
    last["t"] = f.last_t;
    last["what"] = f.last_what;
    d["last"] = last;
  } else {
    d["last"] = py::none();
  }
  return d;
}

// rows, diverged, law_failures, the first ncols columns, then flags and ctrl_mode.
inline py::dict closed_loop_dict(const R& r, std::size_t ncols) {
  const py::ssize_t n = r.rows;
  auto arr = [n](const std::vector<double>& v, py::ssize_t w) {
    py::array_t<double> a = w == 1 ? py::array_t<double>(n) : py::array_t<double>({n, w});
    std::copy(v.begin(), v.begin() + n * w, a.mutable_data());
    return a;
  };
  py::dict d;
  d["rows"] = r.rows;
  d["diverged"] = r.diverged;
  d["law_failures"] = law_failures_dict(r.law_failures);
  d["telemetry_names"] = r.telemetry_names;
  for (std::size_t i = 0; i < ncols; ++i) d[kLoopColumns[i].name] = arr(r.*(kLoopColumns[i].v), kLoopColumns[i].width);
  py::array_t<int> flags(n), mode(n);
  std::copy(r.flags.begin(), r.flags.begin() + n, flags.mutable_data());
  std::copy(r.ctrl_mode.begin(), r.ctrl_mode.begin() + n, mode.mutable_data());
  d["flags"] = flags;
  d["ctrl_mode"] = mode;
  return d;
}

}  // namespace sc_rt_bind
