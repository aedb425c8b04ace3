// Small helpers for error messages (not on any hot path).
#pragma once
#include <string>
#include <vector>

#include <Eigen/Core>

namespace sc_rt {

std::string format_double(double x);

template <typename Derived>
std::string format_matrix(const Eigen::MatrixBase<Derived>& m) {
  std::string s = "[";
  for (int i = 0; i < m.rows(); ++i) {
    if (m.cols() > 1) s += (i ? ", [" : "[");
    for (int j = 0; j < m.cols(); ++j) {
      s += format_double(m(i, j));
      if (j + 1 < m.cols()) s += ", ";
    }
    if (m.cols() > 1) s += "]";
    else if (i + 1 < m.rows()) s += ", ";
  }
  return s + "]";
}

// Throws std::invalid_argument("<what>: e1; e2; ...") when errors is not empty.
void throw_if_errors(const std::string& what, const std::vector<std::string>& errors);

}  // namespace sc_rt
