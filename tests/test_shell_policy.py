"""The controller shell's policy classes, through the bindings: the input gate
(session adoption, duplicates, order, counters) and the phase-locked
scheduler of the real-time mode. Both are the code sc-rt-controller runs
(cpp/shell/input_gate.*, phase_lock.*); time is passed in as monotonic ns."""

from __future__ import annotations

import math
import random

import pytest

from sc_rt import _core

V = _core.GateVerdict
S = 1_000_000_000  # 1 s [ns]
TIMEOUT = 2 * S
S1, S2, S3 = 111, 222, 333


def gate(timeout: int = TIMEOUT) -> _core.InputGate:
    return _core.InputGate(timeout)


# ---------------------------------------------------------------- input gate

def test_session_timeout_is_the_stale_time_or_2_s():
    assert _core.InputGate.session_timeout_for(500_000_000) == 2 * S
    assert _core.InputGate.session_timeout_for(7 * S) == 7 * S
    assert _core.InputGate(123).session_timeout_ns == 123


def test_first_session_is_followed():
    g = gate()
    assert not g.have_state
    assert g.offer(10 * S, S1, 0, True) == V.Accept
    assert (g.have_state, g.session, g.seq, g.last_rx_ns) == (True, S1, 0, 10 * S)
    assert g.offer(11 * S, S1, 1, True) == V.Accept
    assert (g.seq, g.last_rx_ns) == (1, 11 * S)
    c = g.counts()
    # following the first session is not an adoption
    assert (c.received, c.sessions_adopted, c.rejected) == (2, 0, 0)


def test_second_session_is_ignored_while_the_first_is_alive():
    g = gate()
    g.offer(10 * S, S1, 5, True)
    # up to one ns before the timeout since the first's newest state
    for t in (10 * S, 11 * S, 10 * S + TIMEOUT - 1):
        assert g.offer(t, S2, 0, True) == V.ForeignSession
    # a state of the first keeps it alive: the window restarts there
    assert g.offer(12 * S, S1, 6, True) == V.Accept
    assert g.offer(12 * S + TIMEOUT - 1, S2, 1, True) == V.ForeignSession
    assert (g.session, g.seq, g.last_rx_ns) == (S1, 6, 12 * S)
    c = g.counts()
    assert (c.foreign_session, c.sessions_adopted, c.rejected, c.received) == (4, 0, 4, 6)


def test_second_session_is_adopted_after_the_first_is_silent():
    g = gate()
    g.offer(10 * S, S1, 500, True)
    # foreign states do not keep the first session alive
    assert g.offer(11 * S, S2, 0, True) == V.ForeignSession
    # the first has been silent for exactly the timeout: the new one is adopted,
    # its sequence numbers start afresh (0 < 500 is not out of order)
    assert g.offer(10 * S + TIMEOUT, S2, 1, True) == V.Adopt
    assert (g.session, g.seq, g.last_rx_ns) == (S2, 1, 10 * S + TIMEOUT)
    assert g.offer(10 * S + TIMEOUT + 1, S2, 2, True) == V.Accept
    # now the old session is the foreign one
    assert g.offer(10 * S + TIMEOUT + 2, S1, 501, True) == V.ForeignSession
    c = g.counts()
    assert (c.sessions_adopted, c.foreign_session) == (1, 2)


def test_a_new_session_is_adopted_only_at_a_valid_state():
    g = gate()
    g.offer(0, S1, 0, True)
    assert g.offer(TIMEOUT, S2, 0, False) == V.InvalidCandidate
    assert (g.session, g.last_rx_ns) == (S1, 0)  # still the silent first
    assert g.offer(TIMEOUT + 1, S2, 1, True) == V.Adopt
    c = g.counts()
    assert (c.invalid_state, c.sessions_adopted, c.rejected) == (1, 1, 1)


def test_silence_alone_changes_nothing_and_adoption_can_repeat():
    g = gate()
    g.offer(0, S1, 0, True)
    # the same session after a long silence: simply the next state
    assert g.offer(100 * S, S1, 1, True) == V.Accept
    # (a restarted emulator has a new session; the old one restarting its
    # numbering would be out of order)
    assert g.offer(200 * S, S1, 0, True) == V.OutOfOrder
    assert g.offer(200 * S, S2, 0, True) == V.Adopt
    assert g.offer(200 * S + TIMEOUT, S3, 0, True) == V.Adopt
    assert g.session == S3
    assert g.counts().sessions_adopted == 2


def test_duplicates_are_answered_again_and_do_not_refresh_the_session():
    g = gate()
    assert g.offer(0, S1, 7, True) == V.Accept
    assert g.offer(1 * S, S1, 7, True) == V.Duplicate
    assert g.offer(int(1.9 * S), S1, 7, True) == V.Duplicate
    assert g.last_rx_ns == 0  # a re-sent state is not a new arrival
    # so the plant counts as silent since t = 0
    assert g.offer(TIMEOUT, S2, 0, True) == V.Adopt
    # the first state of an adopted session is never a duplicate, even with the old seq
    g2 = gate()
    g2.offer(0, S1, 3, True)
    assert g2.offer(TIMEOUT, S2, 3, True) == V.Adopt
    c = g.counts()
    assert (c.duplicate, c.rejected) == (2, 2)


def test_out_of_order_states_are_dropped():
    g = gate()
    g.offer(0, S1, 5, True)
    assert g.offer(1, S1, 3, True) == V.OutOfOrder
    assert g.offer(2, S1, -1, True) == V.OutOfOrder
    assert (g.seq, g.last_rx_ns) == (5, 0)
    assert g.offer(3, S1, 9, True) == V.Accept  # gaps are fine
    assert g.offer(4, S1, 8, True) == V.OutOfOrder
    assert g.counts().out_of_order == 3


def test_invalid_state_of_our_session_is_applied_and_counted():
    # the core answers it with SAFE; lockstep runs stay identical to offline ones
    g = gate()
    assert g.offer(0, S1, 0, False) == V.Accept
    assert g.offer(5, S1, 1, False) == V.Accept
    assert (g.seq, g.last_rx_ns) == (1, 5)
    c = g.counts()
    assert (c.invalid_state, c.rejected) == (2, 2)


def test_every_message_is_counted_once_by_kind():
    g = gate()
    assert g.malformed() == V.Malformed
    assert g.trailing_bytes() == V.TrailingBytes
    assert not g.have_state  # neither touches the followed state
    g.offer(0, S1, 1, True)
    g.offer(1, S1, 1, True)       # duplicate
    g.offer(2, S1, 0, True)       # out of order
    g.offer(3, S2, 0, True)       # foreign
    g.offer(4, S1, 2, False)      # invalid, applied
    g.malformed()
    d = g.counts().as_dict()
    # the names of the controller's exit summary ("rejected" and beside it)
    assert d == {"received": 8, "malformed": 2, "trailing_bytes": 1, "duplicate": 1,
                 "out_of_order": 1, "invalid_state": 1, "foreign_session": 1, "sessions_adopted": 0,
                 "seq_jump": 0}
    assert g.counts().rejected == 7


# ------------------------------------------------------------ phase lock

P = 10_000_000        # 100 Hz [ns]
PHI = 3_300_000       # arrival phase of the plant's states [ns]
T0 = 1_000 * S        # the controller's start (monotonic)


def run_lock(jitter_us: float, *, n: int = 3000, seed: int = 7, offset_us: float = 50.0,
             late_us: float = 20.0, compute_us: float = 30.0, stall_every: int = 0):
    """The controller's real-time loop against simulated arrivals.

    States arrive at T0 + k P + PHI + U(-J, J); the controller wakes at the
    lock's deadline plus a lateness U(0, late), uses the newest state that has
    arrived by then (fresh if not used before), computes for compute_us
    (3.5 periods every stall_every steps) and advances the lock. Returns one
    row per step: deadline, guard in force, fresh, now_ns, next deadline.
    """
    rng = random.Random(seed)
    arrivals = [T0 + k * P + PHI + round(rng.uniform(-jitter_us, jitter_us) * 1e3) for k in range(n + 10)]
    lock = _core.PhaseLock(P, offset_us, T0)
    assert lock.deadline == T0 + P
    rows = []
    newest, used = -1, -1
    for k in range(n):
        w, g = lock.deadline, lock.guard_ns
        wake = w + round(rng.uniform(0.0, late_us) * 1e3)
        while newest + 1 < len(arrivals) and arrivals[newest + 1] <= wake:
            newest += 1
        fresh = newest > used
        used = newest
        rx = arrivals[newest] if newest >= 0 else 0
        busy = 3.5 * P if stall_every and k % stall_every == stall_every - 1 else compute_us * 1e3
        now = wake + round(busy)
        nxt = lock.advance(fresh, rx, now)
        rows.append((w, g, fresh, now, nxt))
    return rows, lock


def phase(w: int) -> int:
    """Wake-up phase after the nominal arrival, in (-P/2, P/2]."""
    ph = (w - T0 - PHI) % P
    return ph - P if ph > P // 2 else ph


def test_free_running_clock_keeps_its_period():
    lock = _core.PhaseLock(P, -1.0, T0)
    assert not lock.locked
    for k in range(1, 50):
        assert lock.advance(k % 3 == 0, T0 + 12345 * k, lock.deadline + 1000) == T0 + (k + 1) * P
    assert lock.guard_ns == -1000.0


def trunc_div(a: int, b: int) -> int:
    """C++ integer division (toward zero)."""
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b > 0) else -q


def test_guard_and_lock_step_rules():
    lock = _core.PhaseLock(P, 50.0, T0)
    assert lock.locked and lock.guard_ns == 50_000.0
    # a miss widens the guard by a quarter + 5 us and leaves the phase alone
    assert lock.advance(False, T0 + 123, T0 + P + 30_000) == T0 + 2 * P
    assert lock.guard_ns == 1.25 * 50_000 + 5e3
    assert lock.advance(False, T0 + 456, T0 + 2 * P + 30_000) == T0 + 3 * P
    g = 1.25 * (1.25 * 50_000 + 5e3) + 5e3
    assert lock.guard_ns == g
    # a fresh step shrinks it by 1 % and moves the next deadline a quarter of
    # the way to (arrival + guard), modulo the period
    rx = T0 + 3 * P + 2_000_000
    g = max(0.99 * g, 50_000.0)
    err = (T0 + 4 * P - (rx + int(g))) % P
    err = err - P if err > P // 2 else err
    assert err < 0
    assert lock.advance(True, rx, T0 + 3 * P + 30_000) == T0 + 4 * P - trunc_div(err, 4)
    assert lock.guard_ns == g
    # the guard is capped at half a period and floored at the offset
    for _ in range(60):
        lock.advance(False, 0, lock.deadline)
    assert lock.guard_ns == P / 2
    for _ in range(600):
        lock.advance(True, lock.deadline - 50_000, lock.deadline)
    assert lock.guard_ns == 50_000.0


def test_lock_without_jitter_converges_to_arrival_plus_offset():
    rows, lock = run_lock(0.0, n=400, late_us=0.0)
    # start: the first wake is at phase P - PHI (-3.3 ms); each fresh step
    # removes a quarter of the error: e_k = 0.75^k e_0 to within a few ns
    # (the integer division by 4 truncates, at most 1 ns per step).
    e0 = phase(rows[0][0]) - 50_000
    assert abs(e0) > 3_000_000
    for k, (w, g, fresh, _, _) in enumerate(rows):
        assert fresh
        assert g == 50_000.0  # no miss: the guard never widened
        assert abs(phase(w) - 50_000 - 0.75 ** k * e0) <= min(k, 4) + 1, k
    assert abs(phase(rows[-1][4]) - 50_000) <= 4
    assert lock.guard_ns == 50_000.0


@pytest.mark.parametrize("jitter_us", [50.0, 200.0, 1000.0])
def test_lock_converges_to_arrival_plus_guard_under_jitter(jitter_us):
    J = jitter_us * 1e3
    rows, _ = run_lock(jitter_us)
    settled = rows[600:]
    g_lo = min(r[1] for r in settled)
    g_hi = max(r[1] for r in settled)
    # the guard adapts: never below the offset, never above P/2; with jitter
    # beyond the offset, misses widened it
    assert 50_000.0 <= g_lo <= g_hi <= P / 2
    assert g_hi > 50_000.0
    # Derivation (ph: wake phase after the nominal arrival, j: the used
    # state's jitter, g': the guard after the step): a fresh step gives
    # ph' = 3/4 ph + 1/4 (j + g'), a miss leaves ph unchanged. So ph stays in
    # the hull [g_lo - J, g_hi + J], and e = ph - g (tracking error against
    # the guard in force) obeys e' = 3/4 e + 3/4 (g - g') + 1/4 j on fresh
    # steps (0 <= g - g' <= 1 % g) and only decreases on misses:
    #   e <= J + 0.03 g_hi,   e >= g_lo - g_hi - J.
    eps = 8  # ns of integer truncation
    errs = []
    for w, g, _, _, _ in settled:
        ph = phase(w)
        assert g_lo - J - eps <= ph <= g_hi + J + eps
        e = ph - g
        assert e <= J + 0.03 * g_hi + eps
        assert e >= g_lo - g_hi - J - eps
        errs.append(e)
    # the bound is not vacuous: the error uses a good part of it, and on
    # average the wake-up sits at arrival + guard within a quarter of J
    assert max(abs(e) for e in errs) > 0.3 * J
    assert abs(sum(errs) / len(errs)) < 0.25 * J
    # guard balance: each miss widens it by >= 25 %, each fresh step shrinks
    # it by <= 1 %, so misses m and fresh steps f over the window satisfy
    # m ln 1.25 <= ln(g_end / g_start) + f ln(1 / 0.99)  (about 4.5 % misses)
    m = sum(1 for r in settled if not r[2])
    f = len(settled) - m
    g_start, g_end = settled[0][1], rows[-1][1]
    assert m > 0
    assert m * math.log(1.25) <= math.log(g_end / g_start) + f * math.log(1 / 0.99) + 1e-9
    assert m / len(settled) < 0.05


@pytest.mark.parametrize("jitter_us", [0.0, 200.0])
def test_lock_never_schedules_in_the_past(jitter_us):
    rows, _ = run_lock(jitter_us, stall_every=97)
    stalls = 0
    for w, _, _, now, nxt in rows:
        assert nxt >= now  # never a deadline already behind the clock
        # at most one period (plus the lock's quarter-error step) ahead
        assert nxt - max(now, w) <= P + P // 8
        if now - w > P:  # a stall: the missed periods were skipped, not burst
            stalls += 1
            assert nxt - now <= P
    assert stalls == len(rows) // 97


def test_stall_skips_whole_periods_and_keeps_the_phase():
    a = _core.PhaseLock(P, 50.0, T0)
    b = _core.PhaseLock(P, 50.0, T0)
    for k in range(200):  # lock both on the same arrivals
        rx = T0 + k * P + PHI
        w = a.deadline
        a.advance(True, rx, w + 30_000)
        b.advance(True, rx, w + 30_000)
    assert a.deadline == b.deadline
    w = a.deadline
    rx = w - 50_000
    d_ok = a.advance(True, rx, w + 30_000)
    d_stall = b.advance(True, rx, w + 5 * P + 123)
    skipped, rest = divmod(d_stall - d_ok, P)
    assert rest == 0 and skipped == 5
    assert d_stall > w + 5 * P + 123
