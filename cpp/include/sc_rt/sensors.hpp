// Attitude sensors of the offline loop (docs/MODEL.md section 10): a rate
// gyro, a star tracker and wheel tachometers, sampled on the plant's grid,
// seeded, and the same numbers in both offline engines (the Python engine
// calls these through the bindings; the C++ engine inside
// simulate_closed_loop).
//
// Random numbers: one SplitMix64 stream per sensor and purpose (a stream is
// SplitMix64 started at mix(seed, stream id), i.e. counter based: value n of
// a stream is mix(start + n * golden)), normal deviates by Marsaglia's polar
// method (Box-Muller without sin/cos; a rejected pair consumes its draws). Integer
// arithmetic is exact everywhere; the deviates use std::log and std::sqrt
// (sqrt is correctly rounded, log is not required to be), so two platforms with different libm may differ in
// the last bit of a deviate (the same build always gives the same numbers).
//
// Times: a sensor samples at tick i (plant step i, t = the engine's time of
// that step) when i is a multiple of its period in ticks. Every period and
// the star tracker's latency are integer numbers of plant steps (the
// scenario reader refuses other values, naming the nearest valid rates).
#pragma once
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "sc_rt/plant.hpp"
#include "sc_rt/types.hpp"

namespace sc_rt {

// SplitMix64 (Steele, Lea, Flood 2014) with normals by Marsaglia's polar method.
// Defined here so that the sensors' and the MEKF's per-sample loops inline them.
class Rng {
 public:
  explicit Rng(std::uint64_t seed = 0, std::uint64_t stream = 0)
      : s_(mix(mix(seed + kGolden) ^ (stream * 0xD1B54A32D192ED03ULL))) {}
  std::uint64_t next_u64() {
    s_ += kGolden;
    return mix(s_);
  }
  double uniform() { return static_cast<double>(next_u64() >> 11) * 0x1.0p-53; }  //!< [0, 1), 53 bits
  double normal() {  //!< N(0, 1)
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    // Marsaglia's polar form of Box-Muller: no sin/cos, 21.5 % of the pairs rejected.
    double x, y, r2;
    do {
      x = 2.0 * uniform() - 1.0;
      y = 2.0 * uniform() - 1.0;
      r2 = x * x + y * y;
    } while (r2 >= 1.0 || r2 == 0.0);
    const double f = std::sqrt(-2.0 * std::log(r2) / r2);
    spare_ = y * f;
    has_spare_ = true;
    return x * f;
  }
  static std::uint64_t mix(std::uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }

 private:
  static constexpr std::uint64_t kGolden = 0x9E3779B97F4A7C15ULL;
  std::uint64_t s_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

// Rate gyro (SI units; the scenario reader converts from deg/h, ppm, arcsec).
//   omega_m = sat((I + diag(scale_factor)) (I - misalignment^) omega + b + n)
//   n ~ N(0, arw^2 / dt) per sample (angle random walk, white rate noise)
//   b: bias0 + b_gm + b_rw; b_gm first-order Gauss-Markov (steady-state
//   sigma bias_sigma, time constant bias_tau), b_rw a random walk (rrw)
//   quantisation: the delta angle omega_m dt is counted in quanta of
//   `quantization` rad with the remainder carried to the next sample.
// Output (docs/MODEL.md, "Gyro"): kGyroRate, the rate at the sample instant
// (omega above is omega_BN_B(t)); or kGyroMeanRate, an integrating gyro: its
// delta angle over the interval since the previous sample divided by the
// interval, tagged at the interval's end, where omega is the mean rate
// phi / dt and phi the rotation vector of the body's attitude change over
// the interval, R(t) = exp(-phi^) R(t - dt) (a coning-compensated
// increment; the first sample, with no interval, is the rate at t).
constexpr int kGyroRate = 0;
constexpr int kGyroMeanRate = 1;
struct GyroParams {
  bool enabled = false;
  int output = kGyroRate;              //!< kGyroRate or kGyroMeanRate
  int period_ticks = 1;                //!< plant steps per sample
  double arw = 0.0;                    //!< [rad/sqrt(s)]
  double bias_sigma = 0.0;             //!< [rad/s] Gauss-Markov steady-state sigma
  double bias_tau = 3600.0;            //!< [s] Gauss-Markov time constant
  double rrw = 0.0;                    //!< [rad/s^(3/2)] rate random walk
  Vec3 bias0 = Vec3::Zero();           //!< [rad/s] constant part of the bias
  Vec3 scale_factor = Vec3::Zero();    //!< [-] per axis
  Vec3 misalignment = Vec3::Zero();    //!< [rad] small rotation of the gyro axes
  double quantization = 0.0;           //!< [rad] angle quantum, 0: none
  double saturation = std::numeric_limits<double>::infinity();  //!< [rad/s] per axis
};

// Star tracker: sigma_meas = sigma_true composed with a small body-frame
// rotation v, v = A [sigma_cross n1, sigma_cross n2, sigma_boresight n3],
// A = [x_s y_s boresight] an orthonormal sensor frame in the body. Exposed at
// tick i, delivered latency_ticks later carrying its exposure time; none
// exposed inside a blackout [start, end), each lost with loss_probability.
struct StarTrackerParams {
  bool enabled = false;
  int period_ticks = 1;
  double sigma_cross = 0.0;            //!< [rad] 1 sigma, each cross-boresight axis
  double sigma_boresight = 0.0;        //!< [rad] 1 sigma about the boresight
  Vec3 boresight = Vec3(0.0, 0.0, 1.0);  //!< [-] body frame, normalised on use
  int latency_ticks = 0;
  double loss_probability = 0.0;       //!< [-]
  std::vector<std::pair<double, double>> blackouts;  //!< [s] exposure windows [start, end)
};

// Wheel tachometer: omega_m = q round(omega / q), q = 2 pi / (counts_per_rev T).
struct TachometerParams {
  bool enabled = false;
  int period_ticks = 1;
  double counts_per_rev = 0.0;  //!< [-] 0: no quantisation
  double period = 0.1;          //!< [s] sample period T (sets the quantum)
};

// Three-axis magnetometer (SI units: tesla; the scenario reader converts
// from nT, sc_rt.scenario.tables.magnetometer). Output in the sensor frame S:
//   B_m = q(sat(M R_SB B_B + bias + n)),  n ~ N(0, noise^2) per axis, white
// R_SB the body-to-sensor rotation, M the scale factor and misalignment
// (I: none), q(x) = lsb nearbyint(x / lsb) per axis (lsb 0: none), sat the
// per-axis range. Seeded like the others: its own stream (id 5) of the seed.
// SensorSuite ticks it (enabled) on the plant's grid from the plant's true
// field in B at the sample instant, which its caller evaluates
// (docs/MODEL.md section 13).
struct MagnetometerParams {
  bool enabled = false;               //!< SensorSuite ticks it
  int period_ticks = 1;               //!< plant steps per sample
  double noise = 0.0;                 //!< [T] 1 sigma white noise per axis
  Vec3 bias = Vec3::Zero();           //!< [T] constant bias, sensor frame
  Mat3 M = Mat3::Identity();          //!< [-] scale factor and misalignment (sensor frame)
  Mat3 R_SB = Mat3::Identity();       //!< [-] body-to-sensor rotation (orthonormal)
  double lsb = 0.0;                   //!< [T] quantum, 0: none
  double range = std::numeric_limits<double>::infinity();  //!< [T] per-axis saturation
};

std::vector<std::string> validate(const MagnetometerParams& p);

class Magnetometer {
 public:
  static constexpr std::uint64_t kStream = 5;  //!< its Rng stream id (sensors.cpp's S_* ids are 1..4)
  Magnetometer(const MagnetometerParams& p, std::uint64_t seed);  // throws std::invalid_argument
  void reset();  //!< back to the seed's first draw
  // One sample [T] (sensor frame) of the field B_B [T] (body frame).
  Vec3 sample(const Vec3& B_B);
  const MagnetometerParams& params() const { return p_; }

 private:
  MagnetometerParams p_;
  std::uint64_t seed_;
  Mat3 MR_;  // M R_SB
  Rng rng_;
};

struct SensorParams {
  GyroParams gyro;
  StarTrackerParams star_tracker;
  TachometerParams tachometer;
  MagnetometerParams magnetometer;
  std::uint64_t seed = 0;
  double dt = 0.01;  //!< [s] plant step (one tick)
};

struct GyroSample {
  double t = 0.0;
  Vec3 omega = Vec3::Zero();  //!< [rad/s] measured
  int output = kGyroRate;     //!< kGyroRate: the rate at t; kGyroMeanRate: the mean over the interval ending at t
};
struct StarSample {
  double t_exposure = 0.0;    //!< [s]
  double t_delivery = 0.0;    //!< [s]
  Vec3 sigma_BN = Vec3::Zero();
};
struct TachSample {
  double t = 0.0;
  Vec4 wheel_speed = Vec4::Zero();
};
struct MagSample {
  double t = 0.0;             //!< [s] sample instant
  Vec3 B_S = Vec3::Zero();    //!< [T] measured field, sensor frame
};

// The field in B [T] a controller takes from a magnetometer sample B_S [T]:
// B_B = R_SB' B_S, the sample rotated from the sensor frame to B with the
// known mounting R_SB (body to sensor). The controller knows nothing of the
// bias, scale factor or misalignment: they stay in its field.
inline Vec3 magnetometer_field_B(const Mat3& R_SB, const Vec3& B_S) { return R_SB.transpose() * B_S; }

// Orthonormal sensor frame [x y b] with b the normalised boresight.
Mat3 boresight_frame(const Vec3& boresight);
// The attitude sigma_BN rotated by the small body-frame rotation vector v:
// R(result) = exp(-v^) R(sigma_BN) (v [rad]).
Vec3 mrp_rotate_body(const Vec3& sigma_BN, const Vec3& v);
// The same with |v| given (v_norm = v.norm(): the MEKF has it already).
Vec3 mrp_rotate_body_by(const Vec3& sigma_BN, const Vec3& v, double v_norm);
// sigma'' composed after sigma': R(result) = R(s2) R(s1), short set.
Vec3 mrp_compose(const Vec3& s1, const Vec3& s2);
// Rotation vector [rad] of the small rotation R(s1) R(s2)' (s1 relative to s2).
Vec3 mrp_error_vector(const Vec3& s1, const Vec3& s2);

// The four sensors. tick() samples those due at tick i from the plant state
// (the magnetometer from the true field in B its caller gives) and queues the
// star tracker's exposures until their delivery tick. No allocation after
// construction.
class SensorSuite {
 public:
  explicit SensorSuite(const SensorParams& p);
  void reset();
  // Sample every sensor due at tick i (time t) from the plant state x; the
  // magnetometer, when due (magnetometer_due), from B_B [T], the plant's true
  // field in B at t (null: none known, a sample of NaN; its draws are taken).
  void tick(std::int64_t i, double t, const PlantState& x, const Vec3* B_B = nullptr);
  // Whether the magnetometer samples at tick i (the caller then evaluates the field).
  bool magnetometer_due(std::int64_t i) const {
    return p_.magnetometer.enabled && i % p_.magnetometer.period_ticks == 0;
  }

  // What the last tick produced (valid until the next tick).
  bool gyro_new() const { return gyro_new_; }
  bool star_new() const { return star_new_; }
  bool tach_new() const { return tach_new_; }
  bool mag_new() const { return mag_new_; }
  const GyroSample& gyro() const { return gyro_; }
  const StarSample& star() const { return star_; }
  const TachSample& tach() const { return tach_; }
  const MagSample& mag() const { return mag_; }
  const Vec3& gyro_bias() const { return bias_; }  //!< [rad/s] the true bias now
  // Counters: exposures lost at random, inside a blackout, delivered.
  long lost() const { return lost_; }
  long blacked_out() const { return blacked_; }
  long delivered() const { return delivered_; }
  const SensorParams& params() const { return p_; }
  // The first tick > i at which some sensor samples or delivers.
  std::int64_t next_tick(std::int64_t i) const;

 private:
  SensorParams p_;
  Mat3 A_;  // star tracker frame
  Mat3 gyro_M_;
  Rng rng_gyro_, rng_bias_, rng_star_, rng_loss_;
  Vec3 bias_ = Vec3::Zero(), gm_ = Vec3::Zero(), rw_ = Vec3::Zero(), carry_ = Vec3::Zero();
  Vec3 sigma_prev_ = Vec3::Zero();  // kGyroMeanRate: the attitude at the previous sample
  bool have_prev_ = false;
  double a_gm_ = 1.0, q_gm_ = 0.0, q_rw_ = 0.0;
  double dt_gyro_ = 0.0, sn_gyro_ = 0.0;  // the gyro's period [s] and white noise sigma per sample
  std::int64_t last_bias_tick_ = -1;
  // Each sensor's next sample tick, a multiple of its period: tick() and next_tick() test
  // i % period == 0 and compute the next multiple without a division when the ticks come in order.
  std::int64_t next_gyro_ = 0, next_star_ = 0, next_tach_ = 0;
  GyroSample gyro_;
  StarSample star_;
  TachSample tach_;
  Magnetometer mag_model_;
  MagSample mag_;
  bool gyro_new_ = false, star_new_ = false, tach_new_ = false, mag_new_ = false;
  struct Pending {
    std::int64_t deliver;
    StarSample s;
  };
  std::vector<Pending> queue_;  // ring buffer
  std::size_t q_head_ = 0, q_size_ = 0;
  long lost_ = 0, blacked_ = 0, delivered_ = 0;
};

}  // namespace sc_rt
