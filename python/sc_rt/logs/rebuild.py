"""A run rebuilt from its log: one row per plant state (``plant_state_t.seq``),
filled as the emulator filled it during the run (see logs/report.py's module
docstring for which message gives which field), so a lockstep run's record
and metrics come back exactly. Also the run's parameters from the logged
``controller_config_t`` (the fault commands and what the plant made of them:
logs/faults.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import sc_rt_lcm

from sc_rt.logs.logread import LogData
from sc_rt.wire.codec import STATUS_FROM_COMMANDS, STATUS_NAV_FIELDS, STATUS_RUN_FIELDS, STATUS_TIMING_FIELDS
from sc_rt.results.record.run import RunMeta, empty_arrays
from sc_rt.scenario.model import LAW_NAMES

__all__ = ["Rebuilt", "rebuild", "sensor_summary", "logged_config", "run_params", "controller_label", "logged_guidance"]


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

    arrays: dict[str, np.ndarray]  # run fields (sc_rt.results.record.run.FIELDS)
    has_truth: np.ndarray  # rows with their plant_truth_t
    last_status: dict[str, Any] | None
    mode: str
    gaps: list[tuple[float, float]]
    #: the rods' truth per row (plant_truth_t of the current layout with rods): ``rod_dipole`` [A m^2]
    #: (n, 6) each rod's dipole applied, ``dipole_B`` [A m^2] (n, 3), ``rod_fault`` (n, 6) int (its
    #: rod_fault); NaN / 0 for a row without it. None: no row has it (no rods, or an older log)
    rods: dict[str, np.ndarray] | None = None


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


def _applied_rods(R: np.ndarray, has: np.ndarray, applied: np.ndarray, rows: np.ndarray,
                  ridx: np.ndarray) -> np.ndarray:
    """[A m^2] the rods' commands of the rows with their truth (``has``), as the
    emulator held them (emulator/twin.py RodHold): the rod command with the
    seq of the row's applied wheel command (``rows``: the rows that applied
    one, ``ridx``: its index in ``R``, -1 none), else the previous row's
    (zero-order hold); zero under the watchdog (no command applied)."""
    at = np.full(len(has), -1, np.int64)
    at[rows] = ridx
    out, held = [], np.zeros(6)
    for k in np.flatnonzero(has):
        if applied[k] < 0:
            held = np.zeros(6)
        elif at[k] >= 0:
            held = _f(R["dipole"][at[k]])
        out.append(held)
    return np.array(out).reshape(-1, 6)


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
    rods = None

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
        R = d.records.get("SCRT_ROD_CMD")
        cfg = logged_config(d)
        n_rods = T["n_rods"][tm]  # 0 in an older layout (plant_truth_v1_t) or without rods
        if np.any(n_rods > 0):
            rods = {"rod_dipole": np.full((n, 6), np.nan), "dipole_B": np.full((n, 3), np.nan),
                    "rod_fault": np.zeros((n, 6), np.int64)}
            at = np.flatnonzero(has)[n_rods > 0]
            for k in rods:
                rods[k][at] = T[k][tm[n_rods > 0]]
            # the record's rods' truth, as the emulator recorded it (NaN beyond the rods)
            traj["m_B"][at] = rods["dipole_B"][at]
            traj["rod_dipole"][at] = np.where(np.arange(6) < n_rods[n_rods > 0][:, None], rods["rod_dipole"][at],
                                              np.nan)
        if (R is not None and R.size) or (cfg is not None and cfg.mag_rods_enabled):
            # magnetic control: the rods' commands the row held, the truth's (the emulator's own), else
            # (a log of the older layout) rebuilt from rod_cmd_t matched by the applied wheel command's seq
            held = np.full((int(np.count_nonzero(has)), 6), np.nan)
            if R is not None and R.size:
                ridx = _applied_cmd(R, d.stamps["SCRT_ROD_CMD"], applied[rows],
                                    d.stamps["SCRT_TRUTH"][ti[pos[rows]]])
                held = _applied_rods(R, has, applied, rows, ridx)
            held[n_rods > 0] = _f(T["rod_dipole_cmd"][tm[n_rods > 0]])
            traj["rod_dipole_cmd"][has] = held
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
            if k in STATUS_FROM_COMMANDS:  # from the commands applied (_applied_rods)
                continue
            v = _f(St[k][sm])
            if traj[k].dtype.kind == "i":  # an integer field an older layout lacks (NaN) keeps its fill
                ok = np.isfinite(v)
                traj[k][np.flatnonzero(hs)[ok]] = v[ok].astype(np.int64)
            else:
                traj[k][hs] = v
        if "nav" in (St.dtype.names or ()):  # a [sensors] run: the estimator's fields and flag
            nav = np.zeros(n, bool)
            nav[hs] = St["nav"][sm] != 0
            if np.any(nav):
                src = sti[ps[nav]]
                for k in STATUS_NAV_FIELDS:
                    traj[k][nav] = _f(St[k][src])
                traj["flags"][nav] |= St["nav_flags"][src].astype(np.int64)
                # the gyro's true bias: the emulator's truth of the row
                nt = nav & has_truth
                if np.any(nt) and "gyro_bias" in (T.dtype.names or ()):
                    traj["bias_true"][nt] = _f(T["gyro_bias"][ti[pos[nt]]])
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

    if mode is None and d.start is not None and d.start.get("mode") in ("lockstep", "realtime"):
        mode = d.start["mode"]  # the run's own record (sc-rt hil's start record), not a guess
    if mode is None:  # a log without a start record: guessed, and the report says so (mode_source)
        wl = traj["wake_lateness_us"]
        wl = wl[np.isfinite(wl)]
        # the lockstep controller steps on arrival: its lateness is exactly 0
        mode = "lockstep" if wl.size and np.all(wl == 0) else "realtime"

    if mode == "realtime" and n:
        # the plant's tick lateness as the logger received its states: each
        # state's receipt against the schedule t / time_scale, from the most
        # punctual one (an estimate: the live run's is the emulator's own clock)
        scale = float((d.start or {}).get("time_scale") or 1.0)
        ahead = s_stamp.astype(float) - (traj["t"] - traj["t"][0]) * 1e6 / scale
        traj["tick_lateness_us"] = ahead - ahead.min()

    # spans without a command (the emulator's watchdog applied zero), as it records them
    h = has_truth
    th = traj["t"][h]
    st = traj["cmd_stale"][h].astype(bool)
    edge = np.diff(np.concatenate(([0], st.astype(np.int8), [0])))
    starts, ends = np.nonzero(edge == 1)[0], np.nonzero(edge == -1)[0]
    gaps = [(float(th[a]), float(th[b]) if b < th.size else float(traj["t"][-1]))
            for a, b in zip(starts, ends)]
    return Rebuilt(traj, has_truth, last_status, mode, gaps, rods)


#: sensor channel -> (summary name, time field)
_SENSORS = {"SCRT_GYRO": ("gyro", "t"), "SCRT_STAR": ("star_tracker", "t_delivery"),
            "SCRT_TACH": ("tachometer", "t"), "SCRT_MAG": ("magnetometer", "t")}


def sensor_summary(d: LogData) -> dict[str, Any]:
    """What the log holds of each sensor channel (a [sensors] run; {} without):
    samples of the main session, the seqs missing between its first and last
    (lost on the way to the logger), the sample rate in simulation time, and
    for the star tracker the latency and the emulator's own drop counters.
    SCRT_MAG: the magnetometer's samples only (source SOURCE_SENSOR; the ideal
    magnetometer's true field, one per state, is not a sensor's)."""
    out: dict[str, Any] = {}
    for base, (name, tf) in _SENSORS.items():
        R = d.records.get(base)
        if R is not None and base == "SCRT_MAG":
            R = R[R["source"] == sc_rt_lcm.magnetometer_t.SOURCE_SENSOR]
        if R is None or R.size == 0:
            continue
        v, c = np.unique(R["session"], return_counts=True)
        main = R[R["session"] == v[np.argmax(c)]]
        seq = np.unique(main["seq"])
        t = np.sort(_f(main[tf]))
        dt = np.diff(t)
        info: dict[str, Any] = {
            "samples": int(main.size), "other_sessions": int(R.size - main.size),
            "seq_first": int(seq[0]), "seq_last": int(seq[-1]),
            "seq_missing": int(seq[-1] - seq[0] + 1 - seq.size), "repeated": int(main.size - seq.size),
            "rate_hz": float(1.0 / np.median(dt)) if dt.size and np.median(dt) > 0 else None}
        if base == "SCRT_STAR":
            lat = _f(main["t_delivery"]) - _f(main["t_exposure"])
            last = main[np.argmax(main["seq"])]
            info.update(latency_s={"min": float(lat.min()), "max": float(lat.max())},
                        lost=int(last["lost"]), blacked_out=int(last["blacked_out"]))
        out[name] = info
    return out


def logged_config(d: LogData):
    msgs = d.messages.get("SCRT_CONFIG", [])
    return msgs[0][1] if msgs else None


def run_params(d: LogData, scenario_path: str | None):
    """(scenario name, law, rate, duration or None, ppc, umin, umax, source)."""
    cfg = logged_config(d)
    scn = None
    if scenario_path:
        from sc_rt.scenario.reader import load_scenario

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


def controller_label(d: LogData, configured: str) -> str:
    """The law that answered, as the log tells it: the name the controller
    announced (controller_info_t, the newest), else the law code of its
    status messages (a built-in law; else the configured one), else
    "external" when commands came from a controller that sent neither."""
    infos = [m for _stamp, m in d.messages.get("SCRT_CTRL_INFO", []) if m.law]
    if infos:
        return infos[-1].law
    st = d.records["SCRT_CTRL_STATUS"]
    if st.size:
        return LAW_NAMES.get(int(st["law"][-1]), configured)
    return "external" if d.records["SCRT_CMD"].size else configured


def logged_guidance(d: LogData, scenario_path: str | None):
    """The desired trajectory's parameters (_core.GuidanceParams), from the
    logged controller_config_t or the scenario file."""
    from sc_rt import _core

    cfg = logged_config(d)
    if cfg is not None:
        return _core.ControllerConfig.from_lcm_bytes(cfg.encode()).guidance
    from sc_rt.scenario.reader import load_scenario

    return load_scenario(scenario_path).core_config().guidance
