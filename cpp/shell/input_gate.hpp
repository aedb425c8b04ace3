// The controller shell's input gate: which plant session the controller
// follows, which states it applies, which it answers again and which it
// rejects, counted by kind. Policy only: no I/O, no clock (the caller passes
// the monotonic arrival time in ns), no LCM types (the caller decodes).
//
// Threads: offer(), malformed() and trailing_bytes() mutate the gate and
// need the caller's lock; counts() may be read from any thread (atomic).
#pragma once
#include <atomic>
#include <cstdint>

namespace sc_rt {

// What the shell does with one received message.
enum class GateVerdict {
  Accept,            // apply: the newest state of the followed session
  Adopt,             // apply, and a new plant session: re-engage the law
  Duplicate,         // same seq as the newest: re-send the previous answer
  OutOfOrder,        // older seq than the newest: drop
  SeqJump,           // more than kSeqWindow ahead of the newest, unconfirmed: drop (see offer)
  ForeignSession,    // another session while ours is alive: drop
  InvalidCandidate,  // another session after ours went silent, but invalid: drop
  Malformed,         // did not decode: drop
  TrailingBytes,     // decoded, followed by extra bytes: drop
};

const char* verdict_name(GateVerdict v);

// A snapshot of the gate's counters (the names of the controller's summary).
struct GateCounts {
  int64_t received = 0;
  int64_t malformed = 0;        // decode failed (empty, truncated, random, wrong type)
  int64_t trailing_bytes = 0;   // valid message followed by extra bytes
  int64_t duplicate = 0;        // same seq as the newest
  int64_t out_of_order = 0;     // older seq than the newest
  int64_t invalid_state = 0;    // non-finite or out-of-range fields (applied or not)
  int64_t foreign_session = 0;  // a state from another plant while ours is alive
  int64_t sessions_adopted = 0; // a new plant adopted after ours went silent
  int64_t seq_jump = 0;         // a seq beyond the window, not (yet) confirmed by its successor
  int64_t rejected() const {
    return malformed + trailing_bytes + duplicate + out_of_order + invalid_state + foreign_session + seq_jump;
  }
};

// States a followed plant may skip at once (lost, or the plant ran on while
// the link was down). A seq further ahead is not taken as the new newest on
// its own word: one forged message would otherwise make every genuine state
// after it "out of order" for the rest of the run. It is dropped and counted
// (seq_jump); its successor (seq + 1) confirms the jump (a plant that really
// moved on), so a genuine jump costs one state.
constexpr int64_t kSeqWindow = 1000;

class InputGate {
 public:
  // A silent plant is replaced after session_timeout_ns without a state.
  explicit InputGate(int64_t session_timeout_ns);
  // The controller's timeout: max(stale time, 2 s).
  static int64_t session_timeout_for(int64_t stale_ns);

  // A message that did not decode / decoded with extra bytes.
  GateVerdict malformed();
  GateVerdict trailing_bytes();
  // A decoded state of `session` with sequence number `seq`, received at
  // monotonic time now_ns; `valid`: its values pass measurement_valid().
  // A state of the followed session that is not valid is still accepted
  // (counted as invalid_state): the core answers it with SAFE.
  GateVerdict offer(int64_t now_ns, int64_t session, int64_t seq, bool valid);

  bool have_state() const { return have_; }
  int64_t session() const { return session_; }  // of the newest accepted state
  int64_t seq() const { return seq_; }
  int64_t last_rx_ns() const { return rx_ns_; }  // arrival of the newest accepted state
  int64_t session_timeout_ns() const { return timeout_ns_; }
  GateCounts counts() const;

 private:
  using C = std::atomic<int64_t>;
  int64_t timeout_ns_;
  bool have_ = false;
  int64_t session_ = 0, seq_ = 0, rx_ns_ = 0;
  bool jump_pending_ = false;
  int64_t jump_seq_ = 0;  // the newest unconfirmed jump's seq
  C seq_jump_{0};
  C received_{0}, malformed_{0}, trailing_{0}, duplicate_{0}, out_of_order_{0}, invalid_{0},
      foreign_{0}, adopted_{0};
};

}  // namespace sc_rt
