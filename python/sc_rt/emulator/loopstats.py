"""Where the plant emulator's microseconds go (``timing.json``
``emulator_breakdown_us``), from the stamps its loop takes per row and the
times of each state's publish and of its answer, kept per state seq in
preallocated arrays (emulator/process.py, emulator/inbox.py)."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["loop_breakdown", "stats", "MISSING"]

#: an int64 per-seq entry that holds nothing (no such message)
MISSING = np.iinfo(np.int64).min


def stats(v) -> dict[str, float | None]:
    """p50, p99, max and mean of ``v`` (None for an empty sample)."""
    v = np.asarray(v, float)
    if v.size == 0:
        return {"p50": None, "p99": None, "max": None, "mean": None}
    return {"p50": float(np.percentile(v, 50)), "p99": float(np.percentile(v, 99)),
            "max": float(v.max()), "mean": float(v.mean())}


def loop_breakdown(stamps: np.ndarray | None, mode: str, cmd_utime: np.ndarray, pub_wall_us: np.ndarray,
                   cmd_rx: np.ndarray, pub_ns: np.ndarray) -> dict[str, Any]:
    """``stamps``: per row, monotonic ns [tick or answer, integrated, state
    published, truth started, truth done]; ``cmd_utime`` / ``pub_wall_us``:
    per state seq (int64 arrays, ``MISSING`` where there is none), the
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
    split the same way."""
    if stamps is None or len(stamps) == 0:
        return {}
    ok = np.all(stamps > 0, axis=1)
    s = stamps[ok]
    d = np.diff(s, axis=1) / 1e3
    out: dict[str, Any] = {"integrate": stats(d[:, 0]), "publish_state": stats(d[:, 1]),
                           "truth_record": stats(d[:, 3]), "rows": int(len(s))}
    if mode == "lockstep" and len(stamps) > 1:
        both = ok[1:] & ok[:-1]
        out["wait_answer"] = stats((stamps[1:, 0] - stamps[:-1, 4])[both] / 1e3)
    ks = np.flatnonzero((cmd_utime != MISSING) & (pub_wall_us != MISSING) & (cmd_rx != MISSING)
                        & (pub_ns != MISSING))
    if ks.size:
        there = cmd_utime[ks].astype(float) - pub_wall_us[ks]  # in float: a hostile utime cannot wrap
        back = (cmd_rx[ks] - pub_ns[ks]) / 1e3 - there
        out["state_to_controller_publish"] = stats(there)
        out["controller_publish_to_handled"] = stats(back)
        if mode == "realtime":  # the answer to state k is due at row k's tick
            inside = ks < len(stamps)
            tick = np.zeros(ks.size, np.int64)
            tick[inside] = stamps[ks[inside], 0]
            late = inside & (tick > 0) & (cmd_rx[ks] > tick)
            out["late_answers"] = {"count": int(np.count_nonzero(late)), "of": int(ks.size),
                                   "state_to_controller_publish": stats(there[late]),
                                   "controller_publish_to_handled": stats(back[late])}
    return out
