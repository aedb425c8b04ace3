#include "sensor_intake.hpp"

#include <cmath>

namespace sc_rt {

SensorIntake::SensorIntake(const MekfParams& p, bool use_estimate, const Vec3& sigma0, std::size_t queue)
    : est_(p, use_estimate), p_(p), sigma0_(sigma0), queue_(queue == 0 ? 1 : queue) {
  est_.reset(sigma0_);
}

void SensorIntake::offer_gyro(int64_t session, int64_t seq, const GyroSample& g) {
  if (!std::isfinite(g.t) || !g.omega.allFinite()) {
    ++c_.invalid;
    return;
  }
  offer(Item{SensorKind::Gyro, session, seq, g, {}, {}});
}

void SensorIntake::offer_star(int64_t session, int64_t seq, const StarSample& s) {
  if (!std::isfinite(s.t_exposure) || !std::isfinite(s.t_delivery) || s.t_exposure > s.t_delivery ||
      !s.sigma_BN.allFinite() || s.sigma_BN.norm() > 1.0 + 1e-9) {
    ++c_.invalid;
    return;
  }
  offer(Item{SensorKind::Star, session, seq, {}, s, {}});
}

void SensorIntake::offer_tach(int64_t session, int64_t seq, const TachSample& s) {
  if (!std::isfinite(s.t) || !s.wheel_speed.allFinite()) {
    ++c_.invalid;
    return;
  }
  offer(Item{SensorKind::Tach, session, seq, {}, {}, s});
}

void SensorIntake::offer(const Item& it) {
  if (following_ && it.session == session_) {
    apply(it);
    return;
  }
  const std::size_t n = queue_.size();
  if (q_size_ == n) {  // full: the oldest goes (of a session nobody follows)
    q_head_ = (q_head_ + 1) % n;
    --q_size_;
    ++c_.foreign;
  }
  queue_[(q_head_ + q_size_) % n] = it;
  ++q_size_;
}

void SensorIntake::follow(int64_t session) {
  if (following_ && session == session_) return;
  following_ = true;
  session_ = session;
  started_ = ready_ = false;
  for (int64_t& s : last_seq_) s = -1;
  est_.reset(sigma0_);
  const std::size_t n = queue_.size();
  for (std::size_t k = 0; k < q_size_; ++k) {
    const Item& it = queue_[(q_head_ + k) % n];
    if (it.session == session) {
      apply(it);
    } else {
      ++c_.foreign;
    }
  }
  q_head_ = q_size_ = 0;
  // no sample of it yet: not ready until its first (seq 0: the run's start)
}

void SensorIntake::apply(const Item& it) {
  const int k = static_cast<int>(it.kind);
  if (it.seq <= last_seq_[k]) {
    ++c_.out_of_order;
    return;
  }
  if (!started_) {  // the session's first sample: the run's start, or a late join
    started_ = true;
    ready_ = it.seq == 0;
    if (!ready_) est_.reset(sigma0_);  // replaced at the first attitude
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
  }
  last_seq_[k] = it.seq;
  if (ok) {
    ++c_.used[k];
  } else {
    ++c_.too_old;
  }
}

}  // namespace sc_rt
