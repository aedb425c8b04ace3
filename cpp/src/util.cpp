#include "sc_rt/util.hpp"

#include <cstdio>
#include <stdexcept>

namespace sc_rt {

std::string format_double(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

void throw_if_errors(const std::string& what, const std::vector<std::string>& errors) {
  if (errors.empty()) return;
  std::string msg = "invalid " + what + ": ";
  for (std::size_t i = 0; i < errors.size(); ++i) msg += (i ? "; " : "") + errors[i];
  throw std::invalid_argument(msg);
}

}  // namespace sc_rt
