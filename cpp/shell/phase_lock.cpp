#include "phase_lock.hpp"

#include <algorithm>
#include <stdexcept>

namespace sc_rt {

PhaseLock::PhaseLock(int64_t period_ns, double phase_offset_us, int64_t start_ns)
    : period_ns_(period_ns),
      offset_us_(phase_offset_us),
      deadline_(start_ns + period_ns),
      guard_ns_(phase_offset_us * 1e3) {
  if (period_ns <= 0) throw std::invalid_argument("PhaseLock: period_ns must be > 0");
}

int64_t PhaseLock::advance(bool used_fresh, int64_t rx_ns, int64_t now_ns) {
  const int64_t P = period_ns_;
  deadline_ += P;
  if (offset_us_ >= 0.0) {
    // The guard after an arrival adapts to the plant's jitter: a step that
    // found no new state (it came after the wake-up) widens it by a quarter;
    // fresh steps shrink it by 1 % back toward the phase offset.
    const double P2 = 0.5 * double(P);
    guard_ns_ = used_fresh ? std::max(0.99 * guard_ns_, offset_us_ * 1e3)
                           : std::min(1.25 * guard_ns_ + 5e3, P2);
  }
  if (offset_us_ >= 0.0 && used_fresh) {
    // phase-locked loop on the state arrivals: move the next deadline a
    // quarter of the way toward (arrival + guard), modulo the period
    const int64_t target = rx_ns + int64_t(guard_ns_);
    int64_t err = (deadline_ - target) % P;
    if (err < 0) err += P;
    if (err > P / 2) err -= P;
    deadline_ -= err / 4;
  }
  // after a long stall, skip the missed periods instead of bursting
  if (now_ns > deadline_) deadline_ += ((now_ns - deadline_) / P + 1) * P;
  return deadline_;
}

}  // namespace sc_rt
