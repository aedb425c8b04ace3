// The controller's sensor intake (docs/PROTOCOL.md, "Sensors"): the sensor
// messages of the plant emulator (gyro_t, star_tracker_t, tachometer_t)
// into the core's Estimator, and a magnetometer's samples (magnetometer_t)
// into the field the magnetic part uses (field_B: the offline loop's
// Navigation::field_B, the latest sample rotated to B with the known
// mounting, held until the next; docs/MODEL.md section 17), with the shell's policy: which session's
// samples are used, what is rejected, when the estimate is ready. Policy
// only: no I/O, no clock, no LCM (the shell decodes; the core estimates).
//
// Sessions and time: the intake follows the plant session the input gate
// follows and applies a sample only once a state of that session at or
// after the sample's time is used (use(), called with each accepted state):
// the law's measurement at the state's time t then comes from exactly the
// samples taken up to t, as offline, even when the controller acts on a
// state a little older than the newest samples (real time: the samples of
// a period go out while the emulator integrates it, before its state).
// Samples wait in arrival order in a bounded queue: those of another session
// too, because a run's first samples go out just before its first state;
// when a state adopts their session the estimator restarts and they are
// applied in order, else they are dropped and counted as foreign.
//
// Start: a session whose samples begin at seq 0 starts the filter at t = 0
// from the configured initial estimate (the run's start: lockstep equals the
// offline loop). A controller that joins a run later (its samples start at
// seq > 0) has no estimate until the first star tracker attitude: it resets
// the filter there (ready() false until then; the shell commands SAFE).
#pragma once
#include <cstdint>
#include <limits>
#include <vector>

#include "sc_rt/mekf.hpp"

namespace sc_rt {

// A first-in first-out queue of fixed capacity whose storage is allocated
// once: pushing and popping samples never allocates (the controller's step
// path does not, issue #31).
template <class T>
class FixedFifo {
 public:
  explicit FixedFifo(std::size_t capacity) : buf_(capacity == 0 ? 1 : capacity) {}
  std::size_t size() const { return n_; }
  std::size_t capacity() const { return buf_.size(); }
  bool empty() const { return n_ == 0; }
  bool full() const { return n_ == buf_.size(); }
  const T& front() const { return buf_[head_]; }
  void pop_front() {
    head_ = (head_ + 1) % buf_.size();
    --n_;
  }
  void push_back(const T& v) {  // precondition: !full()
    buf_[(head_ + n_) % buf_.size()] = v;
    ++n_;
  }
  // Visits every item in order and keeps those for which keep(item) is
  // true, in order, in place.
  template <class F>
  void retain(F keep) {
    std::size_t w = 0;
    for (std::size_t i = 0; i < n_; ++i) {
      const T item = buf_[(head_ + i) % buf_.size()];
      if (keep(item)) buf_[(head_ + w++) % buf_.size()] = item;
    }
    n_ = w;
  }

 private:
  std::vector<T> buf_;
  std::size_t head_ = 0, n_ = 0;
};

enum class SensorKind { Gyro = 0, Star = 1, Tach = 2, Mag = 3 };

struct SensorCounts {
  int64_t used[4] = {0, 0, 0, 0};  //!< applied, per SensorKind
  int64_t malformed = 0;        //!< did not decode, trailing bytes, tag did not verify
  int64_t invalid = 0;          //!< non-finite values, |sigma| > 1, exposure after delivery, an unknown gyro output kind
  int64_t out_of_order = 0;     //!< seq not after the previous one of its kind (duplicates too)
  int64_t too_old = 0;          //!< older than the filter (a gyro sample) or its ring (an attitude)
  int64_t foreign = 0;          //!< of a session that was never followed
  int64_t before_fix = 0;       //!< a late joiner's gyro samples before its first attitude
  int64_t rejected() const { return malformed + invalid + out_of_order + too_old + foreign + before_fix; }
};

class SensorIntake {
 public:
  SensorIntake(const MekfParams& p, bool use_estimate, const Vec3& sigma0, std::size_t queue = 4096);

  void offer_gyro(int64_t session, int64_t seq, const GyroSample& g);
  void offer_star(int64_t session, int64_t seq, const StarSample& s);
  void offer_tach(int64_t session, int64_t seq, const TachSample& s);
  // A magnetometer's sample (sensor frame); only after mount_magnetometer.
  void offer_mag(int64_t session, int64_t seq, const MagSample& s);
  // The magnetometer's known mounting R_SB [-] (body to sensor): its samples
  // are used from now on (NavSetup::mag_enabled).
  void mount_magnetometer(const Mat3& R_SB) {
    R_SB_ = R_SB;
    mag_mounted_ = true;
  }
  bool magnetometer_mounted() const { return mag_mounted_; }
  //! [T] the field in B from the followed session's latest magnetometer
  //! sample applied (magnetometer_field_B), NaN before the first
  const Vec3& field_B() const { return field_B_; }
  void malformed() { ++c_.malformed; }
  // A state of `session` at time t is used now: follow that session (a new
  // one restarts the estimator) and apply its waiting samples up to t.
  void use(int64_t session, double t);
  // The estimator has an attitude: the followed session's samples began at
  // seq 0, or (a late joiner) its first star tracker attitude arrived.
  bool ready() const { return ready_; }
  bool use_estimate() const { return est_.use_estimate(); }
  Measurement measure(const Measurement& truth, NavTelemetry* tel) { return est_.measure(truth, tel); }
  const SensorCounts& counts() const { return c_; }
  const Estimator& estimator() const { return est_; }
  int64_t session() const { return session_; }
  // Samples waiting: of unfollowed sessions (counted as foreign when
  // dropped) or later than the newest state used.
  std::size_t queued() const { return queue_.size(); }

 private:
  struct Item {
    SensorKind kind;
    int64_t session, seq;
    GyroSample g;
    StarSample s;
    TachSample c;
    MagSample b;
  };
  void offer(const Item& it);
  void apply(const Item& it);
  static double time_of(const Item& it);
  Estimator est_;
  Vec3 sigma0_;
  bool following_ = false, started_ = false, ready_ = false;
  int64_t session_ = -1;
  int64_t last_seq_[4] = {-1, -1, -1, -1};
  Mat3 R_SB_ = Mat3::Identity();  // [-] the magnetometer's mounting, body to sensor
  bool mag_mounted_ = false;
  Vec3 field_B_ = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());  // [T]
  double horizon_ = -1.0;      // the time of the newest state used
  FixedFifo<Item> queue_;      // samples not yet applied, in arrival order
  SensorCounts c_;
};

}  // namespace sc_rt
