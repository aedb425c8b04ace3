#include "sc_rt/mekf.hpp"

#include <algorithm>
#include <cmath>
#if defined(__SSE2__) && !defined(SC_RT_EIGEN_COVARIANCE)
#define SC_RT_SSE2_COVARIANCE 1
#include <emmintrin.h>
#endif

#include "sc_rt/mrp.hpp"

namespace sc_rt {

namespace {
constexpr std::uint64_t kStreamInit = 5;  // the initial estimation error (sensors use 1-4)

// The covariance step of Mekf::propagate (see there):
//   F = exp(-theta^) = I - (sin a / a) theta^ + ((1 - cos a) / a^2) theta^ theta^, a = |theta|
//   (a < 1e-8: I - theta^ + theta^ theta^ / 2)
//   T1 = F P11 - dt P12', T2 = F P12 - dt P22 (rows 1-3 of Phi P)
//   P11 <- sym(T1 F' - dt T2 + q11 I), P12 <- a T2 - q12 I, P22 <- sym(a^2 P22 + q22 I)
// sym(N) = (N + N') / 2.
#ifdef SC_RT_SSE2_COVARIANCE
// By hand in SSE2, bit for bit in the order of the Eigen expressions it replaced (kept below
// for other targets; -DSC_RT_EIGEN_COVARIANCE selects them here too, to compare): Eigen
// evaluates a 3x3 product column by column, rows 0-1 as one packet summed in k order,
// ((a0 b0 + a1 b1) + a2 b2), row 2 as a scalar reduction, a0 b0 + (a1 b1 + a2 b2). Here the
// 3x3 temporaries stay in registers (Eigen stores and reloads them: ~15 % of the propagation).
// A 3x3 M is kept as lo[j] = rows 0-1 of column j, hi[j] = row 2.
struct M3 {
  __m128d lo[3];
  double hi[3];
};
inline double row0(__m128d v) { return _mm_cvtsd_f64(v); }
inline double row1(__m128d v) { return _mm_cvtsd_f64(_mm_unpackhi_pd(v, v)); }
inline double coeff(const M3& m, int i, int j) { return i == 0 ? row0(m.lo[j]) : i == 1 ? row1(m.lo[j]) : m.hi[j]; }
// C = A B, B given by its coefficients b(k, j).
template <class B>
inline void mul(const M3& A, B b, M3& C) {
  for (int j = 0; j < 3; ++j) {
    const double b0 = b(0, j), b1 = b(1, j), b2 = b(2, j);
    __m128d r = _mm_mul_pd(A.lo[0], _mm_set1_pd(b0));
    r = _mm_add_pd(_mm_mul_pd(A.lo[1], _mm_set1_pd(b1)), r);
    r = _mm_add_pd(_mm_mul_pd(A.lo[2], _mm_set1_pd(b2)), r);
    C.lo[j] = r;
    C.hi[j] = A.hi[0] * b0 + (A.hi[1] * b1 + A.hi[2] * b2);
  }
}

inline void covariance_step(const Mat6& Pin, Mat6& Pout, const Vec3& v, double an, double dt, double a,
                            double q11, double q12, double q22) {
  const double x = v.x(), y = v.y(), z = v.z();
  const double S[3][3] = {{0.0, -z, y}, {z, 0.0, -x}, {-y, x, 0.0}};
  double c1 = 1.0, c2 = 0.5;
  const bool small = an < 1e-8;
  if (!small) {
    c1 = std::sin(an) / an;
    c2 = (1.0 - std::cos(an)) / (an * an);
  }
  M3 cS, SS, F;
  for (int j = 0; j < 3; ++j) {
    cS.lo[j] = _mm_set_pd(c2 * S[1][j], c2 * S[0][j]);
    cS.hi[j] = c2 * S[2][j];
  }
  mul(cS, [&](int k, int j) { return S[k][j]; }, SS);
  for (int j = 0; j < 3; ++j) {
    double f[3];
    for (int i = 0; i < 3; ++i) f[i] = ((i == j ? 1.0 : 0.0) - (small ? S[i][j] : c1 * S[i][j])) + coeff(SS, i, j);
    F.lo[j] = _mm_set_pd(f[1], f[0]);
    F.hi[j] = f[2];
  }
  const double* Pd = Pin.data();  // column-major, outer stride 6 (every read before the writes: Pout may be Pin)
  auto p = [Pd](int i, int j) { return Pd[i + 6 * j]; };
  M3 T1, T2, N11;
  mul(F, [&](int k, int j) { return p(k, j); }, T1);
  mul(F, [&](int k, int j) { return p(k, 3 + j); }, T2);
  const __m128d vdt = _mm_set1_pd(dt);
  for (int j = 0; j < 3; ++j) {
    T1.lo[j] = _mm_sub_pd(T1.lo[j], _mm_mul_pd(vdt, _mm_set_pd(p(j, 4), p(j, 3))));  // - dt P12'
    T1.hi[j] = T1.hi[j] - dt * p(j, 5);
    T2.lo[j] = _mm_sub_pd(T2.lo[j], _mm_mul_pd(vdt, _mm_loadu_pd(Pd + 3 + 6 * (3 + j))));  // - dt P22
    T2.hi[j] = T2.hi[j] - dt * p(5, 3 + j);
  }
  mul(T1, [&](int k, int j) { return coeff(F, j, k); }, N11);  // T1 F'
  const double aa = a * a;
  double n11[3][3], n12[3][3], n22[3][3];
  const __m128d va = _mm_set1_pd(a), vaa = _mm_set1_pd(aa);
  for (int j = 0; j < 3; ++j) {
    const __m128d l = _mm_sub_pd(N11.lo[j], _mm_mul_pd(vdt, T2.lo[j]));
    n11[0][j] = row0(l);
    n11[1][j] = row1(l);
    n11[2][j] = N11.hi[j] - dt * T2.hi[j];
    const __m128d m12 = _mm_mul_pd(va, T2.lo[j]);
    n12[0][j] = row0(m12);
    n12[1][j] = row1(m12);
    n12[2][j] = a * T2.hi[j];
    const __m128d m22 = _mm_mul_pd(vaa, _mm_loadu_pd(Pd + 3 + 6 * (3 + j)));
    n22[0][j] = row0(m22);
    n22[1][j] = row1(m22);
    n22[2][j] = aa * p(5, 3 + j);
  }
  for (int i = 0; i < 3; ++i) {
    n11[i][i] += q11;
    n12[i][i] -= q12;
    n22[i][i] += q22;
  }
  double* Pw = Pout.data();
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      Pw[i + 6 * j] = 0.5 * (n11[i][j] + n11[j][i]);
      Pw[i + 6 * (3 + j)] = n12[i][j];
      Pw[(3 + j) + 6 * i] = n12[i][j];
      Pw[(3 + i) + 6 * (3 + j)] = 0.5 * (n22[i][j] + n22[j][i]);
    }
}
#else
inline void covariance_step(const Mat6& P, Mat6& Pout, const Vec3& theta, double an, double dt, double a,
                            double q11, double q12, double q22) {
  const Mat3 S = skew(theta);
  const Mat3 F11 = an < 1e-8 ? Mat3(Mat3::Identity() - S + 0.5 * S * S)
                             : Mat3(Mat3::Identity() - (std::sin(an) / an) * S +
                                    ((1.0 - std::cos(an)) / (an * an)) * S * S);
  const Mat3 P11 = P.topLeftCorner<3, 3>(), P12 = P.topRightCorner<3, 3>(), P22 = P.bottomRightCorner<3, 3>();
  const Mat3 T1 = F11 * P11 - dt * P12.transpose();
  const Mat3 T2 = F11 * P12 - dt * P22;
  Mat3 N11 = T1 * F11.transpose() - dt * T2;
  Mat3 N12 = a * T2;
  Mat3 N22 = (a * a) * P22;
  N11.diagonal().array() += q11;
  N12.diagonal().array() -= q12;
  N22.diagonal().array() += q22;
  Pout.topLeftCorner<3, 3>() = 0.5 * (N11 + N11.transpose());
  Pout.topRightCorner<3, 3>() = N12;
  Pout.bottomLeftCorner<3, 3>() = N12.transpose();
  Pout.bottomRightCorner<3, 3>() = 0.5 * (N22 + N22.transpose());
}
#endif
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
  cur_slot_ = -1;
  ahead_ = MekfState{};
  ahead_.t = t;
  ahead_.sigma = sigma;
  ahead_.bias = bias;
  const double pa = p_.initial_attitude_sigma * p_.initial_attitude_sigma;
  const double pb = p_.initial_bias_sigma * p_.initial_bias_sigma;
  ahead_.P.diagonal() << pa, pa, pa, pb, pb, pb;
  omega_m_.setZero();
  have_gyro_ = false;
  innov_.setZero();
  nis_ = 0.0;
  last_exposure_ = t;
  updates_ = dropped_ = 0;
  head_ = size_ = 0;
}

void Mekf::propagate_into(const MekfState& in, MekfState& out, const Vec3& omega_m, double dt,
                          bool covariance) const {
  if (!(dt > 0.0)) {
    if (&out != &in) out = in;
    return;
  }
  const Vec3 theta = (omega_m - in.bias) * dt;
  const double an = theta.norm();  // once for the attitude and Phi
  out.sigma = mrp_rotate_body_by(in.sigma, theta, an);
  out.bias = in.bias;
  out.t = in.t + dt;
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
  covariance_step(in.P, out.P, theta, an, dt, a, q11, r2 * dt * dt / 2.0, r2 * dt + qb);
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

void Mekf::gyro(double t, const Vec3& omega_m, int output) {
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
  const MekfState& c = cur();
  sn.interval_rate = have_gyro_ && output == kGyroRate ? Vec3(0.5 * (omega_m_ + omega_m)) : omega_m;
  propagate_into(c, sn.s, sn.interval_rate, t - c.t);
  sn.omega_m = omega_m;
  sn.output = output;
  cur_slot_ = static_cast<long>(w);
  omega_m_ = omega_m;
  have_gyro_ = true;
  ++size_;
}

bool Mekf::star(double t_exposure, const Vec3& sigma_m) {
  const std::size_t n = ring_.size();
  if (size_ == 0) {  // no gyro yet: only a measurement at or after now
    MekfState& c = cur();  // ahead_
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
    MekfState* s = &ring_[k].s;
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

MekfState Mekf::predict(double t) const {
  MekfState s = cur();
  propagate(s, omega_m_, t - s.t);
  return s;
}

const MekfState& Mekf::predict_to(double t, bool covariance) const {
  const MekfState& c = cur();
  const double dt = t - c.t;
  if (!(dt > 0.0)) return c;  // propagate() would change nothing: no copy
  propagate_into(c, pred_, omega_m_, dt, covariance);
  return pred_;
}

Vec3 initial_estimate(std::uint64_t seed, double sigma, const Vec3& sigma_true0) {
  Rng rng(seed, kStreamInit);
  Vec3 d;
  for (int k = 0; k < 3; ++k) d(k) = sigma * rng.normal();
  return mrp_rotate_body(sigma_true0, -d);
}

Estimator::Estimator(const MekfParams& p, bool use_estimate)
    : mekf_(p), degraded_after_(p.degraded_after), use_estimate_(use_estimate) {}

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
  mekf_.gyro(g.t, g.omega, g.output);
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
    const bool degraded = t - mekf_.last_update_exposure() > degraded_after_;
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
