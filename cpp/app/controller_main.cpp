// sc-rt-controller: the fixed-rate LCM shell around the control core.
// This first slice parses its command line and validates a configuration
// file; the LCM loop (lockstep and real-time modes) arrives with the HIL
// issue.
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "translate.hpp"

namespace {
const char* kUsage =
    "usage: sc-rt-controller [--help] [--version] --config FILE\n"
    "\n"
    "The sc-rt real-time controller process.\n"
    "\n"
    "  --config FILE   controller_config_t, LCM-encoded (sc-rt writes it from a\n"
    "                  scenario file); validated and summarised\n"
    "  --version       print the version and exit\n"
    "  --help          this text\n";

int load_config(const std::string& path, sc_rt::ControllerConfig& cfg) {
  std::ifstream f(path, std::ios::binary);
  if (!f) {
    std::fprintf(stderr, "sc-rt-controller: cannot open config file %s\n", path.c_str());
    return 2;
  }
  std::vector<char> buf((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  try {
    cfg = sc_rt::config_from_bytes(buf.data(), static_cast<int>(buf.size()));
    sc_rt::Controller::create(cfg);  // validates every parameter
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sc-rt-controller: %s: %s\n", path.c_str(), e.what());
    return 2;
  }
  return 0;
}
}  // namespace

int main(int argc, char** argv) {
  std::string config_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (a == "--version") {
      std::printf("sc-rt-controller %s\n", SCRT_VERSION);
      return 0;
    } else if (a == "--config" && i + 1 < argc) {
      config_path = argv[++i];
    } else {
      std::fprintf(stderr, "sc-rt-controller: unknown argument '%s'\n%s", a.c_str(), kUsage);
      return 2;
    }
  }
  if (config_path.empty()) {
    std::fprintf(stderr, "sc-rt-controller: --config FILE is required\n%s", kUsage);
    return 2;
  }
  sc_rt::ControllerConfig cfg;
  if (int rc = load_config(config_path, cfg)) return rc;
  std::printf("sc-rt-controller: config ok: law %s, %.6g Hz\n", sc_rt::law_name(cfg.law),
              cfg.control_rate_hz);
  return 0;
}
