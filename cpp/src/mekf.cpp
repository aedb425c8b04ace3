#include "sc_rt/mekf.hpp"

#include <algorithm>
#include <cmath>

#include "sc_rt/mrp.hpp"

namespace sc_rt {

namespace {
constexpr std::uint64_t kStreamInit = 5;  // the initial estimation error (sensors use 1-4)

// exp(-v^) by Rodrigues' formula, a = |v|.
inline Mat3 rot_exp_minus(const Vec3& v, double a) {
  const Mat3 S = skew(v);
  if (a < 1e-8) return Mat3::Identity() - S + 0.5 * S * S;
  return Mat3::Identity() - (std::sin(a) / a) * S + ((1.0 - std::cos(a)) / (a * a)) * S * S;
}
}  // namespace

Mekf::Mekf(const MekfParams& p) : p_(p) {
  const Mat3 A = boresight_frame(p.boresight);
  const Vec3 d(p.sigma_cross * p.sigma_cross, p.sigma_cross * p.sigma_cross,
               p.sigma_boresight * p.sigma_boresight);
  // the gyro's quantisation leaves the propagated attitude off by the carried remainder,
  // uniform in one quantum per axis: variance q^2 / 12, added to the fix's noise
  R_ = A * d.asDiagonal() * A.transpose() +
       (p.quantization * p.quantization / 12.0) * Mat3::Identity();
  ring_.resize(static_cast<std::size_t>(std::max(2, p.history)));
  reset(0.0, Vec3::Zero(), Vec3::Zero());
}

void Mekf::reset(double t, const Vec3& sigma, const Vec3& bias) {
  cur_ = MekfState{};
  cur_.t = t;
  cur_.sigma = sigma;
  cur_.bias = bias;
  const double pa = p_.initial_attitude_sigma * p_.initial_attitude_sigma;
  const double pb = p_.initial_bias_sigma * p_.initial_bias_sigma;
  cur_.P.diagonal() << pa, pa, pa, pb, pb, pb;
  omega_m_.setZero();
  have_gyro_ = false;
  innov_.setZero();
  nis_ = 0.0;
  last_exposure_ = t;
  updates_ = dropped_ = 0;
  head_ = size_ = 0;
}

void Mekf::propagate(MekfState& s, const Vec3& omega_m, double dt) const {
  if (!(dt > 0.0)) return;
  const Vec3 theta = (omega_m - s.bias) * dt;
  const double an = theta.norm();  // once for the attitude and Phi
  s.sigma = mrp_rotate_body_by(s.sigma, theta, an);
  s.t += dt;
  const Mat3 F11 = rot_exp_minus(theta, an);
  double a = 1.0, qb = 0.0;
  if (p_.bias_sigma > 0.0) {
    // exp(-dt / tau) of the last few dt (the gyro's period comes out of the sample times as a
    // handful of values a bit apart, and the re-propagation after a delivery has its own)
    int j = 0;
    while (j < kGmCache && gm_dt_[j] != dt) ++j;
    if (j == kGmCache) {
      j = gm_next_;
      gm_next_ = (gm_next_ + 1) % kGmCache;
      gm_dt_[j] = dt;
      gm_a_[j] = std::exp(-dt / p_.bias_tau);
    }
    a = gm_a_[j];
    qb = p_.bias_sigma * p_.bias_sigma * (1.0 - a * a);
  }
  const double r2 = p_.rrw * p_.rrw;
  // P <- Phi P Phi' + Q with Phi = [[F11, -dt I], [0, a I]], by blocks.
  const Mat3 P11 = s.P.topLeftCorner<3, 3>(), P12 = s.P.topRightCorner<3, 3>(),
             P22 = s.P.bottomRightCorner<3, 3>();
  const Mat3 T1 = F11 * P11 - dt * P12.transpose();  // rows 1-3 of Phi P, cols 1-3
  const Mat3 T2 = F11 * P12 - dt * P22;              // rows 1-3 of Phi P, cols 4-6
  Mat3 N11 = T1 * F11.transpose() - dt * T2;
  Mat3 N12 = a * T2;
  Mat3 N22 = (a * a) * P22;
  // (no quantisation term: with its remainder carried, the angle error it leaves is bounded by
  // one quantum and does not grow with the number of samples; it is in R instead)
  const double q11 = p_.arw * p_.arw * dt + r2 * dt * dt * dt / 3.0;
  N11.diagonal().array() += q11;
  N12.diagonal().array() -= r2 * dt * dt / 2.0;
  N22.diagonal().array() += r2 * dt + qb;
  s.P.topLeftCorner<3, 3>() = 0.5 * (N11 + N11.transpose());
  s.P.topRightCorner<3, 3>() = N12;
  s.P.bottomLeftCorner<3, 3>() = N12.transpose();
  s.P.bottomRightCorner<3, 3>() = 0.5 * (N22 + N22.transpose());
}

void Mekf::update(MekfState& s, const Vec3& sigma_m) {
  const Vec3 z = mrp_error_vector(sigma_m, s.sigma);
  // S stays invertible with noiseless sensors (R = 0, P -> 0): a floor of (1e-12 rad)^2
  const Mat3 S = s.P.topLeftCorner<3, 3>() + R_ + 1e-24 * Mat3::Identity();
  const Eigen::LDLT<Mat3> Sf(S);
  const Eigen::Matrix<double, 6, 3> PHt = s.P.leftCols<3>();
  const Eigen::Matrix<double, 6, 3> K = Sf.solve(PHt.transpose()).transpose();
  const Vec6 dx = K * z;
  Mat6 IKH = Mat6::Identity();
  IKH.leftCols<3>() -= K;
  const Mat6 P = IKH * s.P * IKH.transpose() + K * R_ * K.transpose();
  s.P = 0.5 * (P + P.transpose());
  s.sigma = mrp_rotate_body(s.sigma, dx.head<3>());
  s.bias += dx.tail<3>();
  innov_ = z;
  nis_ = z.dot(Sf.solve(z));
}

void Mekf::gyro(double t, const Vec3& omega_m) {
  // over the interval the two samples bound: their mean (the held sample beyond the newest)
  propagate(cur_, have_gyro_ ? Vec3(0.5 * (omega_m_ + omega_m)) : omega_m, t - cur_.t);
  omega_m_ = omega_m;
  have_gyro_ = true;
  // the snapshot, written in place (no temporary Snap, no division for the ring index)
  const std::size_t n = ring_.size();
  if (size_ == n) {
    if (++head_ == n) head_ = 0;
    --size_;
  }
  std::size_t w = head_ + size_;
  if (w >= n) w -= n;
  Snap& sn = ring_[w];
  sn.s = cur_;
  sn.omega_m = omega_m;
  ++size_;
}

bool Mekf::star(double t_exposure, const Vec3& sigma_m) {
  const std::size_t n = ring_.size();
  if (size_ == 0) {  // no gyro yet: only a measurement at or after now
    if (t_exposure < cur_.t) {
      ++dropped_;
      return false;
    }
    propagate(cur_, omega_m_, t_exposure - cur_.t);
    update(cur_, sigma_m);
  } else {
    std::size_t j = size_;  // newest snapshot at or before the exposure
    while (j > 0 && ring_[(head_ + j - 1) % n].s.t > t_exposure) --j;
    if (j == 0) {
      ++dropped_;
      return false;
    }
    std::size_t k = (head_ + j - 1) % n;
    MekfState s = ring_[k].s;
    propagate(s, ring_[k].omega_m, t_exposure - s.t);
    update(s, sigma_m);
    if (s.t == ring_[k].s.t) ring_[k].s = s;
    for (std::size_t m = j; m < size_; ++m) {  // re-propagate the later snapshots
      const std::size_t prev = (head_ + m - 1) % n, here = (head_ + m) % n;
      propagate(s, Vec3(0.5 * (ring_[prev].omega_m + ring_[here].omega_m)), ring_[here].s.t - s.t);
      ring_[here].s = s;
    }
    const double target = std::max(cur_.t, s.t);
    propagate(s, ring_[(head_ + size_ - 1) % n].omega_m, target - s.t);
    cur_ = s;
  }
  last_exposure_ = std::max(last_exposure_, t_exposure);
  ++updates_;
  return true;
}

MekfState Mekf::predict(double t) const {
  MekfState s = cur_;
  propagate(s, omega_m_, t - s.t);
  return s;
}

const MekfState& Mekf::predict_to(double t, bool covariance) const {
  const double dt = t - cur_.t;
  if (!(dt > 0.0)) return cur_;  // propagate() would change nothing: no copy
  MekfState& tmp = pred_;
  tmp.t = cur_.t;
  tmp.sigma = cur_.sigma;
  tmp.bias = cur_.bias;
  if (covariance) {
    tmp.P = cur_.P;
    propagate(tmp, omega_m_, dt);
  } else {  // the attitude as propagate() moves it, the covariance left alone
    const Vec3 theta = (omega_m_ - tmp.bias) * dt;
    tmp.sigma = mrp_rotate_body_by(tmp.sigma, theta, theta.norm());
    tmp.t += dt;
  }
  return tmp;
}

Vec3 initial_estimate(std::uint64_t seed, double sigma, const Vec3& sigma_true0) {
  Rng rng(seed, kStreamInit);
  Vec3 d;
  for (int k = 0; k < 3; ++k) d(k) = sigma * rng.normal();
  return mrp_rotate_body(sigma_true0, -d);
}

Estimator::Estimator(const MekfParams& p, bool use_estimate)
    : mekf_(p), p_(p), use_estimate_(use_estimate) {}

void Estimator::reset(const Vec3& sigma0) {
  mekf_.reset(0.0, sigma0, Vec3::Zero());
  wheel_.setZero();
  have_tach_ = false;
  updated_ = false;
}

void Estimator::reset_at(double t, const Vec3& sigma) {
  mekf_.reset(t, sigma, Vec3::Zero());
  updated_ = false;
}

bool Estimator::gyro(const GyroSample& g) {
  if (!(g.t >= mekf_.state().t)) return false;
  mekf_.gyro(g.t, g.omega);
  return true;
}

bool Estimator::star(const StarSample& s) {
  updated_ = true;
  return mekf_.star(s.t_exposure, s.sigma_BN);
}

void Estimator::tach(const TachSample& s) {
  wheel_ = s.wheel_speed;
  have_tach_ = true;
}

Measurement Estimator::measure(const Measurement& truth, NavTelemetry* tel) {
  const double t = truth.t;
  const MekfState& s = mekf_.predict_to(t, tel != nullptr);  // the covariance only for the telemetry
  if (tel) {
    const bool degraded = t - mekf_.last_update_exposure() > p_.degraded_after;
    tel->sigma_est = s.sigma;
    tel->bias_est = s.bias;
    tel->P_diag = s.P.diagonal();
    const double nan = std::numeric_limits<double>::quiet_NaN();
    tel->innovation = updated_ ? mekf_.innovation() : Vec3::Constant(nan);
    tel->nis = updated_ ? mekf_.nis() : nan;
    tel->flags = degraded ? FLAG_NAV_DEGRADED : 0;
    updated_ = false;  // the next row reports the next update
  }
  if (!use_estimate_) return truth;
  return Measurement{t, s.sigma, Vec3(mekf_.rate() - s.bias), have_tach_ ? wheel_ : truth.wheel_speed};
}

Navigation::Navigation(const NavConfig& c)
    : c_(c), sensors_(c.sensors), est_(c.mekf, c.use_estimate) {
  reset(PlantState{});
}

void Navigation::reset(const PlantState& x0) {
  sensors_.reset();
  est_.reset(initial_estimate(c_.sensors.seed, c_.mekf.initial_attitude_sigma, x0.sigma_BN));
}

void Navigation::tick(std::int64_t i, double t, const PlantState& x) {
  sensors_.tick(i, t, x);
  if (sensors_.gyro_new()) est_.gyro(sensors_.gyro());
  if (sensors_.star_new()) est_.star(sensors_.star());
  if (sensors_.tach_new()) est_.tach(sensors_.tach());
}

Measurement Navigation::measure(double t, const PlantState& x, NavTelemetry* tel) {
  const Measurement m = est_.measure(Measurement{t, x.sigma_BN, x.omega_BN_B, x.wheel_speed}, tel);
  if (tel) {
    tel->bias_true = sensors_.gyro_bias();
    tel->att_error = mrp_error_vector(x.sigma_BN, tel->sigma_est);
  }
  return m;
}

}  // namespace sc_rt
