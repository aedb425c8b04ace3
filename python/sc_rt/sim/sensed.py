"""The offline closed loop with sensors and the estimator in it (a scenario
with a ``[sensors]`` table; docs/MODEL.md section 10). Without one,
sc_rt.sim.engines runs today's loop untouched.

Loop (both engines, the same calls in the same order; the sensor models and
the MEKF are the C++ core's ``_core.Navigation``):

    nav.reset(x0); nav.tick(0, 0, x0); controller.reset(nav.measure(0, x0))
    for k = 0..N:                               t_k = k / rate, tick i = k n_sub
        if k > 0: nav.tick(i, t_k, x)
        m = nav.measure(t_k, x)                 truth or estimate ([controller] measurement)
        command = controller.step(m)            magnetic control: step(m, nav.field_B)
        record row k (+ the estimator's telemetry)
        for j = 0..n_sub-1:
            if j > 0: nav.tick(i + j, t_k + j h, x)
            x = rk4_step(x, h, command.u_cmd)   (+ the rods' dipole of the held commands)

A tick where the magnetometer is due (``nav.magnetometer_due``) gets the
plant's true field in B at that instant (``sc_rt.model.plant.field_B``); with
magnetic control (``[momentum]``, ``[bdot]``) the controller gets
``nav.field_B``, the magnetometer's latest sample rotated to B with its known
mounting (docs/MODEL.md section 17), and the row records the true field
beside it (``B_B_true``). Both engines call ``nav.tick`` only at the ticks
where a sensor samples or delivers (``nav.next_tick``; a tick with nothing
due would change nothing), and stay bitwise equal (tests/test_sensors.py,
tests/test_mag_sensed.py).
"""

from __future__ import annotations

import math

import numpy as np

from sc_rt import _core
from sc_rt.model import actuators, plant, truth
from sc_rt.model.momentum import total_momentum_N
from sc_rt.model.rods import rods_dipole_B
from sc_rt.isolate import beat, beat_done
from sc_rt.results.record.fields import packed_layout
from sc_rt.results.record.run import FIELD
from sc_rt.scenario.overrides import grid, initial_state
from sc_rt.scenario.schema import ScenarioError, ScenarioIssue
from sc_rt.scenario.tables.sensors import nav_config
from sc_rt.sim.columns import LAW_FAILURES, TELEMETRY_NAMES, AppliedRods, loop_columns

__all__ = ["run_sensed", "NAV", "NAV_RECORDED"]

#: Layout of Navigation.measure's telemetry (name -> slice), from _core.NAV_FIELDS.
NAV: dict[str, slice] = packed_layout(_core.NAV_FIELDS, _core.NAV_SIZE)

#: The navigation telemetry the run records (run field = telemetry name):
#: every field of NAV_FIELDS but nav_flags (OR-ed into the row's flags).
NAV_RECORDED = tuple(n for n, _ in _core.NAV_FIELDS if n != "nav_flags")
for _k in NAV_RECORDED:
    assert FIELD[_k].shape == ((NAV[_k].stop - NAV[_k].start,) if NAV[_k].stop - NAV[_k].start > 1 else ()), _k


def _config(scn):
    return nav_config(scn.sensors, scn.run.plant_step, f"{scn.path}")


def _tick(nav, pp, i: int, t: float, x) -> None:
    """The navigation's tick i at t from the state x, with the plant's true field in B
    for the magnetometer when it is due (the C++ loop's ClosedLoop::tick)."""
    nav.tick(i, t, x, plant.field_B(pp, t, x) if nav.magnetometer_due(i) else None)


def _run_python(scn, packed: dict[str, slice], recorded: dict[str, str]):
    n_ctrl, n_sub, h, rate = grid(scn)
    pp, act = scn.plant, scn.actuators
    x = initial_state(scn)
    ctl = _core.Controller(scn.core_config())
    nav = _core.Navigation(_config(scn))
    nav.reset(x)
    _tick(nav, pp, 0, 0.0, x)
    ctl.reset(nav.measure_only(0.0, x))
    # magnetic control (docs/MODEL.md section 17): the magnetometer's field for the controller,
    # its rod commands held over the period through the plant's rods and their faults
    mag = scn.magnetic_control is not None
    rods = pp.magnetorquers if mag else None
    BT = np.full((n_ctrl + 1, 3), np.nan)
    applied = AppliedRods(pp.magnetorquers, n_ctrl + 1)  # the rods' truth (without magnetic control: their own)
    nxt = nav.next_tick(0)
    n = n_ctrl + 1
    T = np.full(n, np.nan)
    X = np.full((n, 10), np.nan)
    OUT = np.full((n, _core.PACKED_SIZE), np.nan)
    NAVT = np.full((n, _core.NAV_SIZE), np.nan)
    ACC = np.full((n, 4), np.nan)
    D2 = np.full((n, 3), np.nan)
    HN = np.full((n, 3), np.nan)
    items = list(packed.items())
    rows, diverged = 0, False
    plant_row, rk4 = truth.row, truth.rk4_step
    motor = truth.new_motor(act)  # the wheels' motor torques (a lag's state), None for the paper's
    isfinite = math.isfinite
    for k in range(n):
        t = k / rate
        i0 = k * n_sub
        if k > 0 and i0 == nxt:
            _tick(nav, pp, i0, t, x)
            nxt = nav.next_tick(i0)
        m, tel = nav.measure(t, x)
        if mag:
            B_true = plant.field_B(pp, t, x)
            if B_true is not None:
                BT[k] = B_true
            c = ctl.step(m, nav.field_B)
        else:
            c = ctl.step(m)
        row = OUT[k]
        for name, sl in items:
            row[sl] = getattr(c, name)
        u_cmd = row[packed["u_cmd"]].copy()
        m_B0 = None  # the dipole the step's first stage holds: the row's accelerations with it
        if rods is not None:
            d_cmd = row[packed["rod_dipole_cmd"]][:rods.n_rods].tolist()
            m_B0 = applied.row(k, t, d_cmd)
        elif applied.rods is not None:
            applied.row(k, t)
        _, accel, delta2 = plant_row(pp, act, t, x, u_cmd, motor, m_B0)
        T[k] = t
        X[k] = x
        NAVT[k] = tel
        ACC[k] = accel
        D2[k] = delta2
        HN[k] = total_momentum_N(pp, x)
        rows = k + 1
        beat(t)  # a step done: for a parent watching a contained run (sc_rt.isolate)
        if k == n_ctrl:
            break
        for j in range(n_sub):
            if j > 0 and i0 + j == nxt:
                _tick(nav, pp, i0 + j, t + j * h, x)
                nxt = nav.next_tick(i0 + j)
            if rods is not None:
                m_B = m_B0 if j == 0 else rods_dipole_B(rods, t + j * h, d_cmd)
                x = rk4(pp, act, t + j * h, x, h, u_cmd, motor, m_B)
            else:
                x = rk4(pp, act, t + j * h, x, h, u_cmd, motor)
        if not all(map(isfinite, x)):
            diverged = True
            break
    cols = loop_columns(T, X, ACC, D2, OUT, packed, recorded)
    cols["H_N"] = HN
    cols["B_B_true"] = BT
    cols.update(applied.columns())
    for name in NAV_RECORDED:
        v = NAVT[:, NAV[name]]
        cols[name] = v[:, 0] if v.shape[1] == 1 else v
    cols["flags"] |= np.nan_to_num(NAVT[:, NAV["nav_flags"]][:, 0]).astype(np.int64)
    cols[LAW_FAILURES], cols[TELEMETRY_NAMES] = ctl.law_failures, ctl.telemetry_names
    return cols, rows, diverged


def _run_cpp(scn):
    n_ctrl, n_sub, _, rate = grid(scn)
    # one call for the whole run: unwatched, except a Python law's steps,
    # which beat themselves (sc_rt.pylaw); a plugin's are not (docs/LAWS.md)
    beat_done()
    res = _core.simulate_closed_loop_sensed(
        scn.core_config(), plant.plant_params_to_cpp(scn.plant),
        actuators.actuator_params_to_cpp(scn.actuators), initial_state(scn), n_ctrl, n_sub, rate,
        _config(scn))
    rows = int(res.pop("rows"))
    diverged = bool(res.pop("diverged"))
    failures, names = res.pop("law_failures"), res.pop("telemetry_names")
    unknown = set(res) - set(FIELD)
    if unknown:
        raise RuntimeError(f"simulate_closed_loop_sensed returned columns the run does not declare: {sorted(unknown)}")
    return {**res, LAW_FAILURES: failures, TELEMETRY_NAMES: names}, rows, diverged


def run_sensed(scn, engine: str, packed: dict[str, slice], recorded: dict[str, str]):
    """(columns, rows, diverged) of the scenario's loop with its sensors on
    ``engine`` ("python" or "cpp"); ``packed``/``recorded``: the engines'
    packed-row layout and the telemetry they record."""
    if engine == "python":
        return _run_python(scn, packed, recorded)
    if engine == "cpp":
        return _run_cpp(scn)
    # a ScenarioError, so that the CLI reports it in one line (exit 2)
    raise ScenarioError(scn.path, [ScenarioIssue(0, "sensors", None, f"a scenario with [sensors] runs on the "
                                                 f"python or cpp engine, not {engine!r}")])
