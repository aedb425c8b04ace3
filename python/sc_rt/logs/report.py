"""``sc-rt report LOG``: the run's metrics, timing report and figures, rebuilt
from an ``lcm-logger`` log alone; ``sc-rt replay LOG``: the log back onto a bus.

The log is read with ``lcm.EventLog``; the messages of each channel are
decoded together from their raw bytes (numpy structured arrays over the
fixed big-endian layouts of the generated types), so a million events take
seconds. Channels that are not ours (``LCM_SELF_TEST``, ``SCRT_HIL_START``,
anything else) are skipped and counted; events on our channels that are not
exactly one message of the channel's type are counted as undecodable, never
fatal.

The trajectory has one row per plant state (``plant_state_t.seq``):

- ``plant_state_t``: t, sigma_BN, omega_BN_B, wheel_speed;
- ``plant_truth_t`` with the same seq: the command the plant applied from t
  on (u_cmd, and which ``wheel_cmd_t`` it was), wheel_accel, delta2, the
  fault state, and with magnetic control the rods' commands the plant held
  (rod_dipole_cmd; a log of the older layout without the rods' truth: the
  ``rod_cmd_t`` matched by the applied wheel command's seq) and with rods
  what they applied (m_B, rod_dipole);
- ``wheel_cmd_t``: u_sat of the applied command (lockstep: the answer to
  that state; real time: the newest held);
- the first ``controller_status_t`` that used the state: sigma_DN, sigma_BD,
  omega_BD_B, z1, z2, chi, lam and the controller's timing.

That is what the emulator records during the run, so on a lockstep run the
metrics are the run's own, exactly. The PPC envelope for ``bound_ok`` comes
from the ``controller_config_t`` that ``sc-rt hil`` logs on SCRT_CONFIG at
start (or ``--scenario``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import time
from pathlib import Path
from typing import Any

import numpy as np
import sc_rt_lcm

from sc_rt.wire.lcmio import lcm_binary
from sc_rt.logs.logread import LogData, read_log
from sc_rt.logs.timing import RealtimeLimits, log_missing, realtime_shortfall, timing_report
from sc_rt.logs.faults import fault_summary
from sc_rt.logs.rebuild import (Rebuilt, controller_label, logged_config, logged_guidance, rebuild,
                               run_params, sensor_summary)
from sc_rt.pylaw import FLAG_LAW_INVALID
from sc_rt.results.judge.metrics import fill_tracking_errors, finish_run, mark_invalid
from sc_rt.results.present.output import write_run
from sc_rt.results.record.meta import command_fields
from sc_rt.results.record.run import Run, RunMeta, json_safe, provenance

__all__ = ["LogData", "read_log", "rebuild", "write_report", "replay_command", "plant_sessions",
           "command_conflicts"]


def _timing(run: Run, r: Rebuilt, d: LogData, wall: float) -> dict[str, Any]:
    stale = int(np.sum(run["cmd_stale"]))
    run.counters = {"cmd_timeout" if r.mode == "lockstep" else "cmd_stale_ticks": stale,
                    "malformed": d.undecodable}
    ls = r.last_status or {}
    summary = {"steps": ls.get("steps", len(run)), "deadline_misses": ls.get("deadline_misses", 0),
               "stale_states": ls.get("stale_states", 0), "scheduler": "unknown (not in the log)"}
    out = timing_report(run, summary, wall)
    out["source"] = "log"
    # sc-rt hil's end marker in the log: everything published before it was logged
    out["log_complete"] = d.skipped.get(d.prefix + "SCRT_HIL_END", 0) > 0
    out["logger_scheduler"] = "unknown (not in the log)"
    out["logger"] = None  # its exit summary is not in the log
    if d.start is not None:  # the run's own record: how it was triggered
        out["trigger"] = d.start.get("trigger")
        out["mode"] = d.start.get("mode", out["mode"])
    # with magnetic control (its ideal field in the log) a field per row too, as sc-rt hil counts it;
    # a magnetometer's samples are counted as the other sensors' (sensor_summary's seq_missing)
    mag = d.records.get("SCRT_MAG")
    ideal = mag is not None and bool(np.any(mag["source"] == sc_rt_lcm.magnetometer_t.SOURCE_TRUE_FIELD))
    out["log_missing"] = log_missing(d.path, d.prefix, len(run), {"SCRT_MAG": len(run)} if ideal else None)
    out["controller_rejected_total"] = ls.get("rejected")
    out["state_to_cmd_latency_source"] = "lcm-logger receive times"
    if out.get("mode") == "realtime":
        _judge_real_time(run, out, (d.start or {}).get("rt_limits"))
    return out


def _judge_real_time(run: Run, timing: dict[str, Any], logged: dict[str, Any] | None) -> None:
    """The live run's "kept real time" from the log: the same limits (the
    run's own, from its start record; the defaults for a log without them)
    on what the log holds: the controller's last status (steps, deadline
    misses, stale states), the rows whose command was stale, and the
    state-to-command latency as the logger received them."""
    names = {f.name for f in dataclasses.fields(RealtimeLimits)}
    limits = RealtimeLimits(**{k: v for k, v in (logged or {}).items() if k in names})
    why = realtime_shortfall(timing, limits)
    timing["kept_real_time"] = why is None
    timing["realtime_limits"] = dataclasses.asdict(limits)
    timing["realtime_limits_source"] = "the run's start record" if logged else "the defaults (not in the log)"
    if why is not None:
        mark_invalid(run, f"{why} (judged from the log)")


def _main_session(records: np.ndarray) -> int | None:
    """The session of the run's end: the most frequent among the channel's
    last 1000 messages (a hostile publisher draws a new one per message)."""
    if records.size == 0 or "session" not in (records.dtype.names or ()):
        return None
    v, n = np.unique(records["session"][-1000:], return_counts=True)
    return int(v[np.argmax(n)])


#: states of one session below which it is not a plant but stray or forged
#: messages (the emulator's own bench-collision rule: 20 well-formed states)
PLANT_MIN_STATES = 20


def plant_sessions(records: np.ndarray) -> list[dict[str, Any]]:
    """The plants whose states the log holds, in order of their first state:
    session, states, first and last t (sessions of fewer than
    PLANT_MIN_STATES states are not plants: stray or forged messages)."""
    if records.size == 0 or "session" not in (records.dtype.names or ()):
        return []
    v, first, n = np.unique(records["session"], return_index=True, return_counts=True)
    out = []
    for i in np.argsort(first):
        if n[i] >= PLANT_MIN_STATES:
            t = records["t"][records["session"] == v[i]]
            out.append({"session": int(v[i]), "states": int(n[i]), "first_t": float(t[0]), "last_t": float(t[-1])})
    return out


def _requirements(d, scenario: str | None) -> tuple[dict[str, Any], ...]:
    """What the log is judged by: ``--scenario``'s [[requirements]] when given
    (judging a run by another budget), else the run's own from its start
    record; none for a log from before sc-rt logged them."""
    if scenario:
        from sc_rt.scenario.reader import load_scenario

        return tuple(dataclasses.asdict(r) for r in load_scenario(scenario).requirements)
    return tuple((d.start or {}).get("requirements") or ())


def _expect(d, scenario: str | None) -> str:
    """The verdict the run's file expects (its ``expect``): ``--scenario``'s
    when given, else the start record's; "" for none."""
    if scenario:
        from sc_rt.scenario.reader import load_scenario

        return load_scenario(scenario).expect
    return str((d.start or {}).get("expect") or "")


def write_report(log: str | Path, out: str | Path, *, scenario: str | None = None,
                 prefix: str | None = None, mode: str | None = None, plots: bool = True) -> dict[str, Any]:
    """Read ``log`` and write metrics.json, timing.json, trajectory.arrow,
    report.json and the figures into ``out``; returns report.json's content."""
    out = Path(out)
    d = read_log(log, prefix)
    if d.records["SCRT_STATE"].size == 0:
        raise ValueError(f"{d.path}: no plant_state_t on {d.prefix}SCRT_STATE: nothing to report")
    name, law, rate, duration, ppc, umin, umax, source = run_params(d, scenario)
    if duration is None and (d.start or {}).get("duration_s") is not None:
        duration = float(d.start["duration_s"])  # the run's own duration (its start record): a log cut short is partial
    law = controller_label(d, law)  # the law that answered (its announcement), not only the configured one
    t_build = time.perf_counter()
    r = rebuild(d, mode)
    # the complete rows only: a log cut short (an interrupted, crashed or
    # full-disk run) ends with states whose command and truth never came, and
    # a logger that fell behind lost some rows' plant_truth_t
    keep = r.has_truth.copy() if np.any(r.has_truth) else np.ones(len(r.has_truth), bool)
    at_end = len(keep) - (int(np.flatnonzero(keep)[-1]) + 1) if len(keep) else 0
    dropped = int(len(keep) - np.count_nonzero(keep))
    if dropped:
        r = dataclasses.replace(r, arrays={k: v[keep] for k, v in r.arrays.items()}, has_truth=r.has_truth[keep])
    rows = len(r.arrays["t"])
    short = duration is not None and (not rows or float(r.arrays["t"][-1]) < duration - 0.5 / rate)
    if duration is None:
        duration = (rows - 1) / rate if rows else 0.0
    st = r.arrays["state_log_us"]
    wall = float(st[-1] - st[0]) / 1e6 if st.size > 1 else 0.0
    cfg = logged_config(d)
    extra = {} if cfg is None or not cfg.nav_enabled else {
        "sensors": True, "measurement": "estimate" if cfg.nav_use_estimate else "truth"}
    if cfg is not None:  # the wheels' geometry the controller was configured with (a momentum requirement)
        extra.update(Cbar=tuple(tuple(float(x) for x in row) for row in cfg.Cbar),
                   Jw=tuple(float(x) for x in cfg.Jw))
    ident = (d.start or {}).get("law")
    if ident and ident.get("name") and ident.get("source") != "external":
        law = ident["name"]  # an external controller: the name it announced (controller_label)
    if cfg is not None:  # the wheels' command interface the controller was configured with, and the law's
        extra.update(command_fields("torque" if cfg.wheel_torque_command else "acceleration",
                                    (ident or {}).get("spec") if (ident or {}).get("source") != "external" else None))
    meta = RunMeta(scenario=name, law=law, engine="report", control_rate_hz=rate, duration_s=duration,
                   ppc=ppc, umin=tuple(float(x) for x in umin), umax=tuple(float(x) for x in umax),
                   wall_s=wall, mode=r.mode, law_identity=ident, requirements=_requirements(d, scenario),
                   expect=_expect(d, scenario), inputs=(d.start or {}).get("inputs") or {},
                   telemetry_names=tuple((d.start or {}).get("telemetry_names") or ()), **extra)
    run = Run(meta, r.arrays, gaps=r.gaps, partial=bool(at_end or short))
    if run.partial:
        run.metrics = {"t_reached_s": float(r.arrays["t"][-1]) if rows else None, "stopped": _stopped(d.end)}
    if dropped:
        run.metrics.update(incomplete_rows_dropped=dropped, incomplete_rows_at_end=at_end)
    run.metrics.update(provenance(_main_session(d.records["SCRT_STATE"]), _main_session(d.records["SCRT_CMD"])))
    plants = plant_sessions(d.records["SCRT_STATE"])
    if len(plants) > 1 and d.start is not None:  # a sc-rt hil run has one plant: the live run says collision
        mark_invalid(run, f"the log holds the states of {len(plants)} plants (sessions "
                          + ", ".join(f"{p['session']:#x}" for p in plants)
                          + "); a sc-rt hil run has one: another bench on the same URL and prefix (judged "
                            "from the log)")
    if (conflicts := command_conflicts(d.records["SCRT_CMD"])):  # the live run's cmd_conflict, from the log
        mark_invalid(run, f"{conflicts} commands carried another command's session and seq: a forged or racing "
                          "sender on the bus (docs/PROTOCOL.md, 'Sequence numbers'; judged from the log)")
    if d.end is not None and d.end.get("died"):  # how the controller ended: the bench saw it, no message does
        mark_invalid(run, f"{d.end['died']} (the bench's end record in the log)")
    guidance = logged_guidance(d, scenario)
    fill_tracking_errors(run, guidance)
    faults = fault_summary(d, r)
    run.faults_applied = faults["commands"]
    finish_run(run, guidance)
    _law_failures_from_flags(run)
    run.timing = _timing(run, r, d, wall)
    build_s = time.perf_counter() - t_build
    write_run(run, out, figures=plots)
    report = {"log": str(d.path), "events": d.events, "read_decode_s": d.decode_s,
              "events_per_s": d.events / d.decode_s if d.decode_s > 0 else None,
              "rebuild_s": build_s, "prefix": d.prefix, "mode": r.mode, "rows": rows,
              "mode_source": "the run's start record" if (d.start or {}).get("mode") and mode is None
              else "--mode" if mode is not None else "guessed from the controller's wake lateness (no start record)",
              "start": d.start,
              "incomplete_rows_dropped": dropped, "incomplete_rows_at_end": at_end, "partial": run.partial,
              "parameters_from": source, "undecodable": d.undecodable, "channels": d.channels,
              "skipped": d.skipped, "faults": faults, "sensors": sensor_summary(d), "plant_sessions": plants,
              "end": d.end, "command_conflicts": conflicts}
    if cfg is not None:
        report["config"] = {"scenario": cfg.scenario, "law": law, "control_rate_hz": rate}
    (out / "report.json").write_text(json.dumps(json_safe(report), indent=2) + "\n")
    report["metrics"] = {**run.metrics, **({"inputs": meta.inputs} if meta.inputs else {})}  # as metrics.json
    report["timing"] = run.timing
    return report


def _stopped(end: dict[str, Any] | None) -> str:
    """Why a log that ends before its run's duration stopped: the bench's
    own line from its end record (a state left unanswered, a controller that
    died or was killed over its memory limit, an interrupt), else what the
    log cannot tell."""
    if end is not None and end.get("stopped"):
        return f"{end['stopped']} (the bench's end record in the log)"
    why = ("the log ends before the run's duration (an interrupted, crashed or full-disk run, or a logger "
           "stopped early)")
    return why + ("" if end is not None else "; the log has no end record, so why the run stopped is not in it")


def command_conflicts(cmd: np.ndarray) -> int:
    """Commands of the log that carry the (session, seq) of another, different
    command (another answered state or another command): a forged or racing
    sender, the emulator's ``cmd_conflict`` (emulator/receiver.py). A
    controller's repeated identical command is not one. Non-finite commands,
    which the plant drops, are not counted."""
    names = set(cmd.dtype.names or ())
    if cmd.size < 2 or not {"session", "seq", "state_seq", "u_cmd"} <= names:
        return 0
    c = cmd[np.all(np.isfinite(cmd["u_cmd"]), axis=1)]
    c = c[np.lexsort((c["seq"], c["session"]))]  # stable: a key's messages in log order
    same = (c["session"][1:] == c["session"][:-1]) & (c["seq"][1:] == c["seq"][:-1])
    differs = (c["state_seq"][1:] != c["state_seq"][:-1]) | np.any(c["u_cmd"][1:] != c["u_cmd"][:-1], axis=1)
    return int(np.count_nonzero(same & differs))


def _law_failures_from_flags(run: Run) -> None:
    """The law's failures as the log shows them: the steps the controller
    flagged FLAG_LAW_INVALID (it commanded SAFE zeros instead). The live run
    counts them from the controller's summary (its messages are in
    controller_summary.json, not in the log); the verdict is the same."""
    n = int(run.metrics.get("law_invalid_steps") or 0)
    if n == 0:
        return
    first = None
    for c in run.chunks():
        hit = np.flatnonzero((np.asarray(c["flags"]) & FLAG_LAW_INVALID) != 0)
        if hit.size:
            first = float(c["t"][hit[0]])
            break
    mark_invalid(run, f"the law failed at {n} step{'s' if n > 1 else ''} (FLAG_LAW_INVALID in the log's "
                      f"commands; first at t = {first:.4g} s; the messages are in the live run's "
                      "controller_summary.json)")


def replay_command(log: str | Path, url: str, speed: float = 1.0, channels: str | None = None,
                   verbose: bool = False) -> list[str]:
    """The wheel's real lcm-logplayer, playing ``log`` onto ``url``."""
    if not Path(log).exists():
        raise FileNotFoundError(f"{log}: no such log")
    if not (speed > 0 and math.isfinite(speed)):
        raise ValueError(f"--speed must be > 0, got {speed}")
    cmd = [lcm_binary("lcm-logplayer"), "--speed", repr(float(speed)), "--lcm-url", url]
    if channels:
        cmd += ["--regexp", channels]
    if verbose:
        cmd.append("--verbose")
    return cmd + [str(log)]


def replay(log: str | Path, url: str, speed: float = 1.0, channels: str | None = None) -> int:
    return subprocess.call(replay_command(log, url, speed, channels))

