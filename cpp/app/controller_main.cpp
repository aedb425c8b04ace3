// sc-rt-controller: the fixed-rate LCM shell around the control core.
//
// All math is in the core (sc_rt::Controller); this file owns the command
// line, LCM, the clock, the scheduler and the counters. Two modes:
//   lockstep : event-driven, one command per state message, answering its seq;
//   realtime : wakes on absolute deadlines (clock_nanosleep, CLOCK_MONOTONIC,
//              TIMER_ABSTIME), uses the newest state, publishes.
// Every received message is decoded by hand so that malformed input is
// counted by kind and never applied (docs/HIL.md, "Bad input").
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <time.h>
#include <poll.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <mutex>
#include <random>
#include <thread>
#include <string>
#include <vector>

#include "hmac.hpp"
#include "defaults.hpp"
#include "input_gate.hpp"
#include "phase_lock.hpp"
#include "sensor_intake.hpp"
#include "translate.hpp"

namespace {

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
    "                         parameters are handed to it)\n"
    "  --mode MODE            lockstep (default) or realtime\n"
    "  --lcm-url URL          default " SCRT_DEFAULT_LCM_URL "\n"
    "  --prefix P             channel name prefix (default none)\n"
    "  --realtime-priority    ask for SCHED_FIFO and mlockall (falls back with a\n"
    "                         warning when not permitted)\n"
    "  --phase-offset US      real time: lock the timer's phase to the state\n"
    "                         arrivals and wake at least US microseconds after\n"
    "                         one (the guard widens with the plant's jitter;\n"
    "                         default 50; negative: free-running)\n"
    "  --trigger T            real time: timer (default: the own clock above) or\n"
    "                         event (step on each state's arrival, as software\n"
    "                         triggered by a sensor's data-ready)\n"
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

int64_t mono_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}
int64_t wall_us() {
  timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  return int64_t(ts.tv_sec) * 1000000LL + ts.tv_nsec / 1000;
}

// Percentiles of a sample (copied: called once at exit / per report).
struct Stats {
  double p50 = 0, p99 = 0, max = 0;
  std::size_t n = 0;
};
Stats stats(std::vector<double> v) {
  Stats s;
  s.n = v.size();
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  auto q = [&](double p) { return v[std::min(v.size() - 1, std::size_t(p * (v.size() - 1) + 0.5))]; };
  s.p50 = q(0.5);
  s.p99 = q(0.99);
  s.max = v.back();
  return s;
}

// Atomic: the real-time mode receives on its own thread. The input counters
// (received, rejected by kind, sessions adopted) are the gate's (input_gate.hpp).
struct Counters {
  using C = std::atomic<int64_t>;
  C stale_steps{0};     // steps without a fresh state
  C safe_steps{0};      // steps that commanded zero in SAFE mode
  C deadline_misses{0};
  C steps{0};
};

struct Options {
  std::string config_path;
  bool config_channel = false;
  bool check = false;
  bool realtime = false;
  bool rt_priority = false;
  std::string url = SCRT_DEFAULT_LCM_URL;
  std::string prefix;
  int64_t max_steps = -1;
  std::string summary_path;
  std::string law_plugin;  // --law-plugin: overrides the config's law
  std::string auth_key;    // --auth-key: the key's bytes (empty: no authentication)
  // real time: lock the wake-up phase to the arrival of states (PLL), this
  // many microseconds after a state arrives (< 0: free-running clock)
  double phase_offset_us = 50.0;
  bool event_trigger = false;  // --trigger event: step on each state's arrival (real time)
  bool null_law = false;       // --null-law: zero commands, no law step (the bench floor)
  int cpu = -1;                // --cpu N: pin to this CPU (< 0: no pinning)
};

class Shell {
 public:
  Shell(const Options& o, lcm::LCM& lcm) : opt_(o), lcm_(lcm) {
    lat_.reserve(1 << 20);
    comp_.reserve(1 << 20);
    age_.reserve(1 << 20);
  }

  void configure(const sc_rt::ControllerConfig& cfg, const sc_rt::NavSetup& nav) {
    ctl_ = sc_rt::Controller::create(cfg);
    // [sensors]: the estimator runs here on the emulator's sensor messages (sensor_intake.hpp)
    if (nav.enabled) intake_ = std::make_unique<sc_rt::SensorIntake>(nav.mekf, nav.use_estimate, nav.sigma0);
    period_ns_ = int64_t(std::llround(1e9 / cfg.control_rate_hz));
    stale_ns_ = int64_t(cfg.safety.stale_periods * double(period_ns_));
    // a silent plant is replaced after max(stale time, 2 s)
    gate_ = std::make_unique<sc_rt::InputGate>(sc_rt::InputGate::session_timeout_for(stale_ns_));
    std::random_device rd;
    session_ = (int64_t(rd()) << 31 ^ int64_t(rd()) ^ mono_ns()) & 0x7fffffffffffffffLL;
  }

  // --auth-key: every message carries HMAC-SHA256(key, channel || 0 || payload)
  void set_auth_key(const std::string& key) { auth_ = std::make_unique<sc_rt::HmacSha256>(key); }

  // Raw handler: decode by hand; the gate counts every kind of bad input and
  // decides; the newest accepted state goes to the mailbox.
  static void on_state(const lcm::ReceiveBuffer* rb, const std::string&, Shell* self) {
    self->handle_state(rb);
  }
  bool nav() const { return intake_ != nullptr; }

  // A sensor message (gyro_t, star_tracker_t, tachometer_t): verified,
  // decoded by hand and handed to the intake, which decides (sensor_intake.hpp).
  template <class Msg>
  static void on_sensor(const lcm::ReceiveBuffer* rb, const std::string& channel, Shell* self) {
    std::lock_guard<std::mutex> lock(self->mu_);
    int size = int(rb->data_size);
    if (self->auth_) {
      if (!self->auth_->verify(channel, rb->data, rb->data_size)) {
        ++self->auth_failed_;
        self->intake_->malformed();
        return;
      }
      size -= int(sc_rt::HmacSha256::kSize);
    }
    Msg msg;
    const int n = msg.decode(rb->data, 0, size);
    if (n < 0 || n != size) {
      self->intake_->malformed();
      return;
    }
    self->offer(msg);
  }
  void offer(const sc_rt_lcm::gyro_t& m) { intake_->offer_gyro(m.session, m.seq, sc_rt::gyro_from_lcm(m)); }
  void offer(const sc_rt_lcm::star_tracker_t& m) {
    intake_->offer_star(m.session, m.seq, sc_rt::star_from_lcm(m));
  }
  void offer(const sc_rt_lcm::tachometer_t& m) {
    intake_->offer_tach(m.session, m.seq, sc_rt::tach_from_lcm(m));
  }

  // Lockstep: called on the main thread and steps at once. Real time: called
  // on the receive thread, timestamps the arrival and only fills the mailbox.
  void handle_state(const lcm::ReceiveBuffer* rb) {
    const int64_t now = mono_ns();
    std::unique_lock<std::mutex> lock(mu_);
    int size = int(rb->data_size);
    if (auth_) {  // the trailer first: what does not verify is never decoded
      if (!auth_->verify(opt_.prefix + "SCRT_STATE", rb->data, rb->data_size)) {
        ++auth_failed_;
        return;
      }
      size -= int(sc_rt::HmacSha256::kSize);
    }
    sc_rt_lcm::plant_state_t msg;
    const int n = msg.decode(rb->data, 0, size);
    if (n < 0) {
      gate_->malformed();
      return;
    }
    if (n != size) {
      gate_->trailing_bytes();
      return;
    }
    // A decodable state with non-finite or out-of-range values of our
    // session is counted and applied: the core answers it with a SAFE zero
    // command (and re-engages at the next valid state), so lockstep and
    // offline runs stay identical. A new session is adopted only at a valid one.
    const bool valid =
        sc_rt::measurement_valid(sc_rt::measurement_from_lcm(msg), ctl_->config().safety);
    const sc_rt::GateVerdict v = gate_->offer(now, msg.session, msg.seq, valid);
    if (v == sc_rt::GateVerdict::Duplicate) {
      // lockstep: the plant re-sent a state it had no answer to: answer again
      if (!opt_.realtime && have_cmd_) {
        publish_cmd(last_cmd_, msg.seq);
        publish_status(last_cmd_, msg.seq, 0.0, 0.0, 0.0);
      }
      return;
    }
    if (v != sc_rt::GateVerdict::Accept && v != sc_rt::GateVerdict::Adopt) return;
    if (v == sc_rt::GateVerdict::Adopt) reengage_ = true;  // a restarted plant: start the law afresh
    // the plant sessions followed, in order (the bench checks they are its own)
    if ((plant_sessions_.empty() || plant_sessions_.back() != msg.session) && plant_sessions_.size() < 16)
      plant_sessions_.push_back(msg.session);
    if (intake_) intake_->use(msg.session, msg.t);  // its sensor samples up to msg.t feed the estimator
    state_ = msg;
    fresh_ = true;
    lock.unlock();
    if (!opt_.realtime || opt_.event_trigger) step(now, now);  // event-triggered: at once
  }

  // One control step at monotonic time `now` (wake-up at `deadline` in real time).
  void step(int64_t now, int64_t deadline) {
    const int64_t t_start = mono_ns();
    // take the newest state from the mailbox
    sc_rt_lcm::plant_state_t st;
    bool have, fresh, nav_ready = true;
    int64_t rx;
    sc_rt::Measurement m_nav;
    {
      std::lock_guard<std::mutex> lock(mu_);
      st = state_;
      have = gate_->have_state();
      fresh = fresh_;
      rx = gate_->last_rx_ns();
      fresh_ = false;
      // the law's measurement: the truth of the state, or the estimate at its time
      if (intake_ && have && fresh) {
        nav_ready = !intake_->use_estimate() || intake_->ready();
        if (nav_ready) m_nav = intake_->measure(sc_rt::measurement_from_lcm(st), &tel_);
      }
    }
    sc_rt::Command cmd;
    const bool stale = !have || (opt_.realtime && t_start - rx > stale_ns_);
    if (stale) {
      cmd = ctl_->safe_command(have ? st.t : 0.0, sc_rt::FLAG_STALE_STATE);
      ++cnt_.stale_steps;
      ++cnt_.safe_steps;
    } else if (!fresh) {
      // real time, no new state since the last step but not yet stale: hold
      // the last command (zero-order hold), count it
      ++cnt_.stale_steps;
      cmd = last_cmd_;
      cmd.flags |= sc_rt::FLAG_STALE_STATE;
    } else if (!nav_ready) {
      // estimate mode, no attitude yet (a controller that joined a run): SAFE until the first fix
      cmd = ctl_->safe_command(st.t, sc_rt::FLAG_NAV_DEGRADED);
      ++cnt_.safe_steps;
      reengage_ = true;  // the law starts afresh from the first estimate
    } else {
      const sc_rt::Measurement m = intake_ ? m_nav : sc_rt::measurement_from_lcm(st);
      if (reengage_) {  // a new plant session: start the law afresh
        reengage_ = false;
        ctl_->reset(m);
      }
      if (opt_.null_law) {  // the floor: the same messages, zero compute
        cmd = sc_rt::Command{};
        cmd.t = st.t;
        cmd.mode = sc_rt::MODE_NORMAL;
      } else {
        cmd = ctl_->step(m);
      }
      if (cmd.mode == sc_rt::MODE_SAFE) ++cnt_.safe_steps;
    }
    used_fresh_ = fresh && !stale;
    used_rx_ns_ = rx;
    // age of the state at use: its arrival to the start of this step
    const double age_us = have ? double(t_start - rx) / 1e3 : 0.0;
    const int64_t t_end = mono_ns();  // compute: the core's step, no I/O
    last_cmd_ = cmd;
    have_cmd_ = true;
    const int64_t used_seq = have ? st.seq : -1;
    publish_cmd(cmd, used_seq);
    const double comp_us = double(t_end - t_start) / 1e3;
    const double late_us = double(now - deadline) / 1e3;
    ++cnt_.steps;
    // a miss: the command left after the next deadline
    if (opt_.realtime && mono_ns() > deadline + period_ns_) ++cnt_.deadline_misses;
    if (lat_.size() < lat_.capacity()) {
      lat_.push_back(late_us);
      comp_.push_back(comp_us);
      age_.push_back(age_us);
    }
    publish_status(cmd, used_seq, late_us, comp_us, age_us);
  }

  void publish_cmd(const sc_rt::Command& cmd, int64_t state_seq) {
    sc_rt_lcm::wheel_cmd_t m{};
    m.utime = wall_us();
    m.seq = cmd_seq_;
    m.session = session_;
    m.state_seq = state_seq;
    sc_rt::fill_wheel_cmd(cmd, m);
    send(opt_.prefix + "SCRT_CMD", m);
    ++cmd_seq_;
  }

  void publish_status(const sc_rt::Command& cmd, int64_t state_seq, double late_us, double comp_us,
                      double age_us) {
    sc_rt_lcm::controller_status_t s{};
    s.utime = wall_us();
    s.cmd_seq = cmd_seq_ - 1;
    s.session = session_;
    s.state_seq = state_seq;
    sc_rt::fill_status(cmd, ctl_->law_code(), s);
    s.wake_lateness_us = late_us;
    s.compute_us = comp_us;
    s.state_age_us = age_us;
    s.steps = cnt_.steps;
    s.deadline_misses = cnt_.deadline_misses;
    s.stale_states = cnt_.stale_steps;
    s.rejected = gate_->counts().rejected();
    if (intake_) {
      std::lock_guard<std::mutex> lock(mu_);
      sc_rt::fill_nav_status(tel_, s);
      const sc_rt::SensorCounts& c = intake_->counts();
      s.gyro_used = c.used[0];
      s.star_used = c.used[1];
      s.tach_used = c.used[2];
      s.sensor_rejected = c.rejected();
    }
    send(opt_.prefix + "SCRT_CTRL_STATUS", s);
  }

  // Without a key exactly LCM's publish; with one, the message and its tag.
  template <class M>
  void send(const std::string& channel, const M& m) {
    if (!auth_) {
      lcm_.publish(channel, &m);
      return;
    }
    const int n = m.getEncodedSize();
    tx_.resize(std::size_t(n) + sc_rt::HmacSha256::kSize);
    m.encode(tx_.data(), 0, n);
    const sc_rt::Sha256::Digest tag = auth_->message_tag(channel, tx_.data(), std::size_t(n));
    std::copy(tag.begin(), tag.end(), tx_.begin() + n);
    lcm_.publish(channel, tx_.data(), unsigned(tx_.size()));
  }

  bool done() const { return g_stop || (opt_.max_steps >= 0 && cnt_.steps >= opt_.max_steps); }
  // receipt time of the newest state and whether the last step used a new one
  int64_t state_rx_ns() const { return used_rx_ns_; }
  bool used_fresh() const { return used_fresh_; }
  int64_t period_ns() const { return period_ns_; }

  std::string summary_json(const std::string& scheduler) const {
    const Stats l = stats(lat_), c = stats(comp_), a = stats(age_);
    const sc_rt::GateCounts g = gate_->counts();
    char buf[2048];
    std::snprintf(
        buf, sizeof buf,
        "{\"mode\": \"%s\", \"control_rate_hz\": %.9g, \"law\": \"%s\", \"steps\": %lld, "
        "\"deadline_misses\": %lld, \"scheduler\": \"%s\", "
        "\"wake_lateness_us\": {\"p50\": %.3f, \"p99\": %.3f, \"max\": %.3f}, "
        "\"compute_us\": {\"p50\": %.3f, \"p99\": %.3f, \"max\": %.3f}, "
        "\"state_age_us\": {\"p50\": %.3f, \"p99\": %.3f, \"max\": %.3f}, "
        "\"received\": %lld, \"stale_states\": %lld, \"safe_steps\": %lld, "
        "\"rejected\": {\"malformed\": %lld, \"trailing_bytes\": %lld, \"duplicate\": %lld, "
        "\"out_of_order\": %lld, \"invalid_state\": %lld, \"foreign_session\": %lld}, "
        "\"sessions_adopted\": %lld}",
        opt_.realtime ? "realtime" : "lockstep", 1e9 / double(period_ns_), ctl_->law_name().c_str(),
        (long long)cnt_.steps, (long long)cnt_.deadline_misses, scheduler.c_str(), l.p50, l.p99,
        l.max, c.p50, c.p99, c.max, a.p50, a.p99, a.max, (long long)g.received,
        (long long)cnt_.stale_steps, (long long)cnt_.safe_steps, (long long)g.malformed,
        (long long)g.trailing_bytes, (long long)g.duplicate, (long long)g.out_of_order,
        (long long)g.invalid_state, (long long)g.foreign_session,
        (long long)g.sessions_adopted);
    std::string js(buf);
    js.pop_back();  // the closing brace: then the authentication and the plant sessions
    js += std::string(", \"trigger\": \"") + (opt_.event_trigger ? "event" : "timer") +
          "\", \"null_law\": " + (opt_.null_law ? "true" : "false");
    if (intake_) {
      std::lock_guard<std::mutex> lock(mu_);
      const sc_rt::SensorCounts& c = intake_->counts();
      char nb[512];
      std::snprintf(nb, sizeof nb,
                    ", \"nav\": {\"measurement\": \"%s\", \"gyro_used\": %lld, \"star_used\": %lld, "
                    "\"tach_used\": %lld, \"star_dropped\": %ld, \"rejected\": {\"malformed\": %lld, "
                    "\"invalid\": %lld, \"out_of_order\": %lld, \"too_old\": %lld, \"foreign\": %lld, "
                    "\"before_fix\": %lld}}",
                    intake_->use_estimate() ? "estimate" : "truth", (long long)c.used[0], (long long)c.used[1],
                    (long long)c.used[2], intake_->estimator().filter().dropped(), (long long)c.malformed,
                    (long long)c.invalid, (long long)c.out_of_order, (long long)c.too_old, (long long)c.foreign,
                    (long long)c.before_fix);
      js += nb;
    }
    js += ", \"auth\": " + std::string(auth_ ? "true" : "false") +
          ", \"auth_failed\": " + std::to_string(auth_failed_.load()) + ", \"plant_sessions\": [";
    {
      std::lock_guard<std::mutex> lock(mu_);
      for (std::size_t i = 0; i < plant_sessions_.size(); ++i)
        js += (i ? ", " : "") + std::to_string(plant_sessions_[i]);
    }
    return js + "]}";
  }

 private:
  const Options& opt_;
  lcm::LCM& lcm_;
  std::unique_ptr<sc_rt::Controller> ctl_;
  int64_t period_ns_ = 100000000;
  int64_t stale_ns_ = 500000000;
  sc_rt_lcm::plant_state_t state_{};
  bool fresh_ = false, have_cmd_ = false, used_fresh_ = false;
  int64_t used_rx_ns_ = 0;
  std::atomic<bool> reengage_{false};
  int64_t session_ = 0;
  std::unique_ptr<sc_rt::InputGate> gate_;  // session, seq and arrival of the newest state
  std::unique_ptr<sc_rt::HmacSha256> auth_;  // --auth-key
  std::unique_ptr<sc_rt::SensorIntake> intake_;  // [sensors]: the estimator (under mu_)
  sc_rt::NavTelemetry tel_;                      // the estimator's telemetry of the last step (under mu_)
  std::atomic<int64_t> auth_failed_{0};      // states whose tag did not verify
  std::vector<int64_t> plant_sessions_;     // plant sessions followed, in order (under mu_)
  std::vector<uint8_t> tx_;                 // an authenticated message being sent (main thread)
  mutable std::mutex mu_;  // guards the mailbox: state_, fresh_ and the gate's state
  sc_rt::Command last_cmd_;
  int64_t cmd_seq_ = 0;
  Counters cnt_;
  std::vector<double> lat_, comp_, age_;
};

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

std::string setup_scheduler(bool want_rt, int cpu) {
  // Timer slack 1 ns: wake-ups as close to the deadline as the kernel can.
  prctl(PR_SET_TIMERSLACK, 1UL, 0, 0, 0);
  std::string pin;
  if (cpu >= 0) {  // before any thread starts: the receive thread inherits it
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    if (sched_setaffinity(0, sizeof set, &set) == 0) {
      pin = ", CPU " + std::to_string(cpu);
    } else {
      std::fprintf(stderr, "sc-rt-controller: warning: cannot pin to CPU %d (%s)\n", cpu, std::strerror(errno));
    }
  }
  if (!want_rt) return "SCHED_OTHER" + pin;
  std::string s;
  sched_param sp{};
  sp.sched_priority = 80;
  if (sched_setscheduler(0, SCHED_FIFO, &sp) == 0) {
    s = "SCHED_FIFO 80";
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
// and probed once at rest): throws with the plugin's problem.
sc_rt::ControllerConfig load_config(const std::vector<char>& bytes, const Options& o) {
  sc_rt::ControllerConfig cfg = sc_rt::config_from_bytes(bytes.data(), int(bytes.size()));
  if (!o.law_plugin.empty()) cfg.law = sc_rt::kPluginPrefix + o.law_plugin;
  const auto problems = sc_rt::check_law(cfg);
  if (!problems.empty()) throw std::invalid_argument(problems.front().second);
  return cfg;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
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

  std::vector<char> cfg_bytes;
  if (!o.config_path.empty() && !read_file(o.config_path, cfg_bytes)) {
    std::fprintf(stderr, "sc-rt-controller: cannot read config file %s\n", o.config_path.c_str());
    return 2;
  }
  if (o.check) {
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

  if (o.config_channel) {
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
    if (!w.got) return 0;
    cfg_bytes = w.bytes;
  }
  Shell shell(o, lcm);
  if (!o.auth_key.empty()) shell.set_auth_key(o.auth_key);
  try {
    shell.configure(load_config(cfg_bytes, o), sc_rt::nav_from_bytes(cfg_bytes.data(), int(cfg_bytes.size())));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sc-rt-controller: bad configuration: %s\n", e.what());
    return 2;
  }
  const std::string sched = setup_scheduler(o.rt_priority, o.cpu);
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
  std::fprintf(stderr, "sc-rt-controller: %s mode on %s, %s%s%s\n", o.realtime ? "realtime" : "lockstep",
               o.url.c_str(), sched.c_str(), o.realtime && o.event_trigger ? ", event-triggered" : "",
               o.null_law ? ", null law" : "");

  if (!o.realtime || o.event_trigger) {  // one step per state, on its arrival
    while (!shell.done()) lcm.handleTimeout(100);
  } else {
    // A receive thread timestamps every state as it arrives (the newest wins);
    // this thread only wakes on its absolute deadlines and steps.
    std::atomic<bool> rx_stop{false};
    std::thread rx([&] {
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
  const std::string js = shell.summary_json(sched);
  std::printf("%s\n", js.c_str());
  if (!o.summary_path.empty()) {
    std::ofstream f(o.summary_path);
    f << js << "\n";
  }
  return 0;
}
