// The controller process's shell around the control core (sc_rt::Controller):
// the message handlers (states, and the sensor messages into the intake),
// the control step, publishing, the counters and the exit summary JSON.
// It owns no thread, clock loop or scheduler: controller_main.cpp parses the
// command line, sets up LCM and the scheduler and runs the loops that call
// the handlers and step(). Every received message is decoded by hand so that
// malformed input is counted by kind and never applied (docs/HIL.md, "Bad
// input").
#pragma once
#include <pthread.h>
#include <time.h>

#include <atomic>
#include <cstdint>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "defaults.hpp"
#include "histogram.hpp"
#include "hmac.hpp"
#include "input_gate.hpp"
#include "sensor_intake.hpp"
#include "translate.hpp"

namespace sc_rt_controller {

inline int64_t mono_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}
inline int64_t wall_us() {
  timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  return int64_t(ts.tv_sec) * 1000000LL + ts.tv_nsec / 1000;
}

// A mutex with priority inheritance (PTHREAD_PRIO_INHERIT): while the step
// thread (SCHED_FIFO 80) waits for it, the receive thread (70) that holds it
// runs at 80, so a third thread cannot preempt the holder and delay the step
// (no priority inversion). The receive thread holds it to hand samples to
// the estimator, which propagates them (a star fix re-propagates its ring).
class PiMutex {
 public:
  PiMutex() {
    pthread_mutexattr_t a;
    pthread_mutexattr_init(&a);
    pthread_mutexattr_setprotocol(&a, PTHREAD_PRIO_INHERIT);
    pthread_mutex_init(&m_, &a);
    pthread_mutexattr_destroy(&a);
  }
  ~PiMutex() { pthread_mutex_destroy(&m_); }
  PiMutex(const PiMutex&) = delete;
  PiMutex& operator=(const PiMutex&) = delete;
  void lock() { pthread_mutex_lock(&m_); }
  void unlock() { pthread_mutex_unlock(&m_); }
  bool try_lock() { return pthread_mutex_trylock(&m_) == 0; }

 private:
  pthread_mutex_t m_;
};

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
  bool event_trigger = true;  // --trigger event (default): step on each state's arrival (real time)
  bool null_law = false;       // --null-law: zero commands, no law step (the bench floor)
  int cpu = -1;                // --cpu N: pin to this CPU (< 0: no pinning)
};

class Shell {
 public:
  // stop: set on SIGINT/SIGTERM (the process's g_stop); done() reads it.
  Shell(const Options& o, lcm::LCM& lcm, const std::atomic<bool>& stop);

  void configure(const sc_rt::ControllerConfig& cfg, const sc_rt::NavSetup& nav);

  // --auth-key: every message carries HMAC-SHA256(key, channel || 0 || payload)
  void set_auth_key(const std::string& key) { auth_ = std::make_unique<sc_rt::HmacSha256>(key); }

  // Raw handler: decode by hand; the gate counts every kind of bad input and
  // decides; the newest accepted state goes to the mailbox.
  static void on_state(const lcm::ReceiveBuffer* rb, const std::string&, Shell* self) {
    self->handle_state(rb);
  }
  bool nav() const { return intake_ != nullptr; }
  //! the run has magnetic control: the shell takes SCRT_MAG and sends SCRT_ROD_CMD
  bool magnetic() const { return mag_; }

  // magnetometer_t (SCRT_MAG): verified, decoded by hand, the newest kept
  // under the lock; a step uses it when it is the field at its state's time
  // of its state's plant session (docs/PROTOCOL.md, "Magnetic control").
  static void on_mag(const lcm::ReceiveBuffer* rb, const std::string&, Shell* self) { self->handle_mag(rb); }
  void handle_mag(const lcm::ReceiveBuffer* rb);

  // A sensor message (gyro_t, star_tracker_t, tachometer_t): verified,
  // decoded by hand and handed to the intake, which decides (sensor_intake.hpp).
  // Instantiated in controller_shell.cpp for the three sensor types.
  template <class Msg>
  static void on_sensor(const lcm::ReceiveBuffer* rb, const std::string& channel, Shell* self);

  // Lockstep: called on the main thread and steps at once. Real time: called
  // on the receive thread, timestamps the arrival and only fills the mailbox.
  void handle_state(const lcm::ReceiveBuffer* rb);

  // One control step at monotonic time `now` (wake-up at `deadline` in real time).
  void step(int64_t now, int64_t deadline);

  bool done() const { return stop_ || (opt_.max_steps >= 0 && cnt_.steps >= opt_.max_steps); }
  // receipt time of the newest state and whether the last step used a new one
  int64_t state_rx_ns() const { return used_rx_ns_; }
  bool used_fresh() const { return used_fresh_; }
  int64_t period_ns() const { return period_ns_; }

  // The exit summary: one JSON object (scheduler: what setup_scheduler got).
  std::string summary_json(const std::string& scheduler) const;

 private:
  void offer(const sc_rt_lcm::gyro_t& m);
  void offer(const sc_rt_lcm::star_tracker_t& m);
  void offer(const sc_rt_lcm::tachometer_t& m);
  void publish_cmd(const sc_rt::Command& cmd, int64_t state_seq);
  // the rods' command of cmd (rod_cmd_t), with the seq of the wheel command that follows it
  void publish_rod(const sc_rt::Command& cmd, int64_t state_seq);
  // the field in B for state st [T]: the newest magnetometer_t at st's time and session, else NaN (counted)
  sc_rt::Vec3 field_for(const sc_rt_lcm::plant_state_t& st);
  void publish_status(const sc_rt::Command& cmd, int64_t state_seq, double late_us, double comp_us,
                      double age_us);
  void alloc_probe_step();  // sc-rt-controller-alloc only (alloc_probe.hpp)
  // Without a key exactly LCM's publish; with one, the message and its tag.
  template <class M>
  void send(const std::string& channel, const M& m);
  // A sensor message verified and decoded (no lock held), then offered under the lock.
  template <class Msg>
  void handle_sensor(const lcm::ReceiveBuffer* rb, const std::string& channel);

  const Options& opt_;
  // the channel names, built once (a prefixed name is past the small-string limit)
  const std::string ch_state_, ch_cmd_, ch_status_, ch_mag_, ch_rod_;
  lcm::LCM& lcm_;
  const std::atomic<bool>& stop_;
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
  bool mag_ = false;                             // magnetic control ([momentum] or [bdot])
  int n_rods_ = 0;                               // the rods the controller commands
  sc_rt_lcm::magnetometer_t mag_msg_{};          // the newest field message (under mu_)
  bool have_mag_ = false;                        // one arrived (under mu_)
  //! magnetic control's counts: field messages taken, rejected (no tag, do not decode, not an
  //! ideal field in B), steps that had the field of their state, steps without (rods at zero)
  std::atomic<int64_t> mag_received_{0}, mag_rejected_{0}, mag_used_{0}, mag_missing_{0};
  std::atomic<int64_t> auth_failed_{0};      // states whose tag did not verify
  std::vector<int64_t> plant_sessions_;     // plant sessions followed, in order (under mu_)
  std::vector<uint8_t> tx_;                 // a message being encoded (step thread; reserved once)
  mutable PiMutex mu_;  // guards the mailbox: state_, fresh_, the gate's state and the intake
  sc_rt::Command last_cmd_;
  int64_t cmd_seq_ = 0;
  Counters cnt_;
  //! whole-run statistics, fixed size (no cap, no allocation per step): wake lateness, compute, state age
  sc_rt::LogHistogram lat_, comp_, age_;
  long long alloc_count_ = 0;  // sc-rt-controller-alloc: allocations since the warm-up, at the last step
  int64_t alloc_steps_ = 0;    // and the steps they cover
};

}  // namespace sc_rt_controller
