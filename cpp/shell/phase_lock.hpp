// The real-time controller's scheduler: absolute deadlines one period apart,
// phase-locked to the arrivals of plant states, with an adaptive guard after
// the arrival. Policy only: no I/O and no clock of its own (the caller passes
// monotonic times in ns and sleeps until deadline()).
#pragma once
#include <cstdint>

namespace sc_rt {

class PhaseLock {
 public:
  // period_ns > 0; phase_offset_us: the least guard after an arrival [us]
  // (< 0: free-running, no lock); start_ns: now; the first deadline is one
  // period after it.
  PhaseLock(int64_t period_ns, double phase_offset_us, int64_t start_ns);

  // After the step woken at deadline(): whether it used a new state, the
  // arrival time of the state it used, and the clock after the step.
  // Returns the next deadline, never earlier than now_ns.
  //  - guard: a step without a new state (it came after the wake-up) widens
  //    it to min(1.25 guard + 5 us, period / 2); a fresh step shrinks it by
  //    1 % back toward phase_offset_us;
  //  - lock (fresh steps only): the next deadline moves a quarter of the way
  //    toward (arrival + guard), modulo the period;
  //  - after a stall, the missed periods are skipped instead of bursting.
  int64_t advance(bool used_fresh, int64_t rx_ns, int64_t now_ns);

  int64_t deadline() const { return deadline_; }
  double guard_ns() const { return guard_ns_; }
  int64_t period_ns() const { return period_ns_; }
  double phase_offset_us() const { return offset_us_; }
  bool locked() const { return offset_us_ >= 0.0; }

 private:
  int64_t period_ns_;
  double offset_us_;
  int64_t deadline_;
  double guard_ns_;
};

}  // namespace sc_rt
