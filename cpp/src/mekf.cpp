#include "sc_rt/mekf.hpp"

#include <algorithm>
#include <cmath>
#include <type_traits>

#include "mekf_covariance.hpp"
#include "sc_rt/mrp.hpp"

namespace sc_rt {

namespace {
constexpr std::uint64_t kStreamInit = 5;  // the initial estimation error (sensors use 1-4)


// exp(-theta^) (Rodrigues; an = |theta|), as covariance_step's F.
Mat3 rotation_exp(const Vec3& theta, double an) {
  const Mat3 S = skew(theta);
  return an < 1e-8 ? Mat3(Mat3::Identity() - S + 0.5 * S * S)
                   : Mat3(Mat3::Identity() - (std::sin(an) / an) * S + ((1.0 - std::cos(an)) / (an * an)) * S * S);
}

// (I + S)^-1: the body rate from the bias-corrected gyro reading u is (I + S)^-1 u.
Mat3 calibration_inverse(const Eigen::Matrix<double, 9, 1>& c) {
  return (Mat3::Identity() + gyro_calibration_matrix(c)).inverse();
}

// Omega(w) with dS w = Omega(w) dc, dc = [ds1 ds2 ds3, dku1 dku2 dku3, dkl1 dkl2 dkl3].
Eigen::Matrix<double, 3, 9> calibration_jacobian(const Vec3& w) {
  Eigen::Matrix<double, 3, 9> O = Eigen::Matrix<double, 3, 9>::Zero();
  O(0, 0) = w(0);
  O(1, 1) = w(1);
  O(2, 2) = w(2);
  O(0, 3) = w(1);  // ku1
  O(0, 4) = w(2);  // ku2
  O(1, 5) = w(2);  // ku3
  O(1, 6) = w(0);  // kl1
  O(2, 7) = w(0);  // kl2
  O(2, 8) = w(1);  // kl3
  return O;
}
}  // namespace

Mat3 gyro_calibration_matrix(const Eigen::Matrix<double, 9, 1>& c) {
  Mat3 S;
  S << c(0), c(3), c(4),
       c(6), c(1), c(5),
       c(7), c(8), c(2);
  return S;
}

template <int N>
MekfT<N>::MekfT(const MekfParams& p) : p_(p) {
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

template <int N>
void MekfT<N>::reset(double t, const Vec3& sigma, const Vec3& bias) {
  cur_slot_ = -1;
  ahead_ = State{};
  ahead_.t = t;
  ahead_.sigma = sigma;
  ahead_.bias = bias;
  const double pa = p_.initial_attitude_sigma * p_.initial_attitude_sigma;
  const double pb = p_.initial_bias_sigma * p_.initial_bias_sigma;
  ahead_.P.diagonal().template head<6>() << pa, pa, pa, pb, pb, pb;
  if constexpr (N == 15) {  // the calibration: scale factors, then the six misalignments
    const double ps = p_.initial_scale_factor_sigma * p_.initial_scale_factor_sigma;
    const double pk = p_.initial_misalignment_sigma * p_.initial_misalignment_sigma;
    ahead_.P.diagonal().template tail<9>() << ps, ps, ps, pk, pk, pk, pk, pk, pk;
    ahead_.cal = p_.initial_calibration;  // the scenario's initial estimate (0: none)
  }
  omega_m_.setZero();
  have_gyro_ = false;
  innov_.setZero();
  nis_ = 0.0;
  last_exposure_ = t;
  updates_ = dropped_ = 0;
  head_ = size_ = 0;
}

template <int N>
void MekfT<N>::propagate_into(const State& in, State& out, const Vec3& omega_m, double dt,
                          bool covariance) const {
  if (!(dt > 0.0)) {
    if (&out != &in) out = in;
    return;
  }
  Vec3 theta;
  [[maybe_unused]] Mat3 Minv;  // N = 15: (I + S_est)^-1, once for the rate and for Phi
  [[maybe_unused]] Vec3 w;     // N = 15: the calibrated rate
  if constexpr (N == 6) {
    theta = (omega_m - in.bias) * dt;
  } else {
    Minv = calibration_inverse(in.cal);
    w = Minv * (omega_m - in.bias);
    theta = w * dt;
  }
  const double an = theta.norm();  // once for the attitude and Phi
  out.sigma = mrp_rotate_body_by(in.sigma, theta, an);
  out.bias = in.bias;
  out.t = in.t + dt;
  if constexpr (N == 15) out.cal = in.cal;
  if (!covariance) return;  // out.P left as it was (predict_to without the covariance)
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
  // P <- Phi P Phi' + Q with Phi = [[exp(-theta^), -dt I], [0, a I]], by 3x3 blocks
  // (no quantisation term: with its remainder carried, the angle error it leaves is bounded by
  // one quantum and does not grow with the number of samples; it is in R instead)
  const double q11 = p_.arw * p_.arw * dt + r2 * dt * dt * dt / 3.0;
  if constexpr (N == 6) {
    mekf_detail::covariance_step(in.P, out.P, theta, an, dt, a, q11, r2 * dt * dt / 2.0, r2 * dt + qb);
  } else {
    // the calibrating filter: Phi with the calibration columns, dense (docs/MODEL.md)
    MatN Phi = MatN::Identity();
    Phi.template topLeftCorner<3, 3>() = rotation_exp(theta, an);
    Phi.template block<3, 3>(0, 3) = -dt * Minv;
    Phi.template block<3, 9>(0, 6) = -dt * Minv * calibration_jacobian(w);
    Phi.template block<3, 3>(3, 3) = a * Mat3::Identity();
    MatN Q = MatN::Zero();
    Q.template topLeftCorner<3, 3>().diagonal().setConstant(q11);
    Q.template block<3, 3>(0, 3).diagonal().setConstant(-r2 * dt * dt / 2.0);
    Q.template block<3, 3>(3, 0).diagonal().setConstant(-r2 * dt * dt / 2.0);
    Q.template block<3, 3>(3, 3).diagonal().setConstant(r2 * dt + qb);
    const MatN P = Phi * in.P * Phi.transpose() + Q;
    out.P = 0.5 * (P + P.transpose());
  }
}

template <int N>
void MekfT<N>::update(State& s, const Vec3& sigma_m) {
  const Vec3 z = mrp_error_vector(sigma_m, s.sigma);
  // S stays invertible with noiseless sensors (R = 0, P -> 0): a floor of (1e-12 rad)^2
  const Mat3 S = s.P.template topLeftCorner<3, 3>() + R_ + 1e-24 * Mat3::Identity();
  const Eigen::LDLT<Mat3> Sf(S);
  const Eigen::Matrix<double, N, 3> PHt = s.P.template leftCols<3>();
  const Eigen::Matrix<double, N, 3> K = Sf.solve(PHt.transpose()).transpose();
  const VecN dx = K * z;
  MatN IKH = MatN::Identity();
  IKH.template leftCols<3>() -= K;
  const MatN P = IKH * s.P * IKH.transpose() + K * R_ * K.transpose();
  s.P = 0.5 * (P + P.transpose());
  s.sigma = mrp_rotate_body(s.sigma, dx.template head<3>());
  s.bias += dx.template segment<3>(3);
  if constexpr (N == 15) s.cal += dx.template tail<9>();
  innov_ = z;
  nis_ = z.dot(Sf.solve(z));
}

template <int N>
void MekfT<N>::gyro(double t, const Vec3& omega_m, int output) {
  // The new snapshot's slot (no division for the ring index): the oldest when the ring is
  // full, never the current state's (the newest, ring size >= 2).
  const std::size_t n = ring_.size();
  if (size_ == n) {
    if (++head_ == n) head_ = 0;
    --size_;
  }
  std::size_t w = head_ + size_;
  if (w >= n) w -= n;
  Snap& sn = ring_[w];
  // propagated from the current state straight into the snapshot, which becomes the current
  // state (no copy); over the interval the two samples bound: their mean
  const State& c = cur();
  sn.interval_rate = have_gyro_ && output == kGyroRate ? Vec3(0.5 * (omega_m_ + omega_m)) : omega_m;
  propagate_into(c, sn.s, sn.interval_rate, t - c.t);
  sn.omega_m = omega_m;
  sn.output = output;
  cur_slot_ = static_cast<long>(w);
  omega_m_ = omega_m;
  have_gyro_ = true;
  ++size_;
}

template <int N>
bool MekfT<N>::star(double t_exposure, const Vec3& sigma_m) {
  const std::size_t n = ring_.size();
  if (size_ == 0) {  // no gyro yet: only a measurement at or after now
    State& c = cur();  // ahead_
    if (t_exposure < c.t) {
      ++dropped_;
      return false;
    }
    propagate(c, omega_m_, t_exposure - c.t);
    update(c, sigma_m);
  } else {
    std::size_t j = size_;  // newest snapshot at or before the exposure
    while (j > 0 && ring_[(head_ + j - 1) % n].s.t > t_exposure) --j;
    if (j == 0) {
      ++dropped_;
      return false;
    }
    const double now = cur().t;  // before the snapshots change (the current one may be one)
    const std::size_t newest = (head_ + size_ - 1) % n;
    std::size_t k = (head_ + j - 1) % n;
    // The update at the exposure, then the later snapshots re-propagated, each straight from
    // the one before into its own slot (s: where the newest result is; no state copies).
    State* s = &ring_[k].s;
    bool newest_is_s = false;  // the newest snapshot holds s
    if (t_exposure - s->t > 0.0) {  // between snapshots (or after the newest): a scratch state
      // the held rate of snapshot k; an integrating gyro's next sample covers the exposure
      const Vec3& w_k = j < size_ && ring_[(head_ + j) % n].output == kGyroMeanRate
                            ? ring_[(head_ + j) % n].interval_rate : ring_[k].omega_m;
      propagate_into(*s, scratch_, w_k, t_exposure - s->t);
      s = &scratch_;
      update(*s, sigma_m);
      if (s->t == ring_[k].s.t) {
        ring_[k].s = *s;
        s = &ring_[k].s;
        newest_is_s = k == newest;
      }
    } else {  // at the snapshot: updated in place
      update(*s, sigma_m);
      newest_is_s = k == newest;
    }
    for (std::size_t m = j; m < size_; ++m) {  // re-propagate the later snapshots
      const std::size_t here = (head_ + m) % n;
      const double dt = ring_[here].s.t - s->t;
      // from the exposure: the rest of the interval, at the rate that first propagated it
      propagate_into(*s, ring_[here].s, ring_[here].interval_rate, dt);
      s = &ring_[here].s;
      newest_is_s = here == newest;
    }
    const double target = std::max(now, s->t);
    if (target - s->t > 0.0) {
      propagate_into(*s, ahead_, ring_[newest].omega_m, target - s->t);
      cur_slot_ = -1;
    } else if (newest_is_s) {  // the current state is the newest snapshot, already s
      cur_slot_ = static_cast<long>(newest);
    } else {
      ahead_ = *s;
      cur_slot_ = -1;
    }
  }
  last_exposure_ = std::max(last_exposure_, t_exposure);
  ++updates_;
  return true;
}

template <int N>
typename MekfT<N>::State MekfT<N>::predict(double t) const {
  State s = cur();
  propagate(s, omega_m_, t - s.t);
  return s;
}

template <int N>
const typename MekfT<N>::State& MekfT<N>::predict_to(double t, bool covariance) const {
  const State& c = cur();
  const double dt = t - c.t;
  if (!(dt > 0.0)) return c;  // propagate() would change nothing: no copy
  propagate_into(c, pred_, omega_m_, dt, covariance);
  return pred_;
}

template <int N>
Vec3 MekfT<N>::rate_estimate(const State& s) const {
  if constexpr (N == 6) {
    return omega_m_ - s.bias;
  } else {
    return calibration_inverse(s.cal) * (omega_m_ - s.bias);
  }
}

template class MekfT<6>;
template class MekfT<15>;

Vec3 initial_estimate(std::uint64_t seed, double sigma, const Vec3& sigma_true0) {
  Rng rng(seed, kStreamInit);
  Vec3 d;
  for (int k = 0; k < 3; ++k) d(k) = sigma * rng.normal();
  return mrp_rotate_body(sigma_true0, -d);
}

Estimator::Estimator(const MekfParams& p, bool use_estimate)
    : mekf_(p),
      cal_(p.calibrate ? std::make_unique<MekfCal>(p) : nullptr),
      degraded_after_(p.degraded_after),
      use_estimate_(use_estimate) {}

void Estimator::reset(const Vec3& sigma0) {
  with([&](auto& f) { f.reset(0.0, sigma0, Vec3::Zero()); });
  wheel_.setZero();
  have_tach_ = false;
  updated_ = false;
}

void Estimator::reset_at(double t, const Vec3& sigma) {
  with([&](auto& f) { f.reset(t, sigma, Vec3::Zero()); });
  updated_ = false;
}

bool Estimator::gyro(const GyroSample& g) {
  return with([&](auto& f) {
    if (!(g.t >= f.state().t)) return false;
    f.gyro(g.t, g.omega, g.output);
    return true;
  });
}

bool Estimator::star(const StarSample& s) {
  updated_ = true;
  return with([&](auto& f) { return f.star(s.t_exposure, s.sigma_BN); });
}

void Estimator::tach(const TachSample& s) {
  wheel_ = s.wheel_speed;
  have_tach_ = true;
}

long Estimator::updates() const { return cal_ ? cal_->updates() : mekf_.updates(); }
long Estimator::dropped() const { return cal_ ? cal_->dropped() : mekf_.dropped(); }

Measurement Estimator::measure(const Measurement& truth, NavTelemetry* tel) {
  return with([&](auto& f) {
    const double t = truth.t;
    const auto& s = f.predict_to(t, tel != nullptr);  // the covariance only for the telemetry
    if (tel) {
      const bool degraded = t - f.last_update_exposure() > degraded_after_;
      tel->sigma_est = s.sigma;
      tel->bias_est = s.bias;
      tel->P_diag = s.P.diagonal().template head<6>();
      const double nan = std::numeric_limits<double>::quiet_NaN();
      tel->innovation = updated_ ? f.innovation() : Vec3::Constant(nan);
      tel->nis = updated_ ? f.nis() : nan;
      tel->flags = degraded ? FLAG_NAV_DEGRADED : 0;
      if constexpr (std::decay_t<decltype(s.P)>::RowsAtCompileTime == 15) {  // the calibrating filter
        tel->cal_est = s.cal;
        tel->cal_3sigma = 3.0 * s.P.diagonal().template tail<9>().cwiseSqrt();
      }
      updated_ = false;  // the next row reports the next update
    }
    if (!use_estimate_) return truth;
    return Measurement{t, s.sigma, f.rate_estimate(s), have_tach_ ? wheel_ : truth.wheel_speed};
  });
}

Navigation::Navigation(const NavConfig& c)
    : c_(c), sensors_(c.sensors), est_(c.mekf, c.use_estimate) {
  reset(PlantState{});
}

void Navigation::reset(const PlantState& x0) {
  sensors_.reset();
  field_B_ = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  est_.reset(initial_estimate(c_.sensors.seed, c_.mekf.initial_attitude_sigma, x0.sigma_BN));
}

void Navigation::tick(std::int64_t i, double t, const PlantState& x, const Vec3* B_B) {
  sensors_.tick(i, t, x, B_B);
  if (sensors_.gyro_new()) est_.gyro(sensors_.gyro());
  if (sensors_.star_new()) est_.star(sensors_.star());
  if (sensors_.tach_new()) est_.tach(sensors_.tach());
  if (sensors_.mag_new()) field_B_ = magnetometer_field_B(c_.sensors.magnetometer.R_SB, sensors_.mag().B_S);
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
