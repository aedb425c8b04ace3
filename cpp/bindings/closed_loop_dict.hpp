// The field table (fields.hpp) for Python, and simulate_closed_loop's result
// as the dict the Python engines read, once for the plain and the sensed loop:
// both iterate the table, no column is named here.
#pragma once
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "sc_rt/closed_loop.hpp"
#include "sc_rt/fields.hpp"

namespace sc_rt_bind {
namespace py = pybind11;

using R = sc_rt::ClosedLoopResult;

// _core.FIELD_TABLE: the table of fields.hpp as a list of dicts, one per
// field in table order (sc_rt.results.record.fields reads it at import).
inline py::list field_table() {
  py::list out;
  for (const sc_rt::FieldSpec& s : sc_rt::kFields) {
    py::dict d;
    d["name"] = std::string(s.name);
    d["width"] = s.width;
    d["dtype"] = std::string(s.dtype);
    d["unit"] = std::string(s.unit);
    d["unit_rule"] = std::string(s.unit_rule);
    d["source"] = std::string(s.source);
    d["group"] = s.group == sc_rt::kNav ? "nav" : "loop";
    d["packed"] = s.packed;
    d["bus"] = s.bus;
    d["core"] = s.core;
    d["doc"] = std::string(s.doc);
    out.append(d);
  }
  return out;
}

// (name, width) of the table's fields of groups <= g, in table order (the
// result dict's columns: CLOSED_LOOP_FIELDS for kLoop).
inline py::list loop_columns(sc_rt::FieldGroup g) {
  py::list cols;
  for (const sc_rt::FieldSpec& s : sc_rt::kFields)
    if (s.group <= g) cols.append(py::make_tuple(std::string(s.name), s.width));
  return cols;
}

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

// rows, diverged, law_failures, telemetry_names, then every field of the
// result's groups in table order: (rows,) for a width of 1, else (rows,
// width); the table's dtype ("i8": int64).
inline py::dict closed_loop_dict(const R& r) {
  const py::ssize_t n = r.rows;
  py::dict d;
  d["rows"] = r.rows;
  d["diverged"] = r.diverged;
  d["law_failures"] = law_failures_dict(r.law_failures);
  d["telemetry_names"] = r.telemetry_names;
  for (int f = 0; f < sc_rt::kFieldCount; ++f) {
    const sc_rt::FieldSpec& s = sc_rt::kFields[f];
    if (s.group == sc_rt::kNav && !r.nav) continue;
    const py::ssize_t w = s.width;
    const double* src = r.col(static_cast<sc_rt::FieldId>(f));
    if (s.dtype == "i8") {
      py::array_t<std::int64_t> a = w == 1 ? py::array_t<std::int64_t>(n) : py::array_t<std::int64_t>({n, w});
      std::int64_t* o = a.mutable_data();
      for (py::ssize_t k = 0; k < n * w; ++k) o[k] = static_cast<std::int64_t>(src[k]);
      d[py::str(std::string(s.name))] = a;
    } else {
      py::array_t<double> a = w == 1 ? py::array_t<double>(n) : py::array_t<double>({n, w});
      std::copy(src, src + n * w, a.mutable_data());
      d[py::str(std::string(s.name))] = a;
    }
  }
  return d;
}

}  // namespace sc_rt_bind
