"""Offline closed loop: the plant (plant.py, or its C++ twin) and a control
law of the C++ core, sampled at the control rate with a zero-order hold.

Loop (both engines, identical arithmetic order):

    x = x0; controller.reset(measurement(0, x))
    for k = 0..N:                       t_k = k / rate
        command = controller.step(measurement(t_k, x))
        record row k (state, command, actual wheel acceleration, true delta_2)
        if k == N: stop
        repeat n_sub times: x = rk4_step(x, h, command.u_cmd)   (plant saturates)
        stop early at the first non-finite state

``sc-rt hil --mode lockstep`` runs the same loop over LCM and must give the
same numbers to the last bit as ``engine="python"``.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import threading
import time
from pathlib import Path

import numpy as np

from sc_rt import _core
from sc_rt.isolate import beat, beat_done, beating
from sc_rt.model import actuators, plant, truth
from sc_rt.model.momentum import total_momentum_N
from sc_rt.model.rods import rods_dipole_B
from sc_rt.pylaw import register
from sc_rt.results.judge.metrics import finish_run, record_law_failures
from sc_rt.sim.columns import LAW_FAILURES, TELEMETRY_NAMES, AppliedRods, loop_columns
from sc_rt.results.record.fields import COLUMNS, packed_layout
from sc_rt.results.record.run import FIELD, Run, RunMeta
from sc_rt.results.record.store import remove_with, scratch_dir
from sc_rt.scenario.model import Scenario
from sc_rt.scenario.overrides import grid, initial_state, with_overrides

__all__ = ["simulate", "cpp_loop_args", "PACKED", "ENGINES", "STOP"]

#: Set (by a signal handler of the CLI) to end the python engine's run at
#: its next step: the rows done are returned (the caller marks them partial).
STOP = threading.Event()

ENGINES = ("python", "cpp", "unsampled")

#: Layout of _core.step_packed's output (name -> slice), from the C++ list
#: _core.PACKED_FIELDS ((name, width) in the order the C++ writes them).
PACKED: dict[str, slice] = packed_layout(_core.PACKED_FIELDS, _core.PACKED_SIZE)

#: Packed telemetry recorded in the run: run field -> packed name (every
#: packed field of the table but flags and ctrl_mode, which loop_columns
#: converts to integers).
RECORDED = {n: n for n, _ in _core.PACKED_FIELDS if n not in ("flags", "ctrl_mode")}
for _k, _p in RECORDED.items():  # the run declares each with the packed width (a scalar: width 1)
    assert FIELD[_k].shape in ((PACKED[_p].stop - PACKED[_p].start,), ()), _k


#: the field the controller gets on a run without one: none known
_NAN3 = (math.nan, math.nan, math.nan)


def _run_python(scn: Scenario) -> tuple[dict[str, np.ndarray], int, bool]:
    n_ctrl, n_sub, h, rate = grid(scn)
    pp, act = scn.plant, scn.actuators
    x = initial_state(scn)
    ctl = _core.Controller(scn.core_config())  # any law: built-in, plugin or Python (sc_rt.pylaw)
    ctl.reset(_core.Measurement(0.0, x[0:3], x[3:6], x[6:10]))
    step = functools.partial(_core.step_packed, ctl)
    n = n_ctrl + 1
    # one row assignment per array and step; columns are split at the end
    T = np.full(n, np.nan)
    X = np.full((n, 10), np.nan)
    OUT = np.full((n, _core.PACKED_SIZE), np.nan)
    ACC = np.full((n, 4), np.nan)
    D2 = np.full((n, 3), np.nan)
    HN = np.full((n, 3), np.nan)
    BT = np.full((n, 3), np.nan)  # the true field in B (what the controller gets here: no magnetometer)
    u_slice = PACKED["u_cmd"]
    rows = 0
    diverged = False
    plant_row, rk4 = truth.row, truth.rk4_step
    motor = truth.new_motor(act)  # the wheels' motor torques (a lag's state), None for the paper's
    isfinite = math.isfinite
    # magnetic control (docs/MODEL.md section 17): the true field in B at t_k for the controller,
    # its rod commands held over the period through the plant's rods and their faults
    mag = scn.magnetic_control is not None
    rods = pp.magnetorquers if mag else None
    rod_slice = PACKED["rod_dipole_cmd"]
    applied = AppliedRods(pp.magnetorquers, n)  # the rods' truth (without magnetic control: their own)
    for k in range(n):
        t = k / rate
        if mag:
            B_B = plant.field_B(pp, t, x)
            if B_B is not None:
                BT[k] = B_B
            out = step(t, x, _NAN3 if B_B is None else B_B)
        else:
            out = step(t, x)
        u_cmd = out[u_slice]
        m_B0 = None  # the dipole the step's first stage holds: the row's accelerations with it
        if rods is not None:
            d_cmd = out[rod_slice][:rods.n_rods].tolist()
            m_B0 = applied.row(k, t, d_cmd)
        elif applied.rods is not None:
            applied.row(k, t)
        _, accel, delta2 = plant_row(pp, act, t, x, u_cmd, motor, m_B0)
        T[k] = t
        X[k] = x
        OUT[k] = out
        ACC[k] = accel
        D2[k] = delta2
        HN[k] = total_momentum_N(pp, x)
        rows = k + 1
        beat(t)  # a step done: for a parent watching a contained run (sc_rt.isolate)
        if k == n_ctrl or STOP.is_set():
            break
        if rods is not None:
            for j in range(n_sub):
                m_B = m_B0 if j == 0 else rods_dipole_B(rods, t + j * h, d_cmd)
                x = rk4(pp, act, t + j * h, x, h, u_cmd, motor, m_B)
        else:
            for j in range(n_sub):
                x = rk4(pp, act, t + j * h, x, h, u_cmd, motor)
        if not all(map(isfinite, x)):
            diverged = True
            break
    cols = loop_columns(T, X, ACC, D2, OUT, PACKED, RECORDED)
    cols["H_N"] = HN
    cols["B_B_true"] = BT
    cols.update(applied.columns())
    cols[LAW_FAILURES], cols[TELEMETRY_NAMES] = ctl.law_failures, ctl.telemetry_names
    return cols, rows, diverged


def cpp_loop_args(scn: Scenario) -> tuple:
    """The arguments of the C++ closed loop for ``scn``, as
    ``_core.simulate_closed_loop`` and ``_core.bare_closed_loop`` take them:
    (controller config, plant, actuators, x0, n_ctrl, n_sub, rate)."""
    n_ctrl, n_sub, _, rate = grid(scn)
    return (scn.core_config(), plant.plant_params_to_cpp(scn.plant), actuators.actuator_params_to_cpp(scn.actuators),
            initial_state(scn), n_ctrl, n_sub, rate)


#: A C++-engine run longer than this many rows is written to disk as it runs,
#: in chunks of this many rows (57 MB of fields), and read back a chunk at a
#: time (results/record/store.py): its memory does not grow with its length.
OFFLINE_CHUNK_ROWS = 65_536


def _run_cpp_chunked(scn: Scenario, path: Path, meta: RunMeta) -> tuple[int, bool, dict, float, RunMeta]:
    """The C++ loop a chunk at a time, each chunk's rows appended to ``path``
    (trajectory.arrow): (rows, diverged, the law's failures, the last row's t,
    ``meta`` with the law's telemetry names)."""
    from sc_rt.results.record.store import ChunkFile

    loop = _core.ClosedLoop(*cpp_loop_args(scn))
    meta = dataclasses.replace(meta, telemetry_names=tuple(loop.telemetry_names))
    w = ChunkFile(path, COLUMNS,
                  {"sc-rt:meta": json.dumps(meta.to_json())})
    rows, diverged, failures, t_end = 0, False, {}, 0.0
    while not loop.done and not STOP.is_set():
        res = loop.run(OFFLINE_CHUNK_ROWS)
        n = int(res.pop("rows"))
        diverged = bool(res.pop("diverged"))
        failures = res.pop("law_failures")
        res.pop("telemetry_names")
        if n == 0:
            break
        cols = Run(meta, res, rows=n)  # every field, the ones the loop does not fill at their fill value
        w.write(cols.trajectory, n)
        rows += n
        t_end = float(cols.t[-1])
        beat(t_end)
    w.close()
    return rows, diverged, failures, t_end, meta


#: Rows per call of the C++ loop in a contained run (a parent watches its
#: beats, sc_rt.isolate): a plugin law's steps return to Python this often
BEAT_ROWS = 4096


def _cpp_in_parts(scn: Scenario) -> dict:
    """The C++ loop BEAT_ROWS rows at a time, in memory, beating after each
    part: the result of ``_core.simulate_closed_loop`` (the same loop)."""
    loop = _core.ClosedLoop(*cpp_loop_args(scn))
    parts, rows, last = [], 0, {}
    while not loop.done:
        last = loop.run(BEAT_ROWS)
        n = int(last["rows"])
        if n == 0:
            break
        parts.append({k: np.asarray(v)[:n] for k, v in last.items() if isinstance(v, np.ndarray)})
        rows += n
        beat(float(parts[-1]["t"][-1]))
        if last["diverged"]:
            break
    res = {k: np.concatenate([p[k] for p in parts]) if parts else last[k] for k in (parts[0] if parts else {})}
    res.update(rows=rows, diverged=bool(last.get("diverged", False)), law_failures=last.get("law_failures"),
               telemetry_names=last.get("telemetry_names", ()))
    return res


def _run_cpp(scn: Scenario) -> tuple[dict[str, np.ndarray], int, bool]:
    res = _cpp_in_parts(scn) if beating() else _core.simulate_closed_loop(*cpp_loop_args(scn))
    rows = int(res.pop("rows"))
    diverged = bool(res.pop("diverged"))
    failures, names = res.pop("law_failures"), res.pop("telemetry_names")
    unknown = set(res) - set(FIELD)
    if unknown:  # the C++ loop names its columns after the run's fields
        raise RuntimeError(f"simulate_closed_loop returned columns the run does not declare: {sorted(unknown)}")
    return {**res, LAW_FAILURES: failures, TELEMETRY_NAMES: names}, rows, diverged


def simulate(scn: Scenario, *, law: str | None = None, engine: str = "python",
             control_rate_hz: float | None = None, duration: float | None = None,
             plant_step: float | None = None, record_dir: str | Path | None = None) -> Run:
    """Run the scenario's closed loop offline.

    Parameters
    ----------
    scn : Scenario
        The scenario (``sc_rt.load_scenario``).
    law : str or type, optional
        "dsc-ppc", "dsc", "pd" or "rft" (default: the scenario's), "plugin:PATH_OR_NAME",
        or a Python law: "module:Class", "file.py:Class" or the class itself (sc_rt.pylaw;
        every engine but "unsampled").
    engine : {"python", "cpp", "unsampled"}
        "python": the reference plant (sc_rt.model.plant) stepped from Python;
        "cpp": its compiled twin, the whole loop in C++ (bitwise equal);
        "unsampled": reference mode, the law inside every RK4 stage, no hold.
    control_rate_hz : float, optional
        [Hz] override of the scenario's control rate.
    duration : float, optional
        [s] override of the scenario's duration.
    plant_step : float, optional
        [s] override of the plant step (see ``sc_rt.scenario.overrides.with_overrides``).
    record_dir : path, optional
        Where a "cpp" run of more than ``OFFLINE_CHUNK_ROWS`` rows writes its
        rows as it runs (trajectory.arrow; the run reads it a chunk at a
        time, results/record/store.py). None: a temporary directory that lasts as
        long as the run.

    Returns
    -------
    Run
        The run record: per-row arrays (``run["sigma_BD"]``), ``run.metrics``.
        A run whose plant state became non-finite stops there (``run.diverged``,
        ``run.message``).

    Raises
    ------
    ValueError
        An unknown ``engine``; a Python law that does not load, or on the
        "unsampled" engine.
    ScenarioError
        An override is invalid (``sc_rt.with_overrides``).
    """
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if isinstance(law, type):  # a Python law's class: into the core's registry (a spec goes in with its
        law = register(law)    # scenario's config: sc_rt.scenario.config_msg.core_config)
    scn = with_overrides(scn, law=law, control_rate_hz=control_rate_hz,
                         duration=duration, plant_step=plant_step)
    t0 = time.perf_counter()
    n_rows = grid(scn).n_ctrl + 1
    if engine == "cpp" and scn.sensors is None and n_rows > OFFLINE_CHUNK_ROWS:  # on disk as it runs
        tmp = scratch_dir() if record_dir is None else None
        record_dir = tmp or record_dir
        Path(record_dir).mkdir(parents=True, exist_ok=True)
        path = Path(record_dir) / "trajectory.arrow"
        rows, diverged, failures, t_end, meta = _run_cpp_chunked(scn, path, RunMeta.of_scenario(scn, engine))
        beat_done()
        run = Run.stored(dataclasses.replace(meta, wall_s=time.perf_counter() - t0), path, diverged=diverged)
        if tmp is not None:
            remove_with(run, tmp)  # a temporary directory lasts as long as the run
        return _finished(run, scn, rows, failures, t_end)
    if scn.sensors is not None:  # sensors and the estimator in the loop (sc_rt.sim.sensed)
        from sc_rt.sim.sensed import run_sensed

        cols, rows, diverged = run_sensed(scn, engine, PACKED, RECORDED)
    elif engine == "python":
        cols, rows, diverged = _run_python(scn)
    elif engine == "cpp":
        cols, rows, diverged = _run_cpp(scn)
    else:
        from sc_rt.sim.unsampled import run_unsampled

        cols, rows, diverged = run_unsampled(scn)
    beat_done()  # the law's steps are over: what follows is the bench's own work
    wall = time.perf_counter() - t0
    failures = cols.pop(LAW_FAILURES, None)
    names = tuple(cols.pop(TELEMETRY_NAMES, ()))  # the law's, as its controller gave them (none: unsampled)
    meta = RunMeta.of_scenario(scn, engine, wall_s=wall, telemetry_names=names)
    run = Run(meta, cols, rows=rows, diverged=diverged)
    return _finished(run, scn, rows, failures, float(run.t[-1]) if rows else 0.0)


def _finished(run: Run, scn: Scenario, rows: int, failures: dict | None, t_end: float) -> Run:
    """The run's message, derived fields, metrics and the law's failures."""
    if run.diverged:
        n_ctrl = grid(scn).n_ctrl
        run.message = (f"the plant state became non-finite after t = {t_end:.6g} s: "
                       f"the run stopped there ({rows} of {n_ctrl + 1} rows)")
    # the guidance: with sensors, the reference's rate for the true rate error
    finish_run(run, scn.core_config().guidance if scn.sensors is not None else None)
    record_law_failures(run, failures)  # a law that failed: counted, named, the run invalid
    return run
