// Attitude estimation (docs/MODEL.md section 10): a multiplicative extended
// Kalman filter, 6 error states (attitude error dtheta [rad] in the body,
// gyro bias error db [rad/s]), gyro-propagated, star-tracker-updated, and
// Navigation, which runs the sensors and the filter and builds the
// Measurement the control law gets (from the truth or from the estimate).
//
// Error: R(sigma_true) = exp(-dtheta^) R(sigma_est); b_true = b_est + db.
// Propagation over dt with w = omega_m - b_est, omega_m the mean of the two
// gyro samples that bound the interval (the held newest sample beyond it,
// for the prediction to a control instant), or, from an integrating gyro,
// the mean rate it delivered for the interval (sensors.hpp, kGyroMeanRate):
//   sigma <- exp(-(w dt)^) sigma (exact for a constant rate)
//   Phi = [[exp(-(w dt)^), -dt I], [0, a I]], a = exp(-dt / bias_tau) (1 without Gauss-Markov)
//   Q   = [[arw^2 dt + rrw^2 dt^3/3, -rrw^2 dt^2/2], [., rrw^2 dt + bias_sigma^2 (1 - a^2)]]
//         (the Gauss-Markov cross terms are left out)
// Update with a star tracker attitude sigma_m: residual z = rotation vector of
// R(sigma_m) R(sigma_est)' (H = [I 0]), R = A diag(sc^2, sc^2, sb^2) A' + q^2/12 I
// (q: the gyro's angle quantum, whose carried remainder is a bounded attitude error),
// Joseph form; sigma_est <- exp(-dtheta^) sigma_est, b_est += db.
//
// Latency: a measurement exposed at t_e and delivered later is applied at
// t_e. The filter keeps a ring of snapshots, one per gyro sample (time,
// state, covariance, the rate held from it on); a delivery restores the last
// snapshot at or before t_e, propagates to t_e, updates, and re-propagates
// through every later snapshot with their own gyro rates to now. The ring
// covers latency + 2 gyro periods; an exposure older than the ring is
// dropped (counted). The star tracker's period must be >= the gyro's, so at
// most one update falls between two snapshots.
#pragma once
#include <cstdint>
#include <memory>
#include <vector>

#include "sc_rt/controllers.hpp"
#include "sc_rt/sensors.hpp"

namespace sc_rt {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

//! Navigation flag bit, OR-ed into the run's flags: the star tracker has
//! been silent longer than degraded_after (gyro-only propagation).
constexpr int FLAG_NAV_DEGRADED = 2048;  // after wheel_cmd_t FLAG_LAW_INVALID = 1024

struct MekfParams {
  double arw = 0.0;               //!< [rad/sqrt(s)] gyro angle random walk
  double rrw = 0.0;               //!< [rad/s^(3/2)] bias random walk
  double bias_sigma = 0.0;        //!< [rad/s] Gauss-Markov sigma (0: none)
  double bias_tau = 3600.0;       //!< [s]
  double quantization = 0.0;      //!< [rad] gyro angle quantum
  double sigma_cross = 0.0;       //!< [rad]
  double sigma_boresight = 0.0;   //!< [rad]
  Vec3 boresight = Vec3(0.0, 0.0, 1.0);
  double initial_attitude_sigma = 0.0;  //!< [rad] per axis, P0 and the initial error drawn
  double initial_bias_sigma = 0.0;      //!< [rad/s] per axis
  double degraded_after = 1.0;    //!< [s] star tracker silence before FLAG_NAV_DEGRADED
  int history = 8;                //!< snapshots kept (>= latency / gyro period + 2)
  //! the calibrating filter (15 states: also the gyro's scale factors and misalignments)
  bool calibrate = false;
  double initial_scale_factor_sigma = 0.0;   //!< [-] per axis, its P0 (calibrate)
  double initial_misalignment_sigma = 0.0;   //!< [rad] per element, its P0 (calibrate)
  //! [-, rad] the initial calibration estimate [s1 s2 s3, ku1 ku2 ku3, kl1 kl2 kl3]
  //! (MekfStateT::cal; calibrate; default 0: none)
  Eigen::Matrix<double, 9, 1> initial_calibration = Eigen::Matrix<double, 9, 1>::Zero();
};

// The filter's state: the attitude and bias estimates, for the calibrating
// filter (N = 15) also the gyro's scale factors and misalignments c, and
// the covariance of the N error states.
template <int N>
struct MekfStateT {
  double t = 0.0;
  Vec3 sigma = Vec3::Zero();  //!< sigma_BN estimate
  Vec3 bias = Vec3::Zero();   //!< [rad/s]
  //! N = 15: [s1 s2 s3, ku1 ku2 ku3, kl1 kl2 kl3] of S = [[s1 ku1 ku2], [kl1 s2 ku3], [kl2 kl3 s3]]
  Eigen::Matrix<double, N - 6, 1> cal = Eigen::Matrix<double, N - 6, 1>::Zero();
  Eigen::Matrix<double, N, N> P = Eigen::Matrix<double, N, N>::Zero();
};
using MekfState = MekfStateT<6>;

// The gyro's scale factor and misalignment matrix S of a calibrating
// filter's state (the gyro measures (I + S) omega + b + noise).
Mat3 gyro_calibration_matrix(const Eigen::Matrix<double, 9, 1>& c);

// N = 6: the filter above. N = 15 (MekfCal): it also estimates the gyro's
// scale factors and misalignments (docs/MODEL.md, "Calibrating filter"):
// the rate is (I + S)^-1 (omega_m - b), and Phi gains the columns
// -dt (I + S)^-1 Omega(w) of the calibration errors (constants: no process
// noise on them).
template <int N>
class MekfT {
 public:
  using State = MekfStateT<N>;
  using VecN = Eigen::Matrix<double, N, 1>;
  using MatN = Eigen::Matrix<double, N, N>;
  explicit MekfT(const MekfParams& p);
  void reset(double t, const Vec3& sigma, const Vec3& bias);
  // A gyro sample at t (>= the current time): propagate to t, then hold it.
  // A rate sample (kGyroRate): over the interval the mean of the two samples
  // that bound it; a mean rate (kGyroMeanRate, an integrating gyro's delta
  // angle over the interval ending at t, divided by it): that rate itself,
  // exact for a coning-compensated increment.
  void gyro(double t, const Vec3& omega_m, int output = kGyroRate);
  // A star tracker attitude exposed at t_exposure <= now; false if dropped.
  bool star(double t_exposure, const Vec3& sigma_m);
  // The state propagated from now to t >= now with the newest sample held (not stored).
  State predict(double t) const;
  // The same without copies: the current state itself when t is now, else the state
  // propagated into a scratch state of the filter (its covariance only if covariance, else
  // not to be read), valid until the next call or change of the filter.
  const State& predict_to(double t, bool covariance) const;
  const State& state() const { return cur(); }
  const Vec3& rate() const { return omega_m_; }  //!< the held gyro sample
  // The body rate estimate of a state from the held sample: (I + S)^-1 (omega_m - b).
  Vec3 rate_estimate(const State& s) const;
  const Vec3& innovation() const { return innov_; }  //!< [rad] last residual
  double nis() const { return nis_; }              //!< last z' S^-1 z
  double last_update_exposure() const { return last_exposure_; }
  long updates() const { return updates_; }
  long dropped() const { return dropped_; }

 private:
  struct Snap {
    State s;
    Vec3 omega_m;        // the sample taken at s.t (held from it on)
    Vec3 interval_rate;  // the rate that propagated the previous snapshot into this one
    int output;          // the sample's kind (kGyroRate, kGyroMeanRate)
  };
  void propagate(State& s, const Vec3& omega_m, double dt) const { propagate_into(s, s, omega_m, dt); }
  // out = in propagated by dt (out may be in): a new snapshot is written where it is kept.
  // Without covariance only t, sigma and bias (out.P is left as it was).
  void propagate_into(const State& in, State& out, const Vec3& omega_m, double dt,
                      bool covariance = true) const;
  // The current state: the newest snapshot (cur_slot_ its ring index) or, before the first
  // gyro sample or when an update moved it past the newest snapshot, ahead_.
  const State& cur() const { return cur_slot_ < 0 ? ahead_ : ring_[static_cast<std::size_t>(cur_slot_)].s; }
  State& cur() { return cur_slot_ < 0 ? ahead_ : ring_[static_cast<std::size_t>(cur_slot_)].s; }
  void update(State& s, const Vec3& sigma_m);
  MekfParams p_;
  Mat3 R_;
  std::vector<Snap> ring_;
  std::size_t head_ = 0, size_ = 0;  // head_: oldest
  State ahead_;
  long cur_slot_ = -1;
  State scratch_;  // star(): an update between snapshots
  Vec3 omega_m_ = Vec3::Zero();
  bool have_gyro_ = false;
  Vec3 innov_ = Vec3::Zero();
  double nis_ = 0.0;
  double last_exposure_ = 0.0;
  long updates_ = 0, dropped_ = 0;
  static constexpr int kGmCache = 8;  // exp(-dt / bias_tau) of the last kGmCache dt
  mutable double gm_dt_[kGmCache] = {-1.0, -1.0, -1.0, -1.0, -1.0, -1.0, -1.0, -1.0};
  mutable double gm_a_[kGmCache] = {};
  mutable int gm_next_ = 0;
  mutable State pred_;  // predict_to's result when it propagates
};
using Mekf = MekfT<6>;
using MekfCal = MekfT<15>;
extern template class MekfT<6>;
extern template class MekfT<15>;

struct NavConfig {
  SensorParams sensors;
  MekfParams mekf;
  bool use_estimate = false;  //!< the law gets the estimate (else the truth)
};

// Per-row telemetry of the navigation (the run's estimator fields).
struct NavTelemetry {
  Vec3 sigma_est = Vec3::Zero();
  Vec3 bias_est = Vec3::Zero();    //!< [rad/s]
  Vec3 bias_true = Vec3::Zero();   //!< [rad/s]
  Vec6 P_diag = Vec6::Zero();      //!< [rad^2, (rad/s)^2]
  Vec3 att_error = Vec3::Zero();   //!< [rad] rotation vector of truth relative to the estimate
  Vec3 innovation = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());  //!< [rad] NaN: no update since the last row
  double nis = std::numeric_limits<double>::quiet_NaN();
  //! [-, rad] the calibrating filter's gyro calibration [s1 s2 s3, ku1 ku2 ku3,
  //! kl1 kl2 kl3] (MekfStateT::cal); NaN with the 6-state filter
  Eigen::Matrix<double, 9, 1> cal_est = Eigen::Matrix<double, 9, 1>::Constant(std::numeric_limits<double>::quiet_NaN());
  //! [-, rad] 3 sigma of each, 3 sqrt of its covariance diagonal; NaN likewise
  Eigen::Matrix<double, 9, 1> cal_3sigma = Eigen::Matrix<double, 9, 1>::Constant(std::numeric_limits<double>::quiet_NaN());
  int flags = 0;
};

// The initial attitude estimate of a run: the true sigma_BN(0) rotated by a
// draw of N(0, sigma^2 I) per axis [rad] from the seed's initialisation
// stream (the offline loop and the bench compute it the same way).
Vec3 initial_estimate(std::uint64_t seed, double sigma, const Vec3& sigma_true0);

// The controller's half of the navigation: the filter fed with sensor
// samples (from the SensorSuite offline, from the sensor messages on the
// bus) and the law's Measurement built from the truth or from the estimate.
// It never sees the plant state except through `truth`, which in estimate
// mode only lends its time (and the wheel speeds when no tachometer runs).
class Estimator {
 public:
  Estimator(const MekfParams& p, bool use_estimate);
  // t = 0: attitude estimate sigma0, bias estimate 0, no tachometer yet.
  void reset(const Vec3& sigma0);
  // Restart at time t from the attitude sigma (a first fix), bias estimate 0,
  // the initial covariance; the held tachometer reading is kept.
  void reset_at(double t, const Vec3& sigma);
  // A gyro sample; false (not applied) when older than the filter's time.
  bool gyro(const GyroSample& g);
  // A star tracker attitude; false when dropped (older than the ring).
  bool star(const StarSample& s);
  void tach(const TachSample& s);
  // The law's measurement at truth.t and (tel) the estimator's telemetry:
  // estimate, bias, covariance diagonal, the innovation and NIS of the
  // updates since the last call (NaN: none), FLAG_NAV_DEGRADED. Leaves
  // tel->bias_true and tel->att_error alone (they need the truth).
  Measurement measure(const Measurement& truth, NavTelemetry* tel = nullptr);
  //! the 6-state filter (not the one in use when MekfParams::calibrate)
  const Mekf& filter() const { return mekf_; }
  //! the calibrating filter, when MekfParams::calibrate (else null)
  const MekfCal* calibrating_filter() const { return cal_.get(); }
  long updates() const;  //!< star tracker updates applied (the filter in use)
  long dropped() const;  //!< exposures older than its ring
  bool use_estimate() const { return use_estimate_; }

 private:
  // f(the filter in use)
  template <class F>
  auto with(F f) {
    return cal_ ? f(*cal_) : f(mekf_);
  }
  Mekf mekf_;
  std::unique_ptr<MekfCal> cal_;
  double degraded_after_;  //!< [s] MekfParams::degraded_after
  bool use_estimate_;
  Vec4 wheel_ = Vec4::Zero();
  bool have_tach_ = false;
  bool updated_ = false;
};

// Sensors + estimator: the offline loop's navigation (the bench splits it:
// the SensorSuite runs in the plant emulator, the Estimator in the controller).
class Navigation {
 public:
  explicit Navigation(const NavConfig& c);
  // Start at t = 0 from the true state: sensors reset, the estimate = the
  // truth rotated by a draw of the initial covariance, bias estimate 0.
  void reset(const PlantState& x0);
  // Plant step i at time t with the plant state x (every tick, or only at
  // next_tick(): the same numbers); B_B [T]: the plant's true field in B at
  // t, needed where magnetometer_due(i) (SensorSuite::tick).
  void tick(std::int64_t i, double t, const PlantState& x, const Vec3* B_B = nullptr);
  std::int64_t next_tick(std::int64_t i) const { return sensors_.next_tick(i); }
  bool magnetometer_due(std::int64_t i) const { return sensors_.magnetometer_due(i); }
  //! [T] the controller's field in B: the latest magnetometer sample rotated
  //! to B with the known mounting (magnetometer_field_B), held until the
  //! next; NaN before the first sample and without a magnetometer
  const Vec3& field_B() const { return field_B_; }
  // The law's measurement at t (truth or estimate) and the row's telemetry.
  Measurement measure(double t, const PlantState& x, NavTelemetry* tel = nullptr);
  const SensorSuite& sensors() const { return sensors_; }
  const Mekf& filter() const { return est_.filter(); }
  const Estimator& estimator() const { return est_; }

 private:
  NavConfig c_;
  SensorSuite sensors_;
  Estimator est_;
  Vec3 field_B_ = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
};

}  // namespace sc_rt
