"""What a bench run's end says about it (``sc-rt hil``): the logger's exit
summary, the controller's death in one line, how the run was scheduled and
how fresh its commands were, and whether a real-time run kept real time."""

from __future__ import annotations

import dataclasses
import json
import os
import sys
from typing import Any

import numpy as np

from sc_rt.emulator.process import Emulator
from sc_rt.hil.external import ExternalController
from sc_rt.hil.floor import TimingSetup
from sc_rt.logs.timing import RealtimeLimits, realtime_shortfall
from sc_rt.results.judge.metrics import mark_invalid
from sc_rt.results.record.run import Run

__all__ = ["bench_timing", "death_line", "judge_real_time", "logger_summary", "run_trigger"]


def logger_summary(err: str) -> dict[str, Any] | None:
    """sc-rt-logger's exit summary (its stderr's last JSON line): events written, deepest queue."""
    for line in reversed(err.splitlines()):
        try:
            d = json.loads(line)
        except ValueError:
            continue
        if isinstance(d, dict) and "events" in d:
            return d
    return None


def judge_real_time(res: Run, summary: dict[str, Any], limits: RealtimeLimits) -> None:
    """One number of SAFE steps everywhere (the controller's, when it says:
    metrics.json, the console and timing.json agree; the rows that applied a
    SAFE command are safe_rows), and a real-time run that did not keep real
    time is invalid, with the reason (RealtimeLimits)."""
    if summary.get("safe_steps") is not None:
        res.metrics["safe_rows"] = res.metrics.get("safe_steps")
        res.metrics["safe_steps"] = int(summary["safe_steps"])
    why = realtime_shortfall(res.timing, limits)
    if res.timing.get("mode") == "realtime":
        res.timing["kept_real_time"] = why is None
        res.timing["realtime_limits"] = dataclasses.asdict(limits)
    if why is not None:
        mark_invalid(res, why)
        print(f"sc-rt hil: {why}", file=sys.stderr)


def death_line(res: Run, died: str, ext: ExternalController | None) -> str:
    """One line: which process died, how, and when (the time of the last
    state it answered, and of the row the bench stopped at)."""
    # a state answered by a command of its own (latency measured); a held
    # command (real time) is not an answer
    last = t_end = None
    for c in res.chunks():
        answered = np.flatnonzero(np.isfinite(c["latency_us"]))
        if answered.size:
            last = float(c["t"][answered[-1]])
        if len(c):
            t_end = float(c["t"][-1])
    when = f"at t = {last:.3f} s (the last state it answered)" if last is not None else \
        "before it answered any state"
    where = f"its stderr: {ext.stderr_name}" if ext else "its stderr: controller_stderr.txt"
    stop_t = f"; the run stopped at t = {t_end:.3f} s" if t_end is not None else ""
    return f"{died} {when}{stop_t}; the run is invalid ({where})"


def run_trigger(summary: dict[str, Any], setup: TimingSetup, told: bool) -> tuple[str | None, str | None]:
    """(the trigger the controller ran, the one it was asked for when it ran
    another): what its summary says; else the setup's when it was told it
    (sc-rt-controller, a Python law's sc-rt controller), None (unknown) for
    an --external process, which is never told. timing.json's ``trigger``
    and ``timing_setup.trigger`` are both the first, so they never disagree."""
    ran = summary.get("trigger")
    if ran is None:
        return (setup.trigger if told else None), None
    return ran, (setup.trigger if told and ran != setup.trigger else None)


def bench_timing(res: Run, summary: dict[str, Any], emu: Emulator, setup: TimingSetup,
                 told: bool = True) -> dict[str, Any]:
    """How the run was scheduled and how fresh its commands were: the share
    of rows that applied the answer to the state of the period just ended
    (real time: the command in hand at the tick answers the previous tick's
    state; lockstep: every answered state), the share of controller steps
    that had a new state, and where the emulator's microseconds went. The
    trigger is the one the controller ran (``run_trigger``; ``told``: the
    controller was given the setup's); a controller that ran another than
    it was told makes the run invalid (``trigger_asked`` says which)."""
    rows = len(res)
    if res.meta.mode == "realtime":
        fresh = emu.fresh_ticks / rows if rows else None
    else:
        fresh = 1.0 - res.counters.get("cmd_timeout", 0) / rows if rows else None
    steps = int(summary.get("steps", 0))
    trigger, asked = run_trigger(summary, setup, told)
    out: dict[str, Any] = {}
    if asked is not None and res.meta.mode == "realtime":
        why = f"the controller ran the {trigger} trigger, asked for {asked} (--trigger)"
        mark_invalid(res, why)
        print(f"sc-rt hil: {why}", file=sys.stderr)
        out["trigger_asked"] = asked
    return {
        "trigger": trigger,
        **out,
        "null_law": bool(summary.get("null_law", setup.null_law)),
        # the setup as the run had it: its trigger is the one that ran (never another than `trigger`)
        "timing_setup": {**dataclasses.asdict(setup), "trigger": trigger},
        "emulator_scheduler": emu.scheduler,
        "fresh_fraction": fresh,
        "controller_fresh_fraction": 1.0 - int(summary.get("stale_states", 0)) / steps if steps else None,
        "emulator_breakdown_us": emu.breakdown(),
        # times the tick waited for the record's writer thread (emulator/record.py; 0: never)
        "record_writer_waits": emu.record.writer_waits,
        "load_avg": list(os.getloadavg()),
    }
