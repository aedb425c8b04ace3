#include "sc_rt/sensors.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

#include "sc_rt/mrp.hpp"
#include "sc_rt/util.hpp"

namespace sc_rt {

namespace {
constexpr double kTwoPi = 6.283185307179586476925286766559;
// Stream ids: one per sensor and purpose, so that enabling one sensor does
// not change another's numbers.
enum Stream : std::uint64_t { S_GYRO = 1, S_BIAS = 2, S_STAR = 3, S_LOSS = 4 };
static_assert(Magnetometer::kStream == 5, "the magnetometer's stream is the next id");

// i % period == 0, with next the cached next multiple of period (any multiple: a tick strictly
// between next - period and next is not one, and i == next is); next moves to the multiple after i.
inline bool due(std::int64_t i, int period, std::int64_t& next) {
  if (i == next) {
    next += period;
    return true;
  }
  if (i < next && i > next - period) return false;
  next = (i / period + 1) * period;  // out of order, or the first tick
  return i % period == 0;
}

// The first multiple of period > i (next: the cached one, used when it is that multiple).
inline std::int64_t next_multiple(std::int64_t i, int period, std::int64_t next) {
  if (i >= 0 && next > i && next - period <= i) return next;
  return (i / period + 1) * period;
}
}  // namespace

Mat3 boresight_frame(const Vec3& boresight) {
  const Vec3 b = boresight.normalized();
  int k = 0;  // the body axis least aligned with b
  for (int i = 1; i < 3; ++i)
    if (std::abs(b(i)) < std::abs(b(k))) k = i;
  const Vec3 x = Vec3::Unit(k).cross(b).normalized();
  const Vec3 y = b.cross(x);
  Mat3 A;
  A.col(0) = x;
  A.col(1) = y;
  A.col(2) = b;
  return A;
}

namespace {
// mrp_short, here so that it inlines into the per-sample compositions (the same operations)
inline Vec3 short_set(const Vec3& s) { return s.squaredNorm() > 1.0 ? Vec3(-s / s.squaredNorm()) : s; }

inline Vec3 compose(const Vec3& s1, const Vec3& s2) {
  auto num_den = [&s2](const Vec3& a, double& den) {
    const double aa = a.squaredNorm(), bb = s2.squaredNorm();
    den = 1.0 + aa * bb - 2.0 * a.dot(s2);
    return Vec3((1.0 - aa) * s2 + (1.0 - bb) * a - 2.0 * s2.cross(a));
  };
  double den;
  const Vec3 num = num_den(s1, den);
  if (den < 0.25 && s1.squaredNorm() > 0.0) {  // as mrp_subtract: the better-conditioned set
    double den2;
    const Vec3 num2 = num_den(mrp_shadow(s1), den2);
    if (den2 > den) return short_set(num2 / den2);
  }
  return short_set(num / den);
}
}  // namespace

Vec3 mrp_compose(const Vec3& s1, const Vec3& s2) { return compose(s1, s2); }

Vec3 mrp_rotate_body_by(const Vec3& sigma_BN, const Vec3& v, double a) {
  const Vec3 d = a > 0.0 ? Vec3(v * (std::tan(0.25 * a) / a)) : Vec3(Vec3::Zero());
  return compose(sigma_BN, d);
}

Vec3 mrp_rotate_body(const Vec3& sigma_BN, const Vec3& v) { return mrp_rotate_body_by(sigma_BN, v, v.norm()); }

Vec3 mrp_error_vector(const Vec3& s1, const Vec3& s2) {
  const Vec3 d = mrp_subtract(s1, s2);
  const double n = d.norm();
  return n > 0.0 ? Vec3(d * (4.0 * std::atan(n) / n)) : Vec3(Vec3::Zero());
}

SensorSuite::SensorSuite(const SensorParams& p)
    : p_(p),
      A_(boresight_frame(p.star_tracker.boresight)),
      gyro_M_(Mat3::Identity()),
      mag_model_(p.magnetometer, p.seed) {
  const GyroParams& g = p_.gyro;
  gyro_M_ = (Mat3::Identity() + Mat3(g.scale_factor.asDiagonal())) *
            (Mat3::Identity() - skew(g.misalignment));
  const double dtg = g.period_ticks * p_.dt;
  dt_gyro_ = dtg;
  sn_gyro_ = g.arw / std::sqrt(dtg);
  if (g.bias_sigma > 0.0) {
    a_gm_ = std::exp(-dtg / g.bias_tau);
    q_gm_ = g.bias_sigma * std::sqrt(1.0 - a_gm_ * a_gm_);
  }
  q_rw_ = g.rrw * std::sqrt(dtg);
  const StarTrackerParams& s = p_.star_tracker;
  queue_.resize(static_cast<std::size_t>(s.latency_ticks / std::max(1, s.period_ticks) + 2));
  reset();
}

void SensorSuite::reset() {
  const std::uint64_t seed = p_.seed;
  rng_gyro_ = Rng(seed, S_GYRO);
  rng_bias_ = Rng(seed, S_BIAS);
  rng_star_ = Rng(seed, S_STAR);
  rng_loss_ = Rng(seed, S_LOSS);
  mag_model_.reset();  // its own stream (Magnetometer::kStream)
  const GyroParams& g = p_.gyro;
  gm_.setZero();
  rw_.setZero();
  carry_.setZero();
  have_prev_ = false;
  if (g.bias_sigma > 0.0)  // stationary start
    for (int i = 0; i < 3; ++i) gm_(i) = g.bias_sigma * rng_bias_.normal();
  bias_ = g.bias0 + gm_ + rw_;
  gyro_ = GyroSample{};
  star_ = StarSample{};
  tach_ = TachSample{};
  mag_ = MagSample{};
  gyro_new_ = star_new_ = tach_new_ = mag_new_ = false;
  q_head_ = q_size_ = 0;
  lost_ = blacked_ = delivered_ = 0;
  last_bias_tick_ = -1;
  next_gyro_ = next_star_ = next_tach_ = 0;
}

void SensorSuite::tick(std::int64_t i, double t, const PlantState& x, const Vec3* B_B) {
  gyro_new_ = star_new_ = tach_new_ = mag_new_ = false;
  const GyroParams& g = p_.gyro;
  if (g.enabled && due(i, g.period_ticks, next_gyro_)) {
    if (last_bias_tick_ >= 0) {  // the bias moves one gyro period
      // (a zero-variance part draws nothing)
      if (q_gm_ > 0.0)
        for (int k = 0; k < 3; ++k) gm_(k) = a_gm_ * gm_(k) + q_gm_ * rng_bias_.normal();
      if (q_rw_ > 0.0)
        for (int k = 0; k < 3; ++k) rw_(k) += q_rw_ * rng_bias_.normal();
    }
    last_bias_tick_ = i;
    bias_ = g.bias0 + gm_ + rw_;
    const double dtg = dt_gyro_, sn = sn_gyro_;
    Vec3 w;
    if (g.output == kGyroMeanRate) {  // the mean rate over the interval: its rotation vector / dt
      w = gyro_M_ * (have_prev_ ? Vec3(mrp_error_vector(x.sigma_BN, sigma_prev_) / dtg) : x.omega_BN_B) + bias_;
      sigma_prev_ = x.sigma_BN;
      have_prev_ = true;
    } else {
      w = gyro_M_ * x.omega_BN_B + bias_;
    }
    for (int k = 0; k < 3; ++k) {
      if (sn > 0.0) w(k) += sn * rng_gyro_.normal();
      w(k) = std::min(std::max(w(k), -g.saturation), g.saturation);
    }
    if (g.quantization > 0.0) {
      for (int k = 0; k < 3; ++k) {
        const double angle = w(k) * dtg + carry_(k);
        const double counts = std::nearbyint(angle / g.quantization);
        carry_(k) = angle - counts * g.quantization;
        w(k) = counts * g.quantization / dtg;
      }
    }
    gyro_ = GyroSample{t, w, g.output};
    gyro_new_ = true;
  }
  const StarTrackerParams& s = p_.star_tracker;
  if (s.enabled) {
    if (due(i, s.period_ticks, next_star_)) {
      bool dark = false;
      for (const auto& w : s.blackouts) dark = dark || (t >= w.first && t < w.second);
      const double u = rng_loss_.uniform();  // drawn for every exposure: streams stay aligned
      Vec3 n;
      for (int k = 0; k < 3; ++k) n(k) = rng_star_.normal();
      if (dark) {
        ++blacked_;
      } else if (u < s.loss_probability) {
        ++lost_;
      } else {
        const Vec3 v = A_ * Vec3(s.sigma_cross * n(0), s.sigma_cross * n(1), s.sigma_boresight * n(2));
        Pending pd{i + s.latency_ticks, StarSample{t, 0.0, mrp_rotate_body(x.sigma_BN, v)}};
        if (q_size_ < queue_.size()) {
          queue_[(q_head_ + q_size_) % queue_.size()] = pd;
          ++q_size_;
        }
      }
    }
    if (q_size_ > 0 && queue_[q_head_].deliver == i) {
      star_ = queue_[q_head_].s;
      star_.t_delivery = t;
      star_new_ = true;
      q_head_ = (q_head_ + 1) % queue_.size();
      --q_size_;
      ++delivered_;
    }
  }
  const TachometerParams& c = p_.tachometer;
  if (c.enabled && due(i, c.period_ticks, next_tach_)) {
    Vec4 w = x.wheel_speed;
    if (c.counts_per_rev > 0.0) {
      const double q = kTwoPi / (c.counts_per_rev * c.period);
      for (int k = 0; k < 4; ++k) w(k) = q * std::nearbyint(w(k) / q);
    }
    tach_ = TachSample{t, w};
    tach_new_ = true;
  }
  if (magnetometer_due(i)) {  // last at a tick: the other sensors' draws are not moved by it
    const Vec3 B = B_B ? *B_B : Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
    mag_ = MagSample{t, mag_model_.sample(B)};
    mag_new_ = true;
  }
}

std::int64_t SensorSuite::next_tick(std::int64_t i) const {
  std::int64_t best = std::numeric_limits<std::int64_t>::max();
  if (p_.gyro.enabled) best = std::min(best, next_multiple(i, p_.gyro.period_ticks, next_gyro_));
  if (p_.star_tracker.enabled) {
    best = std::min(best, next_multiple(i, p_.star_tracker.period_ticks, next_star_));
    if (q_size_ > 0) best = std::min(best, queue_[q_head_].deliver);
  }
  if (p_.tachometer.enabled) best = std::min(best, next_multiple(i, p_.tachometer.period_ticks, next_tach_));
  if (p_.magnetometer.enabled) {
    const std::int64_t n = p_.magnetometer.period_ticks;
    best = std::min(best, i >= 0 ? (i / n + 1) * n : 0);
  }
  return best;
}

std::vector<std::string> validate(const MagnetometerParams& p) {
  std::vector<std::string> errs;
  if (p.period_ticks < 1) errs.push_back("period_ticks must be >= 1, got " + std::to_string(p.period_ticks));
  if (!(std::isfinite(p.noise) && p.noise >= 0.0))
    errs.push_back("noise must be finite and >= 0, got " + format_double(p.noise));
  if (!(std::isfinite(p.lsb) && p.lsb >= 0.0)) errs.push_back("lsb must be finite and >= 0, got " + format_double(p.lsb));
  if (!(p.range > 0.0)) errs.push_back("range must be > 0, got " + format_double(p.range));
  if (!p.bias.allFinite()) errs.push_back("bias is not finite: " + format_matrix(p.bias));
  if (!p.M.allFinite()) errs.push_back("M is not finite: " + format_matrix(p.M));
  if (!p.R_SB.allFinite() || (p.R_SB * p.R_SB.transpose() - Mat3::Identity()).cwiseAbs().maxCoeff() > 1e-9 ||
      p.R_SB.determinant() < 0.0)
    errs.push_back("R_SB is not a rotation matrix: " + format_matrix(p.R_SB));
  return errs;
}

Magnetometer::Magnetometer(const MagnetometerParams& p, std::uint64_t seed)
    : p_(p), seed_(seed), MR_(p.M * p.R_SB), rng_(seed, kStream) {
  throw_if_errors("MagnetometerParams", validate(p));
}

void Magnetometer::reset() { rng_ = Rng(seed_, kStream); }

Vec3 Magnetometer::sample(const Vec3& B_B) {
  Vec3 b = MR_ * B_B + p_.bias;  // M R_SB B + bias, sensor frame
  for (int k = 0; k < 3; ++k) {
    if (p_.noise > 0.0) b(k) += p_.noise * rng_.normal();  // white, drawn x, y, z
    b(k) = std::min(std::max(b(k), -p_.range), p_.range);
    if (p_.lsb > 0.0) b(k) = p_.lsb * std::nearbyint(b(k) / p_.lsb);
  }
  return b;
}

}  // namespace sc_rt
