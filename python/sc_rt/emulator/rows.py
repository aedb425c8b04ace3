"""A row of the emulator's run (emulator/process.py runs the loops that
call it): the command applied over one control period, the next state
published first, then the row recorded and its truth published.

Real time defers the second half (``pending``: the record and the truth)
until the answer to the next state is in, or at most ``defer_ns``, so that
the command is handled as it arrives; the loop flushes it
(``flush_due``). A late tick flushes the previous row first: no row's
record or truth is ever lost.

Also kept here, since a row is where they show: the watchdog's gaps (the
spans of rows applied without a command) and the newest row's time.
"""

from __future__ import annotations

import time
from typing import Callable

import numpy as np

from sc_rt.emulator.twin import NO_RODS

__all__ = ["RowPipeline"]


class RowPipeline:
    """The rows of one run over the emulator's parts: the plant twin
    (emulator/twin.py), the publisher (emulator/outbox.py), the record's
    ring (emulator/record.py), the receiver (emulator/receiver.py), what
    they share (emulator/state.py), the sensors (None without) and
    ``should_stop``, asked before a next state goes out."""

    def __init__(self, twin, publisher, ring, receiver, shared, sensors, should_stop: Callable[[], bool]):
        self.twin, self.publisher, self.ring = twin, publisher, ring
        self.receiver, self.shared, self.sensors = receiver, shared, sensors
        self.should_stop = should_stop
        #: real time: the row whose record and truth wait for the next answer
        self.pending: tuple | None = None
        self.pending_by_ns = 0
        #: the seq of the state published last (the loop publishes a state only once)
        self.next_published = -1
        #: [s] (start, end) of each span of rows applied without a command (the watchdog's zero)
        self.gaps: list[tuple[float, float]] = []
        self._gap_start: float | None = None
        self.t_reached = 0.0  # [s] the newest row's time

    def flush_due(self, has_cmd: Callable[[int], bool]) -> None:
        """Flush the deferred row when the answer to the state published last
        is in (``has_cmd``) or its wait is over."""
        if self.pending is not None and (has_cmd(self.next_published) or time.monotonic_ns() >= self.pending_by_ns):
            self.flush()

    def apply(self, k: int, t: float, x: np.ndarray, cmd, n_sub: int, h: float,
              next_state: tuple[int, float] | None = None, stamps=None, defer_ns: int | None = None,
              d_cmd: tuple | None = None, guidance=None):
        """Row k: apply ``cmd`` (None: the watchdog's zero) over one control
        period; publish the next state (``next_state``: its seq and t, with its
        ``guidance`` values computed ahead or None; not when the run stops or
        diverged) first, then record row k with the truth at t and publish the
        truth. ``stamps``: the row's monotonic ns (integrated, state out, truth
        out) go to stamps[1:5]. ``defer_ns``: the record and the truth wait
        until the answer to the next state is in, at most this long
        (``flush_due``). ``d_cmd``: the rods' commands held (RodHold).
        Returns the next state, or None when it is not finite."""
        stale = cmd is None
        self.receiver.peer_lost = stale
        if stale:
            u_cmd, u_sat_ctrl, cmd_seq = np.zeros(4), np.zeros(4), -1
            if self._gap_start is None:
                self._gap_start = t
        else:
            u_cmd, u_sat_ctrl, cmd_seq = np.array(cmd.u_cmd), np.array(cmd.u_sat), cmd.seq
            if self._gap_start is not None:
                self.gaps.append((self._gap_start, t))
                self._gap_start = None
        # the row's faults, the wheels' and the rods', and the fault commands' seqs that left them
        # (a handler may change them only while we wait)
        act, rods = self.shared.act, self.shared.rods
        fault_seqs = (self.shared.fault_seq_applied, self.shared.fault_seq_refused)
        # the sensors sample inside the period only when a next row follows (as offline)
        sensors = self.sensors if next_state is not None else None
        x_next = self.twin.integrate(act, t, x, u_cmd, n_sub, h, sensors, k * n_sub, d_cmd, rods)
        finite = bool(np.all(np.isfinite(x_next)))
        if stamps is not None:
            stamps[1] = time.monotonic_ns()
        if next_state is not None and finite and not self.should_stop():
            if sensors is not None:  # the samples of the next control instant go out before its state
                self.publisher.sense(next_state[0] * n_sub, next_state[1], x_next, next_state[0])
            self.shared.t_now = next_state[1]  # what arrives from now on arrives during the next row
            self.publisher.state(next_state[0], next_state[1], x_next, guidance)
            self.next_published = next_state[0]
        if stamps is not None:
            stamps[2] = time.monotonic_ns()
        if self.pending is not None:  # a late tick: the previous row's record and truth first, never lost
            self.flush()
        self.pending = (k, t, x, cmd, u_cmd, u_sat_ctrl, cmd_seq, stale, act, stamps, self.twin.motor_at_start,
                        d_cmd, rods, fault_seqs)
        if defer_ns is None or next_state is None or not finite:
            self.flush()
        else:
            self.pending_by_ns = time.monotonic_ns() + defer_ns
        return x_next if finite else None

    def flush(self) -> None:
        """The deferred part of a row: its record and its truth."""
        k, t, x, cmd, u_cmd, u_sat_ctrl, cmd_seq, stale, act, stamps, motor, d_cmd, rods, fault_seqs = self.pending
        self.pending = None
        if stamps is not None:
            stamps[3] = time.monotonic_ns()
        _, accel, delta2 = self.twin.row(act, t, x, u_cmd, motor, d_cmd, rods)
        rod_fields = self.twin.rod_fields(t, d_cmd, rods)  # once: the record's and the truth's
        self._record(k, t, x, cmd, u_cmd, u_sat_ctrl, accel, delta2, d_cmd, rod_fields)
        self.publisher.drain()  # an answer that came meanwhile is received now, not after the truth's publish
        self.publisher.truth(k, t, cmd_seq, u_cmd, accel, delta2, stale, act, rod_fields, fault_seqs)
        if stamps is not None:
            stamps[4] = time.monotonic_ns()

    def close(self, rows: int) -> None:
        """At the run's end: the deferred row, and a gap still open."""
        if self.pending is not None:
            self.flush()
        if self._gap_start is not None and rows > 0:
            self.gaps.append((self._gap_start, self.t_reached))
            self._gap_start = None

    def _record(self, k, t, x, cmd, u_cmd, u_sat_ctrl, accel, delta2, d_cmd=None, rod_fields=NO_RODS) -> None:
        run, k = self.ring.slot(k)
        if d_cmd is not None:  # the rods' commands the row held (0 beyond the rods, as the core's Command)
            run["rod_dipole_cmd"][k] = (*d_cmd, *(0.0,) * (6 - len(d_cmd)))
        n_rods, _, rod_dipole, m_B, _ = rod_fields  # the rods' truth (PlantTwin.rod_fields), NaN without rods
        if n_rods:
            run["m_B"][k] = m_B
            run["rod_dipole"][k, :n_rods] = rod_dipole[:n_rods]
        self.t_reached = t
        run["t"][k] = t
        run["sigma_BN"][k] = x[0:3]
        run["omega_BN_B"][k] = x[3:6]
        run["wheel_speed"][k] = x[6:10]
        run["u_cmd"][k] = u_cmd
        run["u_sat"][k] = u_sat_ctrl
        run["wheel_accel"][k] = accel
        run["delta2"][k] = delta2
        run["cmd_stale"][k] = cmd is None
        if cmd is not None:
            run["cmd_seq_applied"][k] = cmd.seq
            run["flags"][k] = cmd.flags
            run["ctrl_mode"][k] = cmd.mode
