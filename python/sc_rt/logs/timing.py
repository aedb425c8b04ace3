"""What a HIL run's ``timing.json`` holds, computed from the run's record and
the controller's summary (``sc-rt hil`` during the run, ``sc-rt report`` from
the log alone), and how many of the run's messages its log lacks."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.logs.lcmlog import LogDamaged, read_events
from sc_rt.plan.timing import RealtimeLimits
from sc_rt.results.record.run import Run

__all__ = ["percentiles", "timing_report", "log_missing", "RealtimeLimits", "realtime_shortfall",
           "ACQUIRE_S", "lateness_counts"]

#: [s] the timer trigger's phase-lock acquisition: answers in it may take up
#: to a period and more (the lock is not yet on the state arrivals), so the
#: latency limit judges the answers after it (the event trigger: from t = 0)
ACQUIRE_S = 2.0


def percentiles(v: np.ndarray) -> dict[str, float | None]:
    v = np.asarray(v, float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"p50": None, "p99": None, "max": None}
    return {"p50": float(np.percentile(v, 50)), "p99": float(np.percentile(v, 99)),
            "max": float(v.max())}


def log_missing(path: Path, prefix: str, rows: int, sent: dict[str, int] | None = None) -> dict[str, int]:
    """Per channel the emulator publishes once per row (state, truth,
    guidance), and per sensor channel in ``sent`` (channel -> samples the
    emulator sent, numbered from 0): how many of those messages the log lacks
    (by seq: re-sent ones count once, seqs outside what was sent not at
    all; a bit per seq, so any length of run). Zero everywhere for a complete log."""
    sent = {c: n for c, n in (sent or {}).items() if n}
    want = {c: sent.get(c, rows) for c in ("SCRT_STATE", "SCRT_TRUTH", "SCRT_GUIDANCE", *sent)}
    seen = {prefix + c: np.zeros(n, bool) for c, n in want.items()}
    try:
        for _n, _t, ch, data in read_events(path, partial=True):
            s = seen.get(ch.decode("utf-8", "replace"))
            if s is not None and len(data) >= 24:
                k = int.from_bytes(data[16:24], "big", signed=True)  # the seq after fingerprint, utime
                if 0 <= k < len(s):
                    s[k] = True
    except (LogDamaged, OSError):
        return dict(want)
    got = {c[len(prefix):]: int(np.count_nonzero(s)) for c, s in seen.items()}
    return {c: want[c] - n if n or c != "SCRT_GUIDANCE" else 0 for c, n in got.items()}


def lateness_counts(res: Run, trigger: str | None) -> dict[str, Any]:
    """A real-time run's lateness against its control period: answers
    (state-to-command latency, the answered rows) later than one period,
    counted after the timer trigger's acquisition (``ACQUIRE_S``; an unknown
    trigger, an --external process, is judged as the timer), the emulator's
    ticks later than one period, and its worst tick's lateness in periods."""
    period_us = 1e6 / res.meta.control_rate_hz
    judged = answers = late = ticks_late = 0
    worst = 0.0
    since = 0.0 if trigger == "event" else ACQUIRE_S
    for c in res.chunks():
        lat, tick = np.asarray(c["latency_us"], float), np.asarray(c["tick_lateness_us"], float)
        ok = np.isfinite(lat) & (np.asarray(c["t"], float) >= since)
        answers += int(np.count_nonzero(np.isfinite(lat)))
        judged += int(np.count_nonzero(ok))
        late += int(np.count_nonzero(lat[ok] > period_us))
        tick = tick[np.isfinite(tick)]
        ticks_late += int(np.count_nonzero(tick > period_us))
        if tick.size:
            worst = max(worst, float(tick.max()) / period_us)
    return {"answers": answers, "answers_judged": judged, "answers_over_period": late, "latency_judged_from_s": since,
            "ticks_over_period": ticks_late, "worst_tick_lateness_periods": worst}


def timing_report(res: Run, summary: dict[str, Any], wall: float) -> dict[str, Any]:
    """timing.json: the controller's own measurements (from its status
    messages and exit summary) and the emulator's (state-to-command latency)."""
    c = res.counters
    mode, rate, rows = res.meta.mode, res.meta.control_rate_hz, len(res)
    ctl_rej = summary.get("rejected", {})
    return {
        "mode": mode,
        "control_rate_hz": rate,
        "steps": int(summary.get("steps", rows)),
        "deadline_misses": int(summary.get("deadline_misses", 0)),
        "wake_lateness_us": percentiles(res["wake_lateness_us"]) if mode == "realtime"
        else {"p50": None, "p99": None, "max": None},
        "compute_us": percentiles(res["compute_us"]),
        "state_to_cmd_latency_us": percentiles(res["latency_us"]),
        "state_age_us": percentiles(res["state_age_us"]),
        "stale_states": int(summary.get("stale_states", 0)),
        "dropped": int(c.get("cmd_timeout", 0) + c.get("cmd_stale_ticks", 0)),
        "malformed": int(ctl_rej.get("malformed", 0) + ctl_rej.get("trailing_bytes", 0)
                         + c.get("malformed", 0) + c.get("trailing_bytes", 0)),
        "scheduler": summary.get("scheduler", "unknown"),
        "rows": rows,
        "wall_s": wall,
        "steps_per_s": rows / wall if wall > 0 else None,
        "emulator_tick_lateness_us": percentiles(res["tick_lateness_us"]) if mode == "realtime"
        else {"p50": None, "p99": None, "max": None},
        **(lateness_counts(res, summary.get("trigger")) if mode == "realtime" else {}),
        "controller_rejected": ctl_rej,
        "controller_safe_steps": int(summary.get("safe_steps", 0)),
        "emulator_counters": dict(c),
        "command_gaps_s": [list(g) for g in res.gaps],
        "faults_applied": res.faults_applied,
        # how the run was scheduled and how fresh it was: filled by sc-rt hil
        # (hil/bench_end.py bench_timing); a log does not say (sc-rt report: None)
        "trigger": summary.get("trigger"), "null_law": summary.get("null_law"), "timing_setup": None,
        "emulator_scheduler": None, "fresh_fraction": None,
        "controller_fresh_fraction": (1.0 - int(summary.get("stale_states", 0)) / int(summary["steps"])
                                      if summary.get("steps") else None),
        "emulator_breakdown_us": None, "record_writer_waits": None, "load_avg": None,
    }


def realtime_shortfall(timing: dict[str, Any], limits: RealtimeLimits) -> str | None:
    """Why a real-time run did not keep real time (one line), None when it
    did (or for a lockstep run, which has no deadlines)."""
    if timing.get("mode") != "realtime":
        return None
    steps = max(1, int(timing.get("steps") or 0))
    rows = max(1, int(timing.get("rows") or 0))
    skipped = max(0, rows - int(timing.get("steps") or 0))
    over = []
    for name, count, n, limit in (("deadline misses", timing.get("deadline_misses", 0), steps, limits.misses),
                                  ("periods without a step", skipped, rows, limits.skipped),
                                  ("dropped ticks", timing.get("dropped", 0), rows, limits.dropped),
                                  ("stale states", timing.get("stale_states", 0), steps, limits.stale)):
        count = int(count or 0)
        if count > max(limits.allowance, limit * n):
            over.append(f"{name} {count} of {n} ({100 * count / n:.2g} % > {100 * limit:g} %)")
    if "answers_judged" in timing:  # judged against the control period (lateness_counts)
        for name, count, n, limit in (("answers later than a period", timing["answers_over_period"],
                                       max(1, int(timing["answers_judged"])), limits.late),
                                      ("ticks later than a period", timing["ticks_over_period"], rows,
                                       limits.late_ticks)):
            if count > max(limits.allowance, limit * n):
                over.append(f"{name} {count} of {n} ({100 * count / n:.2g} % > {100 * limit:g} %)")
        worst = float(timing["worst_tick_lateness_periods"])
        if worst > limits.stall:
            over.append(f"the plant's worst tick {worst:.0f} periods late (> {limits.stall:g})")
    if not over:
        return None
    rate = timing.get("steps_per_s")
    return ("did not keep real time: " + ", ".join(over)
            + (f"; {rate:.0f} steps/s at {timing.get('control_rate_hz'):g} Hz" if rate else ""))
