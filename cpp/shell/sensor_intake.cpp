#include "sensor_intake.hpp"

#include <cmath>

namespace sc_rt {

SensorIntake::SensorIntake(const MekfParams& p, bool use_estimate, const Vec3& sigma0, std::size_t queue)
    : est_(p, use_estimate), sigma0_(sigma0), queue_(queue) {
  est_.reset(sigma0_);
}

void SensorIntake::offer_gyro(int64_t session, int64_t seq, const GyroSample& g) {
  if (!std::isfinite(g.t) || !g.omega.allFinite() || (g.output != kGyroRate && g.output != kGyroMeanRate)) {
    ++c_.invalid;
    return;
  }
  offer(Item{SensorKind::Gyro, session, seq, g, {}, {}, {}});
}

void SensorIntake::offer_star(int64_t session, int64_t seq, const StarSample& s) {
  if (!std::isfinite(s.t_exposure) || !std::isfinite(s.t_delivery) || s.t_exposure > s.t_delivery ||
      !s.sigma_BN.allFinite() || s.sigma_BN.norm() > 1.0 + 1e-9) {
    ++c_.invalid;
    return;
  }
  offer(Item{SensorKind::Star, session, seq, {}, s, {}, {}});
}

void SensorIntake::offer_tach(int64_t session, int64_t seq, const TachSample& s) {
  if (!std::isfinite(s.t) || !s.wheel_speed.allFinite()) {
    ++c_.invalid;
    return;
  }
  offer(Item{SensorKind::Tach, session, seq, {}, {}, s, {}});
}

void SensorIntake::offer_mag(int64_t session, int64_t seq, const MagSample& s) {
  if (!mag_mounted_ || !std::isfinite(s.t) || !s.B_S.allFinite()) {
    ++c_.invalid;
    return;
  }
  offer(Item{SensorKind::Mag, session, seq, {}, {}, {}, s});
}

double SensorIntake::time_of(const Item& it) {
  switch (it.kind) {
    case SensorKind::Gyro: return it.g.t;
    case SensorKind::Star: return it.s.t_delivery;
    case SensorKind::Tach: return it.c.t;
    case SensorKind::Mag: return it.b.t;
  }
  return 0.0;
}

void SensorIntake::offer(const Item& it) {
  // in time and nothing waiting before it: at once (arrival order is kept)
  if (following_ && it.session == session_ && queue_.empty() && time_of(it) <= horizon_) {
    apply(it);
    return;
  }
  if (queue_.full()) {  // full: the oldest goes (applied if it is the followed session's)
    const Item old = queue_.front();
    queue_.pop_front();
    if (following_ && old.session == session_) {
      apply(old);
    } else {
      ++c_.foreign;
    }
  }
  queue_.push_back(it);
}

void SensorIntake::use(int64_t session, double t) {
  if (!following_ || session != session_) {  // a new plant session: the estimator starts afresh
    following_ = true;
    session_ = session;
    started_ = ready_ = false;  // not ready until its first sample (seq 0: the run's start)
    for (int64_t& s : last_seq_) s = -1;
    est_.reset(sigma0_);
    field_B_ = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());  // none of this session's yet
  }
  horizon_ = t;
  // the waiting samples in order: this session's up to t applied, others' dropped,
  // from this session's first later sample on everything waits for a later state
  bool hold = false;
  queue_.retain([&](const Item& it) {
    if (it.session != session) {
      ++c_.foreign;
      return false;
    }
    if (hold || time_of(it) > t) {
      hold = true;
      return true;
    }
    apply(it);
    return false;
  });
}

void SensorIntake::apply(const Item& it) {
  const int k = static_cast<int>(it.kind);
  if (it.seq <= last_seq_[k]) {
    ++c_.out_of_order;
    return;
  }
  if (it.kind == SensorKind::Mag) {  // the field: no filter in it, a late joiner's too
    // Navigation::tick's B_B = R_SB' B_S (sensors.hpp magnetometer_field_B): the same numbers
    field_B_ = magnetometer_field_B(R_SB_, it.b.B_S);
    last_seq_[k] = it.seq;
    ++c_.used[k];
    return;
  }
  if (!started_) {  // the session's first sample: the run's start, or a late join
    // (use() reset the estimator for this session; a late joiner's is replaced at its first attitude)
    started_ = true;
    ready_ = it.seq == 0;
  }
  if (!ready_) {  // a late joiner: nothing until an attitude fixes the filter
    if (it.kind == SensorKind::Star) {
      est_.reset_at(it.s.t_exposure, it.s.sigma_BN);
      ready_ = true;
      last_seq_[k] = it.seq;
      ++c_.used[k];
    } else if (it.kind == SensorKind::Tach) {
      est_.tach(it.c);
      last_seq_[k] = it.seq;
      ++c_.used[k];
    } else {
      ++c_.before_fix;
    }
    return;
  }
  bool ok = true;
  switch (it.kind) {
    case SensorKind::Gyro: ok = est_.gyro(it.g); break;
    case SensorKind::Star: ok = est_.star(it.s); break;
    case SensorKind::Tach: est_.tach(it.c); break;
    case SensorKind::Mag: break;  // applied above
  }
  last_seq_[k] = it.seq;
  if (ok) {
    ++c_.used[k];
  } else {
    ++c_.too_old;
  }
}

}  // namespace sc_rt
