// The controller's shell (controller_shell.hpp): the message handlers, the
// sensor intake hookup, the control step, publishing and the exit summary.
#include "controller_shell.hpp"

#include "alloc_probe.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

namespace sc_rt_controller {

namespace {

// The exit summary's figures of a whole-run histogram.
struct Stats {
  double p50 = 0, p99 = 0, max = 0;
  std::uint64_t n = 0;
};
Stats stats(const sc_rt::LogHistogram& h) {
  return Stats{h.quantile(0.5), h.quantile(0.99), h.max(), h.count()};
}

}  // namespace

Shell::Shell(const Options& o, lcm::LCM& lcm, const std::atomic<bool>& stop)
    : opt_(o),
      ch_state_(o.prefix + "SCRT_STATE"),
      ch_cmd_(o.prefix + "SCRT_CMD"),
      ch_status_(o.prefix + "SCRT_CTRL_STATUS"),
      ch_mag_(o.prefix + "SCRT_MAG"),
      ch_rod_(o.prefix + "SCRT_ROD_CMD"),
      lcm_(lcm),
      stop_(stop) {
  // every message the step encodes fits: send() never grows it on the step path
  tx_.reserve(std::size_t(1) << 16);
}

void Shell::configure(const sc_rt::ControllerConfig& cfg, const sc_rt::NavSetup& nav) {
  ctl_ = sc_rt::Controller::create(cfg);
  // the guidance's period table now, not in a step: a late joiner's or a
  // re-engagement's first step costs only its bounded evaluation (docs/CORE.md)
  ctl_->prepare();
  // [sensors]: the estimator runs here on the emulator's sensor messages (sensor_intake.hpp)
  if (nav.enabled) intake_ = std::make_unique<sc_rt::SensorIntake>(nav.mekf, nav.use_estimate, nav.sigma0);
  // [sensors.magnetometer]: the magnetic part's field from its samples (SCRT_MAG, handle_mag)
  if (nav.enabled && nav.mag_enabled) intake_->mount_magnetometer(nav.mag_R_SB);
  mag_ = cfg.magnetic.active();
  n_rods_ = mag_ ? static_cast<int>(cfg.magnetic.rods.G_B.cols()) : 0;
  period_ns_ = int64_t(std::llround(1e9 / cfg.control_rate_hz));
  stale_ns_ = int64_t(cfg.safety.stale_periods * double(period_ns_));
  // a silent plant is replaced after max(stale time, 2 s)
  gate_ = std::make_unique<sc_rt::InputGate>(sc_rt::InputGate::session_timeout_for(stale_ns_));
  std::random_device rd;
  session_ = (int64_t(rd()) << 31 ^ int64_t(rd()) ^ mono_ns()) & 0x7fffffffffffffffLL;
}

template <class Msg>
void Shell::on_sensor(const lcm::ReceiveBuffer* rb, const std::string& channel, Shell* self) {
  self->handle_sensor<Msg>(rb, channel);
}

template <class Msg>
void Shell::handle_sensor(const lcm::ReceiveBuffer* rb, const std::string& channel) {
  // the tag and the decoding before the lock: the step thread never waits on them
  int size = int(rb->data_size);
  bool ok = true;
  if (auth_) {
    ok = auth_->verify(channel, rb->data, rb->data_size);
    if (!ok) ++auth_failed_;
    size -= int(sc_rt::HmacSha256::kSize);
  }
  Msg msg;
  if (ok) {
    const int n = msg.decode(rb->data, 0, size);
    ok = n >= 0 && n == size;
  }
  std::lock_guard<PiMutex> lock(mu_);
  if (ok) {
    offer(msg);
  } else {
    intake_->malformed();
  }
}
template void Shell::on_sensor<sc_rt_lcm::gyro_t>(const lcm::ReceiveBuffer*, const std::string&, Shell*);
template void Shell::on_sensor<sc_rt_lcm::star_tracker_t>(const lcm::ReceiveBuffer*, const std::string&, Shell*);
template void Shell::on_sensor<sc_rt_lcm::tachometer_t>(const lcm::ReceiveBuffer*, const std::string&, Shell*);

void Shell::offer(const sc_rt_lcm::gyro_t& m) { intake_->offer_gyro(m.session, m.seq, sc_rt::gyro_from_lcm(m)); }
void Shell::offer(const sc_rt_lcm::star_tracker_t& m) {
  intake_->offer_star(m.session, m.seq, sc_rt::star_from_lcm(m));
}
void Shell::offer(const sc_rt_lcm::tachometer_t& m) {
  intake_->offer_tach(m.session, m.seq, sc_rt::tach_from_lcm(m));
}

void Shell::handle_mag(const lcm::ReceiveBuffer* rb) {
  int size = int(rb->data_size);
  if (auth_) {
    if (!auth_->verify(ch_mag_, rb->data, rb->data_size)) {
      ++auth_failed_;
      return;
    }
    size -= int(sc_rt::HmacSha256::kSize);
  }
  sc_rt_lcm::magnetometer_t msg;
  const int n = msg.decode(rb->data, 0, size);
  const bool sensed = intake_ && intake_->magnetometer_mounted();
  sc_rt::Vec3 B;
  sc_rt::MagSample sample;
  // with a magnetometer, its samples (into the intake, as the other sensors'); else the ideal field
  if (n < 0 || n != size || !(sensed ? sc_rt::mag_sample_from_lcm(msg, sample) : sc_rt::field_from_lcm(msg, B))) {
    ++mag_rejected_;
    return;
  }
  ++mag_received_;
  std::lock_guard<PiMutex> lock(mu_);
  if (sensed) {
    intake_->offer_mag(msg.session, msg.seq, sample);
    return;
  }
  mag_msg_ = msg;
  have_mag_ = true;
}

sc_rt::Vec3 Shell::field_for(const sc_rt_lcm::plant_state_t& st) {
  sc_rt::Vec3 B = sc_rt::Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  {
    std::lock_guard<PiMutex> lock(mu_);
    // with a magnetometer: its latest sample up to the state's time, rotated to B (the
    // offline loop's Navigation::field_B; the intake applied the samples up to st.t)
    if (intake_ && intake_->magnetometer_mounted() && intake_->session() == st.session) B = intake_->field_B();
    // else the field at the state's instant, from its plant (published just before the state)
    else if (have_mag_ && mag_msg_.session == st.session && mag_msg_.t == st.t) sc_rt::field_from_lcm(mag_msg_, B);
  }
  if (B.allFinite())
    ++mag_used_;
  else
    ++mag_missing_;  // no field known: the magnetic part commands the rods zero (magnetic_control.hpp)
  return B;
}

void Shell::handle_state(const lcm::ReceiveBuffer* rb) {
  const int64_t now = mono_ns();
  int size = int(rb->data_size);
  if (auth_) {  // the trailer first: what does not verify is never decoded
    if (!auth_->verify(ch_state_, rb->data, rb->data_size)) {
      ++auth_failed_;
      return;
    }
    size -= int(sc_rt::HmacSha256::kSize);
  }
  // decoded before the lock: the step thread never waits on a decode or a tag
  sc_rt_lcm::plant_state_t msg;
  const int n = msg.decode(rb->data, 0, size);
  std::unique_lock<PiMutex> lock(mu_);
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
    // lockstep: the plant re-sent a state it had no answer to: answer again.
    // Not under mu_: publish_status takes it for the estimator's counts
    // (holding it here deadlocked a [sensors] run at the first re-sent state).
    lock.unlock();
    if (!opt_.realtime && have_cmd_) {
      if (mag_) publish_rod(last_cmd_, msg.seq);
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

void Shell::step(int64_t now, int64_t deadline) {
  const int64_t t_start = mono_ns();
  // take the newest state from the mailbox
  sc_rt_lcm::plant_state_t st;
  bool have, fresh, nav_ready = true;
  int64_t rx;
  sc_rt::Measurement m_nav;
  {
    std::lock_guard<PiMutex> lock(mu_);
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
    } else if (mag_) {
      cmd = ctl_->step(m, field_for(st));  // the magnetic part beside the law (docs/MODEL.md section 17)
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
  if (mag_) publish_rod(cmd, used_seq);  // just before the wheel command it goes with
  publish_cmd(cmd, used_seq);
  const double comp_us = double(t_end - t_start) / 1e3;
  const double late_us = double(now - deadline) / 1e3;
  ++cnt_.steps;
  // a miss: the command left after the next deadline
  if (opt_.realtime && mono_ns() > deadline + period_ns_) ++cnt_.deadline_misses;
  lat_.add(late_us);  // every step of the run, whatever its length (no cap)
  comp_.add(comp_us);
  age_.add(age_us);
  publish_status(cmd, used_seq, late_us, comp_us, age_us);
  if (alloc_probe_linked()) alloc_probe_step();
}

void Shell::alloc_probe_step() {
  const int64_t k = cnt_.steps;
  if (k == kAllocWarmupSteps) sc_rt_alloc_arm();
  if (k > kAllocWarmupSteps) {  // everything since the warm-up step, this step's publishing included
    alloc_count_ = sc_rt_alloc_count();
    alloc_steps_ = k - kAllocWarmupSteps;
  }
}

template <class M>
void Shell::send(const std::string& channel, const M& m) {
  // Encoded into the reserved buffer and published raw: LCM's typed
  // publish allocates a buffer per message.
  const int n = m.getEncodedSize();
  tx_.resize(std::size_t(n) + (auth_ ? sc_rt::HmacSha256::kSize : 0));
  m.encode(tx_.data(), 0, n);
  if (auth_) {
    const sc_rt::Sha256::Digest tag = auth_->message_tag(channel, tx_.data(), std::size_t(n));
    std::copy(tag.begin(), tag.end(), tx_.begin() + n);
  }
  lcm_.publish(channel, tx_.data(), unsigned(tx_.size()));
}

void Shell::publish_cmd(const sc_rt::Command& cmd, int64_t state_seq) {
  sc_rt_lcm::wheel_cmd_t m{};
  m.utime = wall_us();
  m.seq = cmd_seq_;
  m.session = session_;
  m.state_seq = state_seq;
  sc_rt::fill_wheel_cmd(cmd, m);
  send(ch_cmd_, m);
  ++cmd_seq_;
}

void Shell::publish_rod(const sc_rt::Command& cmd, int64_t state_seq) {
  sc_rt_lcm::rod_cmd_t m{};
  m.utime = wall_us();
  m.seq = cmd_seq_;  // the wheel command's, published next
  m.session = session_;
  m.state_seq = state_seq;
  sc_rt::fill_rod_cmd(cmd, n_rods_, m);
  send(ch_rod_, m);
}

void Shell::publish_status(const sc_rt::Command& cmd, int64_t state_seq, double late_us, double comp_us,
                           double age_us) {
  sc_rt_lcm::controller_status_t s{};
  s.utime = wall_us();
  s.cmd_seq = cmd_seq_ - 1;
  s.session = session_;
  s.state_seq = state_seq;
  sc_rt::fill_status(cmd, ctl_->law_code(), static_cast<int>(ctl_->telemetry_names().size()), s);
  s.wake_lateness_us = late_us;
  s.compute_us = comp_us;
  s.state_age_us = age_us;
  s.steps = cnt_.steps;
  s.deadline_misses = cnt_.deadline_misses;
  s.stale_states = cnt_.stale_steps;
  s.rejected = gate_->counts().rejected();
  if (intake_) {
    std::lock_guard<PiMutex> lock(mu_);
    sc_rt::fill_nav_status(tel_, s);
    const sc_rt::SensorCounts& c = intake_->counts();
    s.gyro_used = c.used[0];
    s.star_used = c.used[1];
    s.tach_used = c.used[2];
    s.sensor_rejected = c.rejected();
  }
  send(ch_status_, s);
}

std::string Shell::summary_json(const std::string& scheduler) const {
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
      "\"out_of_order\": %lld, \"invalid_state\": %lld, \"foreign_session\": %lld, \"seq_jump\": %lld}, "
      "\"sessions_adopted\": %lld}",
      opt_.realtime ? "realtime" : "lockstep", 1e9 / double(period_ns_), ctl_->law_name().c_str(),
      (long long)cnt_.steps, (long long)cnt_.deadline_misses, scheduler.c_str(), l.p50, l.p99,
      l.max, c.p50, c.p99, c.max, a.p50, a.p99, a.max, (long long)g.received,
      (long long)cnt_.stale_steps, (long long)cnt_.safe_steps, (long long)g.malformed,
      (long long)g.trailing_bytes, (long long)g.duplicate, (long long)g.out_of_order,
      (long long)g.invalid_state, (long long)g.foreign_session, (long long)g.seq_jump,
      (long long)g.sessions_adopted);
  std::string js(buf);
  js.pop_back();  // the closing brace: then the authentication and the plant sessions
  js += std::string(", \"trigger\": \"") + (opt_.event_trigger ? "event" : "timer") +
        "\", \"null_law\": " + (opt_.null_law ? "true" : "false");
  {  // the law's contained failures: counts per call and the newest, named (issue #25)
    const sc_rt::LawFailures& f = ctl_->law_failures();
    char fb[256];
    std::snprintf(fb, sizeof fb, ", \"law_failures\": {\"reset\": %lld, \"step\": %lld, \"after\": %lld, ",
                  f.reset, f.step, f.after);
    js += fb;
    if (f.total() > 0) {
      std::snprintf(fb, sizeof fb, "\"last\": {\"call\": \"%s\", \"t\": %.9g, \"what\": \"", f.last_call, f.last_t);
      js += fb;
      for (const char ch : f.last_what) {  // JSON string escaping
        if (ch == '"' || ch == '\\') {
          js += '\\';
          js += ch;
        } else if (static_cast<unsigned char>(ch) < 0x20) {
          char u[8];
          std::snprintf(u, sizeof u, "\\u%04x", static_cast<unsigned char>(ch));
          js += u;
        } else {
          js += ch;
        }
      }
      js += "\"}}";
    } else {
      js += "\"last\": null}";
    }
  }
  {  // time jumps the core refused (SAFE, FLAG_TIME_JUMP; docs/CORE.md, "The time contract")
    const sc_rt::ControllerCounts& k = ctl_->counts();
    char tb[128];
    std::snprintf(tb, sizeof tb, ", \"time_jumps\": {\"ahead\": %lld, \"back\": %lld}", k.jumps_ahead,
                  k.steps_back);
    js += tb;
  }
  if (intake_) {
    std::lock_guard<PiMutex> lock(mu_);
    const sc_rt::SensorCounts& c = intake_->counts();
    char nb[512];
    std::snprintf(nb, sizeof nb,
                  ", \"nav\": {\"measurement\": \"%s\", \"gyro_used\": %lld, \"star_used\": %lld, "
                  "\"tach_used\": %lld, \"mag_used\": %lld, \"star_dropped\": %ld, \"rejected\": {\"malformed\": %lld, "
                  "\"invalid\": %lld, \"out_of_order\": %lld, \"too_old\": %lld, \"foreign\": %lld, "
                  "\"before_fix\": %lld}}",
                  intake_->use_estimate() ? "estimate" : "truth", (long long)c.used[0], (long long)c.used[1],
                  (long long)c.used[2], (long long)c.used[3], intake_->estimator().dropped(), (long long)c.malformed,
                  (long long)c.invalid, (long long)c.out_of_order, (long long)c.too_old, (long long)c.foreign,
                  (long long)c.before_fix);
    js += nb;
  }
  if (mag_) {
    char mb[256];
    std::snprintf(mb, sizeof mb,
                  ", \"magnetic\": {\"rods\": %d, \"field_received\": %lld, \"field_rejected\": %lld, "
                  "\"field_used\": %lld, \"field_missing\": %lld}",
                  n_rods_, (long long)mag_received_.load(), (long long)mag_rejected_.load(),
                  (long long)mag_used_.load(), (long long)mag_missing_.load());
    js += mb;
  }
  if (alloc_probe_linked()) {
    char ab[160];
    std::snprintf(ab, sizeof ab, ", \"allocations\": {\"after_step\": %lld, \"steps\": %lld, \"count\": %lld}",
                  (long long)kAllocWarmupSteps, (long long)alloc_steps_, alloc_count_);
    js += ab;
  }
  js += ", \"auth\": " + std::string(auth_ ? "true" : "false") +
        ", \"auth_failed\": " + std::to_string(auth_failed_.load()) + ", \"plant_sessions\": [";
  {
    std::lock_guard<PiMutex> lock(mu_);
    for (std::size_t i = 0; i < plant_sessions_.size(); ++i)
      js += (i ? ", " : "") + std::to_string(plant_sessions_[i]);
  }
  return js + "]}";
}

}  // namespace sc_rt_controller
