"""Where the plant emulator's microseconds go (``timing.json``
``emulator_breakdown_us``), from the stamps its loop takes per row and the
times of each state's publish and of its answer (bus/emulator.py)."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["loop_breakdown", "stats"]


def stats(v) -> dict[str, float | None]:
    """p50, p99, max and mean of ``v`` (None for an empty sample)."""
    v = np.asarray(v, float)
    if v.size == 0:
        return {"p50": None, "p99": None, "max": None, "mean": None}
    return {"p50": float(np.percentile(v, 50)), "p99": float(np.percentile(v, 99)),
            "max": float(v.max()), "mean": float(v.mean())}


def loop_breakdown(stamps: np.ndarray | None, mode: str, cmd_utime: dict[int, int], pub_wall_us: dict[int, int],
                   cmd_rx: dict[int, int], pub_ns: dict[int, int]) -> dict[str, Any]:
    """``stamps``: per row, monotonic ns [tick or answer, integrated, state
    published, truth started, truth done]; ``cmd_utime`` / ``pub_wall_us``:
    per state seq, the answer's and the state's utime [us, wall clock];
    ``cmd_rx`` / ``pub_ns``: per state seq, the answer's receipt and the
    state's publish [monotonic ns].

    Returns ``integrate`` (the tick, or in lockstep the answer, to the next
    state integrated), ``publish_state`` (guidance, state and our own
    looped-back messages), ``truth_record`` (the row recorded, its truth
    published), lockstep ``wait_answer`` (truth done to the next answer);
    the state-to-command latency split at the controller's publish
    (``state_to_controller_publish``, ``controller_publish_to_handled``) and,
    in real time, ``late_answers``: the answers that came after the tick
    that needed them, split the same way."""
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
    ks = [k for k in cmd_utime if k in pub_wall_us and k in cmd_rx and k in pub_ns]
    if ks:
        there = np.array([cmd_utime[k] - pub_wall_us[k] for k in ks], float)
        back = np.array([(cmd_rx[k] - pub_ns[k]) / 1e3 for k in ks]) - there
        out["state_to_controller_publish"] = stats(there)
        out["controller_publish_to_handled"] = stats(back)
        if mode == "realtime":  # the answer to state k is due at row k's tick
            late = [i for i, k in enumerate(ks) if k < len(stamps) and stamps[k, 0] > 0 and cmd_rx[k] > stamps[k, 0]]
            out["late_answers"] = {"count": len(late), "of": len(ks),
                                   "state_to_controller_publish": stats(there[late]),
                                   "controller_publish_to_handled": stats(back[late])}
    return out
