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
  fault state;
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
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import lcm
import numpy as np

from sc_rt.scenario.model import LAW_NAMES
from sc_rt.bus.lcmio import CHANNELS, lcm_binary
from sc_rt.bus.wire import STATUS_RUN_FIELDS, STATUS_TIMING_FIELDS, TYPES, decode_any, decode_array, numpy_dtype
from sc_rt.results.metrics import fill_tracking_errors, finish_run
from sc_rt.results.output import write_run
from sc_rt.results.run import Run, RunMeta, empty_arrays, json_safe

__all__ = ["LogData", "read_log", "rebuild", "write_report", "replay_command", "LAW_NAMES"]

#: fault state changes listed per wheel in report.json (a hostile log could have one per row)
MAX_FAULT_CHANGES = 1000


@dataclass
class LogData:
    path: Path
    events: int
    prefix: str
    decode_s: float
    records: dict[str, np.ndarray]  # base channel name -> structured array, log order
    stamps: dict[str, np.ndarray]  # base channel name -> logger receive time [us]
    messages: dict[str, list]  # variable-size types: base name -> [(stamp, msg)]
    channels: dict[str, dict[str, Any]]  # every channel: type, count, undecodable by kind
    skipped: dict[str, int] = field(default_factory=dict)

    @property
    def undecodable(self) -> int:
        return sum(sum(c["undecodable_kinds"].values()) for c in self.channels.values())


def _reader(log: lcm.EventLog):
    c = getattr(log, "c_eventlog", None)
    if c is not None and hasattr(c, "read_next_event"):
        return c.read_next_event  # (eventnum, timestamp, channel, data) tuples, no Event object

    def nxt():
        e = log.read_next_event()
        return None if e is None else (e.eventnum, e.timestamp, e.channel, e.data)

    return nxt


def _detect_prefix(names) -> str:
    found = sorted({n[: -len("SCRT_STATE")] for n in names if n.endswith("SCRT_STATE")})
    if len(found) > 1:
        raise ValueError(f"the log holds several benches (channel prefixes {found}): pass --prefix")
    return found[0] if found else ""


def read_log(path: str | Path, prefix: str | None = None) -> LogData:
    """Read and decode every event of our channels."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such log")
    t0 = time.perf_counter()
    log = lcm.EventLog(str(path), "r")
    nxt = _reader(log)
    by_ch: dict[str, list] = {}
    events = bad_run = 0
    while True:
        try:
            ev = nxt()
        except (UnicodeDecodeError, ValueError, OSError):
            # an event the reader cannot even represent (a channel name that
            # is not UTF-8; the reader has moved past it): count it, go on
            by_ch.setdefault("<unreadable>", []).append((0, 0, "", b""))
            events += 1
            bad_run += 1
            if bad_run > 10000:  # a reader that no longer advances: stop, keep what was read
                break
            continue
        bad_run = 0
        if ev is None:
            break
        events += 1
        lst = by_ch.get(ev[2])
        if lst is None:
            lst = by_ch[ev[2]] = []
        lst.append(ev)
    log.close()
    prefix = _detect_prefix(by_ch) if prefix is None else prefix
    records, stamps, messages, channels = {}, {}, {}, {}
    for base, (tname, _who, _rate) in CHANNELS.items():
        ch = prefix + base
        lst = by_ch.pop(ch, [])
        cls = TYPES[tname]
        counts: Counter = Counter()
        if numpy_dtype(cls) is not None:
            rec, idx = decode_array(cls, [e[3] for e in lst], counts)
            records[base] = rec
            stamps[base] = np.fromiter((e[1] for e in lst), np.int64, len(lst))[idx]
        else:
            msgs = []
            for e in lst:
                _c, m = decode_any(e[3], counts)
                if m is not None and isinstance(m, cls):
                    msgs.append((e[1], m))
                elif m is not None:
                    counts["unknown_type"] += 1
            messages[base] = msgs
        channels[ch] = {"type": tname, "count": len(lst),
                        "undecodable": int(sum(counts.values())), "undecodable_kinds": dict(counts)}
    skipped = {ch: len(v) for ch, v in sorted(by_ch.items())}
    return LogData(path, events, prefix, time.perf_counter() - t0, records, stamps, messages,
                   channels, skipped)


def _align(rows: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each row seq: whether ``keys`` (unique, sorted) has it, and where."""
    if keys.size == 0:
        return np.zeros(rows.size, bool), np.zeros(rows.size, np.int64)
    pos = np.clip(np.searchsorted(keys, rows), 0, keys.size - 1)
    return keys[pos] == rows, pos


def _f(a) -> np.ndarray:
    return np.asarray(a, dtype=float)  # big-endian -> native


@dataclass
class Rebuilt:
    """The run as the emulator recorded it, and what only the log knows."""

    arrays: dict[str, np.ndarray]  # run fields (sc_rt.results.run.FIELDS)
    has_truth: np.ndarray  # rows with their plant_truth_t
    last_status: dict[str, Any] | None
    mode: str
    gaps: list[tuple[float, float]]


def _first_valid(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique non-negative keys (sorted) and the index of the first record
    holding each, into the original array (fields are then fetched one by
    one: indexing whole records of a wide structured array is slow)."""
    valid = np.nonzero(keys >= 0)[0]
    u, first = np.unique(keys[valid], return_index=True)
    return u, valid[first]


def _applied_cmd(C: np.ndarray, c_stamp: np.ndarray, seq: np.ndarray, stamp: np.ndarray) -> np.ndarray:
    """Index of the wheel_cmd_t with each ``seq`` (-1: none in the log).

    Several commands can share a seq: a restarted controller numbers from 0
    again in a new session, and a hostile publisher can replay one. Among
    those logged before ``stamp`` (the truth that names the command), the
    newest one gives the session in use, and the first of that session is
    taken, as the emulator does (it drops repeats of a seq)."""
    out = np.full(len(seq), -1, np.int64)
    if C.size == 0 or len(seq) == 0:
        return out
    order = np.lexsort((c_stamp, C["seq"]))
    cs, st = C["seq"][order], c_stamp[order]
    lo = np.searchsorted(cs, seq, "left")
    hi = np.searchsorted(cs, seq, "right")
    one = hi > lo
    out[one] = order[lo[one]]
    sess = C["session"] if "session" in (C.dtype.names or ()) else None
    for j in np.nonzero(hi - lo > 1)[0]:  # rare: pick by time and session
        cand = order[lo[j]:hi[j]]
        before = cand[: max(int(np.searchsorted(st[lo[j]:hi[j]], stamp[j], "right")), 1)]
        pick = before[-1]
        if sess is not None:
            pick = before[np.nonzero(sess[before] == sess[pick])[0][0]]
        out[j] = pick
    return out


def rebuild(d: LogData, mode: str | None = None) -> Rebuilt:
    """The trajectory, one row per plant state, as the emulator recorded it."""
    S = d.records["SCRT_STATE"]
    seqs, si = _first_valid(S["seq"])
    s_stamp = d.stamps["SCRT_STATE"][si]
    n = seqs.size
    # every run field at its fill value; then what the log has
    traj = empty_arrays(n)
    for k in ("t", "sigma_BN", "omega_BN_B", "wheel_speed"):
        traj[k] = _f(S[k][si])
    traj["state_log_us"] = s_stamp.astype(float)
    has_truth = np.zeros(n, bool)

    C = d.records["SCRT_CMD"]

    # truth: the command the plant applied from t on
    T = d.records["SCRT_TRUTH"]
    t_seqs, ti = _first_valid(T["seq"])
    has, pos = _align(seqs, t_seqs)
    if np.any(has):
        tm = ti[pos[has]]
        for k in ("u_cmd", "wheel_accel", "delta2"):
            traj[k][has] = _f(T[k][tm])
        for k in ("cmd_seq_applied", "cmd_stale", "fault_Y", "fault_effectiveness", "fault_bias",
                  "fault_stuck"):
            traj[k][has] = T[k][tm]
        has_truth[has] = True
        applied = traj["cmd_seq_applied"]
        none = has & (applied < 0)
        traj["u_sat"][none] = 0.0  # nothing applied: the emulator records zeros
        rows = np.nonzero(has & (applied >= 0))[0]
        idx = _applied_cmd(C, d.stamps["SCRT_CMD"], applied[rows], d.stamps["SCRT_TRUTH"][ti[pos[rows]]])
        ok = idx >= 0
        traj["u_sat"][rows[ok]] = _f(C["u_sat"][idx[ok]])
        traj["flags"][rows[ok]] = C["flags"][idx[ok]]
        traj["ctrl_mode"][rows[ok]] = C["mode"][idx[ok]]
    # a state without its truth: the command answering it (first received)
    miss = ~has
    if np.any(miss) and C.size:
        a_seqs, ai = _first_valid(C["state_seq"])
        ha, pa = _align(seqs, a_seqs)
        ha &= miss
        traj["u_cmd"][ha] = _f(C["u_cmd"][ai[pa[ha]]])
        traj["u_sat"][ha] = _f(C["u_sat"][ai[pa[ha]]])

    # controller status: the first one that used each state
    St = d.records["SCRT_CTRL_STATUS"]
    st_seqs, sti = _first_valid(St["state_seq"])
    hs, ps = _align(seqs, st_seqs)
    if np.any(hs):
        sm = sti[ps[hs]]
        for k in STATUS_RUN_FIELDS + STATUS_TIMING_FIELDS:
            traj[k][hs] = _f(St[k][sm])
    last_status = None
    if St.size:
        last = St[int(np.argmax(St["steps"]))]
        last_status = {k: int(last[k]) for k in ("steps", "deadline_misses", "stale_states", "rejected")}

    # state-to-command latency as the logger saw it: receipt of state k to
    # receipt of the first command answering k
    if C.size:
        a_seqs, ai = _first_valid(C["state_seq"])
        c_stamp = d.stamps["SCRT_CMD"][ai]
        hl, pl = _align(seqs, a_seqs)
        traj["latency_us"][hl] = (c_stamp[pl[hl]] - s_stamp[hl]).astype(float)

    if mode is None:
        wl = traj["wake_lateness_us"]
        wl = wl[np.isfinite(wl)]
        # the lockstep controller steps on arrival: its lateness is exactly 0
        mode = "lockstep" if wl.size and np.all(wl == 0) else "realtime"

    # spans without a command (the emulator's watchdog applied zero), as it records them
    h = has_truth
    th = traj["t"][h]
    st = traj["cmd_stale"][h].astype(bool)
    edge = np.diff(np.concatenate(([0], st.astype(np.int8), [0])))
    starts, ends = np.nonzero(edge == 1)[0], np.nonzero(edge == -1)[0]
    gaps = [(float(th[a]), float(th[b]) if b < th.size else float(traj["t"][-1]))
            for a, b in zip(starts, ends)]
    return Rebuilt(traj, has_truth, last_status, mode, gaps)


def _config(d: LogData):
    msgs = d.messages.get("SCRT_CONFIG", [])
    return msgs[0][1] if msgs else None


def _params(d: LogData, scenario_path: str | None):
    """(scenario name, law, rate, duration or None, ppc, umin, umax, source)."""
    cfg = _config(d)
    scn = None
    if scenario_path:
        from sc_rt.scenario.model import load_scenario

        scn = load_scenario(scenario_path)
    if cfg is not None:
        ppc = {k: tuple(float(x) for x in getattr(cfg, "ppc_" + k))
               for k in ("chi0", "chiinf", "gamma", "dmin", "dmax")}
        return (cfg.scenario, LAW_NAMES.get(cfg.law, str(cfg.law)), float(cfg.control_rate_hz),
                None if scn is None else float(scn.run.duration), ppc,
                np.asarray(cfg.umin, float), np.asarray(cfg.umax, float), "SCRT_CONFIG")
    if scn is not None:
        m = RunMeta.of_scenario(scn, "report")
        return (scn.name, scn.run.controller, float(scn.run.control_rate_hz), float(scn.run.duration),
                m.ppc, np.asarray(scn.actuators.umin), np.asarray(scn.actuators.umax),
                f"--scenario {scenario_path}")
    raise ValueError(f"{d.path}: no controller_config_t on {d.prefix}SCRT_CONFIG (a log from "
                     "before sc-rt hil logged it, or from another bench): pass --scenario FILE "
                     "for the PPC envelope, the law and the rate")


def _guidance(d: LogData, scenario_path: str | None):
    """The desired trajectory's parameters (_core.GuidanceParams), from the
    logged controller_config_t or the scenario file."""
    from sc_rt import _core

    cfg = _config(d)
    if cfg is not None:
        return _core.ControllerConfig.from_lcm_bytes(cfg.encode()).guidance
    from sc_rt.scenario.model import load_scenario

    return load_scenario(scenario_path).core_config().guidance


def fault_summary(d: LogData, r: Rebuilt) -> dict[str, Any]:
    """Fault commands seen on the bus and the fault state changes in
    plant_truth_t (when the emulator applied them)."""
    F = d.records["SCRT_FAULT"]
    fs = d.stamps["SCRT_FAULT"]
    st = r.arrays["state_log_us"]
    t = r.arrays["t"]
    t0 = int(st[0]) if st.size else 0
    cmds = []
    for rec, stamp in zip(F, fs):
        k = int(np.searchsorted(st, stamp, side="right")) - 1  # newest state logged before it
        cmds.append({"log_s": (int(stamp) - t0) / 1e6, "t_sim_at_receipt": float(t[k]) if k >= 0 else None,
                     "wheel": int(rec["wheel"]),
                     "action": {1: "inject", 2: "clear"}.get(int(rec["action"]), int(rec["action"])),
                     "now": bool(rec["now"]), "t_onset": float(rec["t_onset"]), "t_end": float(rec["t_end"]),
                     "effectiveness": float(rec["effectiveness"]), "bias": float(rec["bias"]),
                     "rate": float(rec["rate"]), "stuck": bool(rec["stuck"])})
    changes: list[dict[str, Any]] = []
    h = r.has_truth
    L, B, K, Y = (r.arrays[k][h] for k in ("fault_effectiveness", "fault_bias", "fault_stuck", "fault_Y"))
    th = t[h]
    active_from: list[float | None] = []
    for w in range(4):
        cur = np.stack([L[:, w], B[:, w], K[:, w].astype(float)], axis=1)
        healthy = np.array([1.0, 0.0, 0.0])
        prev = np.vstack([healthy, cur[:-1]]) if th.size else cur
        idx = np.nonzero(np.any(cur != prev, axis=1))[0]
        for i in idx[:MAX_FAULT_CHANGES]:
            changes.append({"t": float(th[i]), "wheel": w + 1, "effectiveness": float(L[i, w]),
                            "bias": float(B[i, w]), "stuck": bool(K[i, w])})
        on = np.nonzero(Y[:, w] > 0)[0]
        active_from.append(float(th[on[0]]) if on.size else None)
    changes.sort(key=lambda c: (c["t"], c["wheel"]))
    return {"commands": cmds, "state_changes": changes, "first_active_s": active_from}


def _timing(run: Run, r: Rebuilt, d: LogData, wall: float) -> dict[str, Any]:
    from sc_rt.bus.hil import timing_report

    stale = int(np.sum(run["cmd_stale"]))
    run.counters = {"cmd_timeout" if r.mode == "lockstep" else "cmd_stale_ticks": stale,
                    "malformed": d.undecodable}
    ls = r.last_status or {}
    summary = {"steps": ls.get("steps", len(run)), "deadline_misses": ls.get("deadline_misses", 0),
               "stale_states": ls.get("stale_states", 0), "scheduler": "unknown (not in the log)"}
    out = timing_report(run, summary, wall)
    out["source"] = "log"
    out["controller_rejected_total"] = ls.get("rejected")
    out["state_to_cmd_latency_source"] = "lcm-logger receive times"
    return out


def write_report(log: str | Path, out: str | Path, *, scenario: str | None = None,
                 prefix: str | None = None, mode: str | None = None, plots: bool = True) -> dict[str, Any]:
    """Read ``log`` and write metrics.json, timing.json, trajectory.npz,
    report.json and the figures into ``out``; returns report.json's content."""
    out = Path(out)
    d = read_log(log, prefix)
    if d.records["SCRT_STATE"].size == 0:
        raise ValueError(f"{d.path}: no plant_state_t on {d.prefix}SCRT_STATE: nothing to report")
    name, law, rate, duration, ppc, umin, umax, source = _params(d, scenario)
    t_build = time.perf_counter()
    r = rebuild(d, mode)
    # a log cut short (an interrupted, crashed or full-disk run) ends with
    # states whose command and truth never came: the complete rows only
    complete = int(np.flatnonzero(r.has_truth)[-1]) + 1 if np.any(r.has_truth) else len(r.has_truth)
    dropped = len(r.has_truth) - complete
    if dropped:
        r = dataclasses.replace(r, arrays={k: v[:complete] for k, v in r.arrays.items()},
                                has_truth=r.has_truth[:complete])
    rows = len(r.arrays["t"])
    short = duration is not None and rows and float(r.arrays["t"][-1]) < duration - 0.5 / rate
    if duration is None:
        duration = (rows - 1) / rate if rows else 0.0
    st = r.arrays["state_log_us"]
    wall = float(st[-1] - st[0]) / 1e6 if st.size > 1 else 0.0
    meta = RunMeta(scenario=name, law=law, engine="report", control_rate_hz=rate, duration_s=duration,
                   ppc=ppc, umin=tuple(float(x) for x in umin), umax=tuple(float(x) for x in umax),
                   wall_s=wall, mode=r.mode)
    run = Run(meta, r.arrays, gaps=r.gaps, partial=bool(dropped or short))
    if run.partial:
        run.metrics = {"t_reached_s": float(r.arrays["t"][-1]) if rows else None,
                       "incomplete_rows_dropped": dropped}
    fill_tracking_errors(run, _guidance(d, scenario))
    faults = fault_summary(d, r)
    run.faults_applied = faults["commands"]
    finish_run(run)
    run.timing = _timing(run, r, d, wall)
    build_s = time.perf_counter() - t_build
    # uncompressed: zlib would take longer than reading a million-event log
    write_run(run, out, figures=plots, compress=False)
    report = {"log": str(d.path), "events": d.events, "read_decode_s": d.decode_s,
              "events_per_s": d.events / d.decode_s if d.decode_s > 0 else None,
              "rebuild_s": build_s, "prefix": d.prefix, "mode": r.mode, "rows": rows,
              "incomplete_rows_dropped": dropped, "partial": run.partial,
              "parameters_from": source, "undecodable": d.undecodable, "channels": d.channels,
              "skipped": d.skipped, "faults": faults}
    cfg = _config(d)
    if cfg is not None:
        report["config"] = {"scenario": cfg.scenario, "law": law, "control_rate_hz": rate}
    (out / "report.json").write_text(json.dumps(json_safe(report), indent=2) + "\n")
    report["metrics"] = run.metrics
    report["timing"] = run.timing
    return report


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

