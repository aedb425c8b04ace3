"""Where the plant emulator's microseconds go (``timing.json``
``emulator_breakdown_us``), from the stamps its loop takes per row and the
times of each state's publish and of its answer, kept per state seq in
the emulator's record (emulator/process.py, emulator/inbox.py), read a
chunk of rows at a time."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["loop_breakdown", "LoopBreakdown", "StreamStats", "stats", "MISSING"]

#: an int64 per-seq entry that holds nothing (no such message)
MISSING = np.iinfo(np.int64).min


class StreamStats:
    """p50, p99, max and mean of a stream of values [us], in memory that does
    not grow with it: count, sum and max exact, the quantiles (nearest rank)
    from a histogram of log-spaced bins 1.2 % wide for |v| in [1 ns, 1000 s]
    (either sign; the values beyond go to the end bins) and a bin for zero,
    each reported at its geometric middle, so within 0.6 % of the value."""

    EDGES = np.geomspace(1e-3, 1e9, 2401)  # [us]: ratio 10^(12/2400) = 1.0116 per bin

    def __init__(self) -> None:
        self.pos = np.zeros(len(self.EDGES) + 1, np.int64)
        self.neg = np.zeros(len(self.EDGES) + 1, np.int64)
        self.zero = 0
        self.n, self.sum, self.max = 0, 0.0, -math.inf

    def add(self, v) -> None:
        v = np.asarray(v, float).reshape(-1)
        v = v[np.isfinite(v)]
        if v.size == 0:
            return
        self.n += v.size
        self.sum += float(v.sum())
        self.max = max(self.max, float(v.max()))
        m = len(self.EDGES) + 1
        self.pos += np.bincount(np.searchsorted(self.EDGES, v[v > 0]), minlength=m)
        self.neg += np.bincount(np.searchsorted(self.EDGES, -v[v < 0]), minlength=m)
        self.zero += int(np.count_nonzero(v == 0))

    def _mid(self, i: int) -> float:
        e = self.EDGES
        return float(e[0] if i == 0 else e[-1] if i >= len(e) else math.sqrt(e[i - 1] * e[i]))

    def quantile(self, p: float) -> float | None:
        if self.n == 0:
            return None
        rank = max(1, math.ceil(p * self.n - 1e-9))
        seen = 0
        for i in range(len(self.neg) - 1, -1, -1):  # the most negative first
            seen += int(self.neg[i])
            if seen >= rank:
                return -self._mid(i)
        seen += self.zero
        if seen >= rank:
            return 0.0
        idx = np.flatnonzero(np.cumsum(self.pos) + seen >= rank)
        return self._mid(int(idx[0]))

    def result(self) -> dict[str, float | None]:
        if self.n == 0:
            return {"p50": None, "p99": None, "max": None, "mean": None}
        return {"p50": self.quantile(0.5), "p99": self.quantile(0.99), "max": self.max, "mean": self.sum / self.n}


def stats(v) -> dict[str, float | None]:
    """p50, p99, max and mean of ``v`` (None for an empty sample), as ``StreamStats``."""
    s = StreamStats()
    s.add(v)
    return s.result()


class LoopBreakdown:
    """``loop_breakdown`` over a run's rows a chunk at a time, in order."""

    def __init__(self, mode: str):
        self.mode = mode
        self.rows = 0
        self._prev_done = 0  # the truth-done stamp of the chunk's previous row (0: none)
        self.s = {k: StreamStats() for k in ("integrate", "publish_state", "truth_record", "wait_answer",
                                             "there", "back", "late_there", "late_back")}
        self.answered = self.late = 0

    def add(self, stamps: np.ndarray, cmd_utime: np.ndarray, pub_wall_us: np.ndarray, cmd_rx: np.ndarray,
            pub_ns: np.ndarray) -> None:
        """The next rows: per row, monotonic ns [tick or answer, integrated,
        state published, truth started, truth done]; per state seq of the
        same rows, the answer's and the state's utime [us] and their
        receipt and publish [monotonic ns] (``MISSING``: none)."""
        if len(stamps) == 0:
            return
        ok = np.all(stamps > 0, axis=1)
        s = stamps[ok]
        d = np.diff(s, axis=1) / 1e3
        self.s["integrate"].add(d[:, 0])
        self.s["publish_state"].add(d[:, 1])
        self.s["truth_record"].add(d[:, 3])
        self.rows += int(len(s))
        if self.mode == "lockstep":
            done = np.concatenate([[self._prev_done], stamps[:-1, 4]])
            both = ok & (done > 0)
            self.s["wait_answer"].add((stamps[:, 0] - done)[both] / 1e3)
        self._prev_done = int(stamps[-1, 4]) if ok[-1] else 0
        ks = np.flatnonzero((cmd_utime != MISSING) & (pub_wall_us != MISSING) & (cmd_rx != MISSING)
                            & (pub_ns != MISSING))
        if ks.size:
            there = cmd_utime[ks].astype(float) - pub_wall_us[ks]  # in float: a hostile utime cannot wrap
            back = (cmd_rx[ks] - pub_ns[ks]) / 1e3 - there
            self.s["there"].add(there)
            self.s["back"].add(back)
            self.answered += int(ks.size)
            if self.mode == "realtime":  # the answer to state k is due at row k's tick
                tick = stamps[ks, 0]
                late = (tick > 0) & (cmd_rx[ks] > tick)
                self.late += int(np.count_nonzero(late))
                self.s["late_there"].add(there[late])
                self.s["late_back"].add(back[late])

    def result(self) -> dict[str, Any]:
        if self.rows == 0 and self._prev_done == 0 and self.answered == 0:
            return {}
        out: dict[str, Any] = {k: self.s[k].result() for k in ("integrate", "publish_state", "truth_record")}
        out["rows"] = self.rows
        if self.mode == "lockstep" and self.s["wait_answer"].n:
            out["wait_answer"] = self.s["wait_answer"].result()
        if self.answered:
            out["state_to_controller_publish"] = self.s["there"].result()
            out["controller_publish_to_handled"] = self.s["back"].result()
            if self.mode == "realtime":
                out["late_answers"] = {"count": self.late, "of": self.answered,
                                       "state_to_controller_publish": self.s["late_there"].result(),
                                       "controller_publish_to_handled": self.s["late_back"].result()}
        return out


def loop_breakdown(stamps: np.ndarray | None, mode: str, cmd_utime: np.ndarray, pub_wall_us: np.ndarray,
                   cmd_rx: np.ndarray, pub_ns: np.ndarray) -> dict[str, Any]:
    """``stamps``: per row, monotonic ns [tick or answer, integrated, state
    published, truth started, truth done]; ``cmd_utime`` / ``pub_wall_us``:
    per state seq of the same rows (int64 arrays, ``MISSING`` where there is none), the
    answer's and the state's utime [us, wall clock]; ``cmd_rx`` / ``pub_ns``:
    per state seq, the answer's receipt and the state's publish [monotonic
    ns].

    Returns ``integrate`` (the tick, or in lockstep the answer, to the next
    state integrated), ``publish_state`` (guidance, state and our own
    looped-back messages), ``truth_record`` (the row recorded, its truth
    published), lockstep ``wait_answer`` (truth done to the next answer);
    the state-to-command latency split at the controller's publish
    (``state_to_controller_publish``, ``controller_publish_to_handled``) over
    the states that have all four times, in seq order, and, in real time,
    ``late_answers``: the answers that came after the tick that needed them,
    split the same way. Each as ``StreamStats`` (a long run: ``LoopBreakdown``
    a chunk at a time)."""
    if stamps is None or len(stamps) == 0:
        return {}
    b = LoopBreakdown(mode)
    n = len(stamps)
    b.add(stamps, cmd_utime[:n], pub_wall_us[:n], cmd_rx[:n], pub_ns[:n])
    return b.result()
