// sc-rt-controller: the fixed-rate LCM shell around the control core.
//
// All math is in the core (sc_rt::Controller); this file owns the command
// line, LCM, the clock, the scheduler and the two loops. Two modes:
//   lockstep : event-driven, one command per state message, answering its seq;
//   realtime : wakes on absolute deadlines (clock_nanosleep, CLOCK_MONOTONIC,
//              TIMER_ABSTIME), uses the newest state, publishes.
// The Shell (controller_shell.hpp/.cpp) handles the messages, steps, publishes
// and keeps the counters and the exit summary; every received message is
// decoded by hand so that malformed input is counted by kind and never
// applied (docs/HIL.md, "Bad input").
#include <dirent.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/syscall.h>
#include <unistd.h>
#include <time.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <thread>
#include <string>
#include <vector>

#include "controller_shell.hpp"
#include "hmac.hpp"
#include "defaults.hpp"
#include "phase_lock.hpp"
#include "translate.hpp"

namespace {

using sc_rt_controller::mono_ns;
using sc_rt_controller::Options;
using sc_rt_controller::Shell;

const char* kUsage =
    "usage: sc-rt-controller (--config FILE | --config-channel) [options]\n"
    "\n"
    "The sc-rt controller process: runs a control law of the C++ core against\n"
    "plant states on LCM and publishes wheel commands and its status.\n"
    "\n"
    "  --config FILE          controller_config_t, LCM-encoded (sc-rt writes it\n"
    "                         from a scenario: sc-rt config SCENARIO --out FILE)\n"
    "  --config-channel       wait for the configuration on <prefix>SCRT_CONFIG\n"
    "  --check                validate the configuration, print it, exit\n"
    "  --law-plugin PATH      run the law of this plugin library instead of the\n"
    "                         configuration's (docs/LAWS.md; the config's law\n"
    "                         table is handed to it when it is that law's, else\n"
    "                         it runs its defaults)\n"
    "  --mode MODE            lockstep (default) or realtime\n"
    "  --lcm-url URL          default " SCRT_DEFAULT_LCM_URL "\n"
    "  --prefix P             channel name prefix (default none)\n"
    "  --realtime-priority    ask for SCHED_FIFO and mlockall (falls back with a\n"
    "                         warning when not permitted)\n"
    "  --phase-offset US      real time: lock the timer's phase to the state\n"
    "                         arrivals and wake at least US microseconds after\n"
    "                         one (the guard widens with the plant's jitter;\n"
    "                         default 50; negative: free-running)\n"
    "  --trigger T            real time: event (default: step on each state's\n"
    "                         arrival, as software triggered by a sensor's\n"
    "                         data-ready) or timer (the own clock above)\n"
    "  --null-law             the bench's floor (sc-rt floor): answer every state\n"
    "                         with a zero command, no law step (same messages)\n"
    "  --cpu N                pin the process to CPU N (sched_setaffinity)\n"
    "  --max-steps N          stop after N control steps (default: run until\n"
    "                         SIGINT/SIGTERM)\n"
    "  --summary FILE         write the exit summary as JSON to FILE\n"
    "  --auth-key FILE        authenticate every message with HMAC-SHA256 under\n"
    "                         the key in FILE (a 32-byte trailer; states that do\n"
    "                         not verify are dropped and counted, auth_failed)\n"
    "  --version              print the version and exit\n"
    "  --help                 this text\n";

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

bool read_file(const std::string& path, std::vector<char>& buf) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return false;
  buf.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  return true;
}

struct ConfigWait {
  bool got = false;
  std::vector<char> bytes;
  const sc_rt::HmacSha256* auth = nullptr;  // --auth-key: only a configuration whose tag verifies
  int64_t auth_failed = 0;
  static void on(const lcm::ReceiveBuffer* rb, const std::string& channel, ConfigWait* self) {
    const char* p = static_cast<const char*>(rb->data);
    std::size_t n = rb->data_size;
    if (self->auth) {
      if (!self->auth->verify(channel, rb->data, n)) {
        ++self->auth_failed;
        return;
      }
      n -= sc_rt::HmacSha256::kSize;
    }
    self->bytes.assign(p, p + n);
    self->got = true;
  }
};

// Real-time priorities: the step thread above the receive thread, so a burst
// of input (or a hostile flood) never delays the step of a deadline.
constexpr int kStepPriority = 80;
constexpr int kReceivePriority = 70;

// The calling (receive) thread below the step thread, when the process runs SCHED_FIFO.
void lower_receive_priority() {
  int policy = 0;
  sched_param sp{};
  if (pthread_getschedparam(pthread_self(), &policy, &sp) != 0 || policy != SCHED_FIFO) return;
  sp.sched_priority = kReceivePriority;
  pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
}

// Every thread of the process but the calling one (LCM's own receive thread,
// started by the first subscribe): fn(tid) for each; how many it was true for.
template <class Fn>
int for_other_threads(Fn fn) {
  const pid_t self = pid_t(syscall(SYS_gettid));
  int n = 0;
  DIR* d = opendir("/proc/self/task");
  if (d == nullptr) return 0;
  while (const dirent* e = readdir(d)) {
    const pid_t tid = pid_t(std::atoi(e->d_name));
    if (tid > 0 && tid != self && fn(tid)) ++n;
  }
  closedir(d);
  return n;
}

// The scheduler of the step thread (the calling one: call it after the
// subscriptions, so that LCM's receive thread exists and is put below it).
std::string setup_scheduler(bool want_rt, int cpu) {
  // Timer slack 1 ns: wake-ups as close to the deadline as the kernel can.
  prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);
  std::string pin;
  if (cpu >= 0) {  // every thread: LCM's receive thread exists, a later one inherits it
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    if (sched_setaffinity(0, sizeof set, &set) == 0) {
      pin = ", CPU " + std::to_string(cpu);
      for_other_threads([&](pid_t tid) { return sched_setaffinity(tid, sizeof set, &set) == 0; });
    } else {
      std::fprintf(stderr, "sc-rt-controller: warning: cannot pin to CPU %d (%s)\n", cpu, std::strerror(errno));
    }
  }
  if (!want_rt) return "SCHED_OTHER" + pin;
  std::string s;
  sched_param sp{};
  sp.sched_priority = kStepPriority;
  if (sched_setscheduler(0, SCHED_FIFO, &sp) == 0) {
    s = "SCHED_FIFO " + std::to_string(kStepPriority);
    sched_param low{};
    low.sched_priority = kReceivePriority;  // the receive path below the step
    if (for_other_threads([&](pid_t tid) { return sched_setscheduler(tid, SCHED_FIFO, &low) == 0; }) > 0) {
      s += " (receive " + std::to_string(kReceivePriority) + ")";
    }
  } else {
    std::fprintf(stderr, "sc-rt-controller: warning: SCHED_FIFO not permitted (%s): running SCHED_OTHER\n",
                 std::strerror(errno));
    s = "SCHED_OTHER (SCHED_FIFO denied)";
  }
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
    s += " + mlockall";
  } else {
    std::fprintf(stderr, "sc-rt-controller: warning: mlockall not permitted (%s)\n", std::strerror(errno));
  }
  return s + pin;
}

// The configuration with --law-plugin applied, its law checked (constructed
// and probed once at rest): throws with the plugin's problem. The table the
// configuration carries is its law's: a plugin that replaces another law runs
// its own defaults.
sc_rt::ControllerConfig load_config(const std::vector<char>& bytes, const Options& o) {
  sc_rt::ControllerConfig cfg = sc_rt::config_from_bytes(bytes.data(), int(bytes.size()));
  if (!o.law_plugin.empty()) {
    const std::string spec = sc_rt::kPluginPrefix + o.law_plugin;
    if (cfg.law != spec && cfg.law != sc_rt::resolve_law(spec).name) cfg.law_params.clear();
    cfg.law = spec;
  }
  const auto problems = sc_rt::check_law(cfg);
  if (!problems.empty()) throw std::invalid_argument(problems.front().second);
  return cfg;
}

}  // namespace

namespace {

constexpr int kGoOn = -1;  // parse_args: no exit code, run

// The command line into ``o``: kGoOn to run, else the exit code (help,
// version: 0; a bad option: 2, one line).
int parse_args(int argc, char** argv, Options& o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto need = [&](const char* what) -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "sc-rt-controller: %s needs a value\n", what);
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (a == "--version") {
      std::printf("sc-rt-controller %s\n", SCRT_VERSION);
      return 0;
    } else if (a == "--config") {
      o.config_path = need("--config");
    } else if (a == "--config-channel") {
      o.config_channel = true;
    } else if (a == "--law-plugin") {
      o.law_plugin = need("--law-plugin");
    } else if (a == "--check") {
      o.check = true;
    } else if (a == "--mode") {
      const std::string m = need("--mode");
      if (m != "lockstep" && m != "realtime") {
        std::fprintf(stderr, "sc-rt-controller: --mode must be lockstep or realtime, got '%s'\n", m.c_str());
        return 2;
      }
      o.realtime = (m == "realtime");
    } else if (a == "--lcm-url") {
      o.url = need("--lcm-url");
    } else if (a == "--prefix") {
      o.prefix = need("--prefix");
    } else if (a == "--realtime-priority") {
      o.rt_priority = true;
    } else if (a == "--phase-offset") {
      o.phase_offset_us = std::atof(need("--phase-offset").c_str());
    } else if (a == "--trigger") {
      const std::string t = need("--trigger");
      if (t != "timer" && t != "event") {
        std::fprintf(stderr, "sc-rt-controller: --trigger must be timer or event, got '%s'\n", t.c_str());
        return 2;
      }
      o.event_trigger = (t == "event");
    } else if (a == "--null-law") {
      o.null_law = true;
    } else if (a == "--cpu") {
      o.cpu = std::atoi(need("--cpu").c_str());
    } else if (a == "--max-steps") {
      o.max_steps = std::atoll(need("--max-steps").c_str());
    } else if (a == "--summary") {
      o.summary_path = need("--summary");
    } else if (a == "--auth-key") {
      const std::string path = need("--auth-key");
      std::vector<char> k;
      if (!read_file(path, k) || k.empty()) {
        std::fprintf(stderr, "sc-rt-controller: --auth-key %s: cannot read the key (or it is empty)\n",
                     path.c_str());
        return 2;
      }
      o.auth_key.assign(k.begin(), k.end());
    } else {
      std::fprintf(stderr, "sc-rt-controller: unknown argument '%s'\n%s", a.c_str(), kUsage);
      return 2;
    }
  }
  if (o.config_path.empty() == !o.config_channel) {
    std::fprintf(stderr, "sc-rt-controller: give exactly one of --config FILE and --config-channel\n%s", kUsage);
    return 2;
  }
  return kGoOn;
}

// --check: the configuration file decoded and the law constructed, nothing run.
int check_only(const std::vector<char>& cfg_bytes, const Options& o) {
  try {
    const sc_rt::ControllerConfig cfg = load_config(cfg_bytes, o);
    std::printf("sc-rt-controller: config ok: law %s, %.6g Hz\n",
                sc_rt::Controller::create(cfg)->law_name().c_str(), cfg.control_rate_hz);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sc-rt-controller: %s: %s\n", o.config_path.c_str(), e.what());
    return 2;
  }
}

// --config-channel: the configuration from SCRT_CONFIG (false: stopped first).
bool wait_config(lcm::LCM& lcm, const Options& o, std::vector<char>& cfg_bytes) {
  ConfigWait w;
  std::unique_ptr<sc_rt::HmacSha256> config_auth;
  if (!o.auth_key.empty()) {
    config_auth = std::make_unique<sc_rt::HmacSha256>(o.auth_key);
    w.auth = config_auth.get();
  }
  auto* sub = lcm.subscribeFunction(o.prefix + "SCRT_CONFIG", &ConfigWait::on, &w);
  std::fprintf(stderr, "sc-rt-controller: waiting for %sSCRT_CONFIG\n", o.prefix.c_str());
  while (!w.got && !g_stop) lcm.handleTimeout(100);
  lcm.unsubscribe(sub);
  if (!w.got) return false;
  cfg_bytes = w.bytes;
  return true;
}

// The shell's subscriptions: states, the sensors of a [sensors] scenario, the
// field of a run with magnetic control.
void subscribe(lcm::LCM& lcm, const Options& o, Shell& shell) {
  // LCM drops messages beyond a subscription's queue capacity (30 by
  // default) without a word: under a burst of hostile traffic that would lose
  // genuine states. Hold many; every one is counted or used.
  lcm.subscribeFunction(o.prefix + "SCRT_STATE", &Shell::on_state, &shell)->setQueueCapacity(100000);
  if (shell.nav()) {  // the sensors of a [sensors] scenario (docs/PROTOCOL.md)
    lcm.subscribeFunction(o.prefix + "SCRT_GYRO", &Shell::on_sensor<sc_rt_lcm::gyro_t>, &shell)
        ->setQueueCapacity(100000);
    lcm.subscribeFunction(o.prefix + "SCRT_STAR", &Shell::on_sensor<sc_rt_lcm::star_tracker_t>, &shell)
        ->setQueueCapacity(100000);
    lcm.subscribeFunction(o.prefix + "SCRT_TACH", &Shell::on_sensor<sc_rt_lcm::tachometer_t>, &shell)
        ->setQueueCapacity(100000);
  }
  if (shell.magnetic())  // the field of a run with magnetic control (docs/PROTOCOL.md, "Magnetic control")
    lcm.subscribeFunction(o.prefix + "SCRT_MAG", &Shell::on_mag, &shell)->setQueueCapacity(100000);
}

// The run: one step per state on its arrival (lockstep, event trigger), or
// a receive thread and phase-locked deadlines (timer trigger).
void run_loops(lcm::LCM& lcm, const Options& o, Shell& shell) {
  if (!o.realtime || o.event_trigger) {  // one step per state, on its arrival
    while (!shell.done()) lcm.handleTimeout(100);
  } else {
    // A receive thread timestamps every state as it arrives (the newest wins);
    // this thread only wakes on its absolute deadlines and steps.
    std::atomic<bool> rx_stop{false};
    std::thread rx([&] {
      lower_receive_priority();
      while (!rx_stop && !g_stop) lcm.handleTimeout(20);
    });
    // The deadlines: phase-locked to the state arrivals with an adaptive
    // guard (--phase-offset; phase_lock.hpp).
    sc_rt::PhaseLock sched_lock(shell.period_ns(), o.phase_offset_us, mono_ns());
    while (!shell.done()) {
      const int64_t deadline = sched_lock.deadline();
      timespec ts{time_t(deadline / 1000000000LL), long(deadline % 1000000000LL)};
      while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR && !g_stop) {
      }
      if (g_stop) break;
      const int64_t now = mono_ns();
      shell.step(now, deadline);
      sched_lock.advance(shell.used_fresh(), shell.state_rx_ns(), mono_ns());
    }
    rx_stop = true;
    rx.join();
  }
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (const int rc = parse_args(argc, argv, o); rc != kGoOn) return rc;
  std::vector<char> cfg_bytes;
  if (!o.config_path.empty() && !read_file(o.config_path, cfg_bytes)) {
    std::fprintf(stderr, "sc-rt-controller: cannot read config file %s\n", o.config_path.c_str());
    return 2;
  }
  if (o.check) return check_only(cfg_bytes, o);

  lcm::LCM lcm(o.url);
  if (!lcm.good()) {
    std::fprintf(stderr,
                 "sc-rt-controller: cannot start LCM on %s (no multicast route? as root: "
                 "ip route add 224.0.0.0/4 dev lo)\n", o.url.c_str());
    return 3;
  }
  struct sigaction sa{};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);

  if (o.config_channel && !wait_config(lcm, o, cfg_bytes)) return 0;
  Shell shell(o, lcm, g_stop);
  if (!o.auth_key.empty()) shell.set_auth_key(o.auth_key);
  try {
    shell.configure(load_config(cfg_bytes, o), sc_rt::nav_from_bytes(cfg_bytes.data(), int(cfg_bytes.size())));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sc-rt-controller: bad configuration: %s\n", e.what());
    return 2;
  }
  subscribe(lcm, o, shell);  // first: LCM's receive thread exists when the step thread's priority is set
  const std::string sched = setup_scheduler(o.rt_priority, o.cpu);
  std::fprintf(stderr, "sc-rt-controller: %s mode on %s, %s%s%s\n", o.realtime ? "realtime" : "lockstep",
               o.url.c_str(), sched.c_str(), o.realtime && o.event_trigger ? ", event-triggered" : "",
               o.null_law ? ", null law" : "");

  run_loops(lcm, o, shell);
  const std::string js = shell.summary_json(sched);
  std::printf("%s\n", js.c_str());
  if (!o.summary_path.empty()) {
    std::ofstream f(o.summary_path);
    f << js << "\n";
  }
  return 0;
}
