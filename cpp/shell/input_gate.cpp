#include "input_gate.hpp"

#include <algorithm>

namespace sc_rt {

const char* verdict_name(GateVerdict v) {
  switch (v) {
    case GateVerdict::Accept: return "accept";
    case GateVerdict::Adopt: return "adopt";
    case GateVerdict::Duplicate: return "duplicate";
    case GateVerdict::OutOfOrder: return "out_of_order";
    case GateVerdict::SeqJump: return "seq_jump";
    case GateVerdict::ForeignSession: return "foreign_session";
    case GateVerdict::InvalidCandidate: return "invalid_candidate";
    case GateVerdict::Malformed: return "malformed";
    case GateVerdict::TrailingBytes: return "trailing_bytes";
  }
  return "?";
}

InputGate::InputGate(int64_t session_timeout_ns) : timeout_ns_(session_timeout_ns) {}

int64_t InputGate::session_timeout_for(int64_t stale_ns) {
  return std::max<int64_t>(stale_ns, 2000000000);
}

GateVerdict InputGate::malformed() {
  ++received_;
  ++malformed_;
  return GateVerdict::Malformed;
}

GateVerdict InputGate::trailing_bytes() {
  ++received_;
  ++trailing_;
  return GateVerdict::TrailingBytes;
}

GateVerdict InputGate::offer(int64_t now_ns, int64_t session, int64_t seq, bool valid) {
  ++received_;
  bool adopt = false;
  if (have_ && session != session_) {
    // Another plant on this channel. While ours is alive, ignore it; once
    // ours has been silent for the session timeout, adopt the new one (a
    // restarted emulator) at its first valid state.
    if (now_ns - rx_ns_ < timeout_ns_) {
      ++foreign_;
      return GateVerdict::ForeignSession;
    }
    if (!valid) {
      ++invalid_;
      return GateVerdict::InvalidCandidate;
    }
    ++adopted_;
    have_ = false;
    adopt = true;
  }
  if (have_ && seq == seq_) {
    ++duplicate_;
    return GateVerdict::Duplicate;
  }
  if (have_ && seq < seq_) {
    ++out_of_order_;
    return GateVerdict::OutOfOrder;
  }
  if (have_ && seq - seq_ > kSeqWindow) {  // (seq > seq_ here: no overflow for seqs the plant can reach)
    const bool confirmed = jump_pending_ && seq == jump_seq_ + 1;
    if (!confirmed) {
      jump_pending_ = true;
      jump_seq_ = seq;
      ++seq_jump_;
      return GateVerdict::SeqJump;
    }
  }
  jump_pending_ = false;
  if (!valid) ++invalid_;
  session_ = session;
  seq_ = seq;
  rx_ns_ = now_ns;
  have_ = true;
  return adopt ? GateVerdict::Adopt : GateVerdict::Accept;
}

GateCounts InputGate::counts() const {
  GateCounts c;
  c.received = received_;
  c.malformed = malformed_;
  c.trailing_bytes = trailing_;
  c.duplicate = duplicate_;
  c.out_of_order = out_of_order_;
  c.invalid_state = invalid_;
  c.foreign_session = foreign_;
  c.sessions_adopted = adopted_;
  c.seq_jump = seq_jump_;
  return c;
}

}  // namespace sc_rt
