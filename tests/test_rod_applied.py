"""The rods' applied dipole in the run record (issue 43; docs/RECORD.md,
docs/MODEL.md section 16): ``m_B`` (the body dipole the rods applied from
t_k) and ``rod_dipole`` (each rod's), truth fields of the core's table,
filled by every engine (C++ and Python, plain and sensed) and by the
emulator, and drawn beside the commands in magnetic_control.png under a fault.

Checked against what the code under test does not compute: the recorded
rod commands clipped and put through the scheduled faults by hand in numpy
(not model/rods.py), numpy's G d, the other engine (bitwise), and the
offline C++ engine's run of the same file for a lockstep run (bitwise) and
its log rebuilt by ``sc-rt report``.

Every test here fails on the old main: the record had no ``m_B`` nor
``rod_dipole`` field (``run["m_B"]`` raised KeyError, the lockstep record
had no such column, the figure drew no applied dipole).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import lcmnet
from magscn import H0, MOMENTUM, mag_data
from sc_rt import simulate
from sc_rt.scenario.overrides import with_overrides
from sc_rt.scenario.reader import load_scenario, scenario_from_data
from sc_rt.scenario.shipped import resolve
from trajcmp import compared_fields, load_traj

#: three tilted rods (rows of the file: one axis per rod), unit vectors
AXES = [[1.0, 0.0, 0.0], [0.0, 0.6, 0.8], [0.28, -0.96, 0.0]]
LIM = 30.0  # [A m^2] magscn's max_dipole
#: rod 3 stuck at 5 A m^2 from 1 s, rod 1 reversed on [2, 4) s
FAULTS = """
[[magnetorquers.faults]]
rod = 3
kind = "stuck"
dipole = 5.0
onset = 1.0

[[magnetorquers.faults]]
rod = 1
kind = "reversed"
onset = 2.0
end = 4.0
"""
STUCK_ON, REV_ON, REV_END, STUCK_D = 1.0, 2.0, 4.0, 5.0


def _data(extra: str, duration: float = 6.0, **kw) -> dict:
    data = mag_data(extra + FAULTS, duration=duration, **kw)
    data["magnetorquers"]["axes"] = AXES
    return data


def _by_hand(t: np.ndarray, d_cmd: np.ndarray) -> np.ndarray:
    """[A m^2] each rod's applied dipole: the command clipped, then the scheduled faults."""
    a = np.clip(d_cmd, -LIM, LIM)
    a[t >= STUCK_ON, 2] = STUCK_D
    rev = (t >= REV_ON) & (t < REV_END)
    a[rev, 0] = -a[rev, 0]
    return a


def _check_by_hand(run) -> None:
    t = np.asarray(run["t"])
    cmd = np.asarray(run["rod_dipole_cmd"])[:, :3]
    rod, m_B = np.asarray(run["rod_dipole"]), np.asarray(run["m_B"])
    want = _by_hand(t, cmd)
    np.testing.assert_array_equal(rod[:, :3], want)  # clip and faults are exact operations
    assert np.isnan(rod[:, 3:]).all()  # beyond the three rods
    # G d: numpy's product against the plant's sums in rod order, a rounding apart (|m| <= 60 A m^2)
    G = np.array(AXES).T
    np.testing.assert_allclose(m_B, want @ G.T, rtol=0, atol=1e-12)
    # where no fault is active the applied dipole is the command clipped: G clip(d_cmd) = m_B_cmd here
    ok = t < STUCK_ON
    np.testing.assert_allclose(m_B[ok], np.asarray(run["m_B_cmd"])[ok], rtol=0, atol=1e-12)
    # the faults act: the record differs from the command where they do (not a vacuous check)
    rev = (t >= REV_ON) & (t < REV_END)
    assert np.all(cmd[rev, 0] != 0.0) and np.all(rod[rev, 0] == -np.clip(cmd[rev, 0], -LIM, LIM))
    assert np.any(cmd[t >= STUCK_ON, 2] != STUCK_D)
    assert np.abs(m_B[rev] - np.asarray(run["m_B_cmd"])[rev]).max() > 1.0


def _equal(a, b, names=("m_B", "rod_dipole")) -> None:
    for k in names:
        np.testing.assert_array_equal(np.asarray(a[k]), np.asarray(b[k]), err_msg=k)


@pytest.fixture(scope="module")
def runs():
    scn = scenario_from_data(_data(MOMENTUM, wheel_speed=tuple(10 * v for v in H0)), "mag.toml")
    return simulate(scn, engine="python"), simulate(scn, engine="cpp")


def test_the_applied_dipole_is_the_command_clipped_and_faulted_on_both_engines_bitwise(runs):
    py, cpp = runs
    assert np.all(np.asarray(cpp["unloading"]) == 1)  # the manager commands the rods all along
    for run in (py, cpp):
        _check_by_hand(run)
    _equal(py, cpp)


def test_the_sensed_engines_record_the_applied_dipole_bitwise():
    data = _data(MOMENTUM + "[sensors]\nseed = 11\n[sensors.magnetometer]\nrate_hz = 10.0\nnoise = 100.0\n",
                 wheel_speed=tuple(10 * v for v in H0))
    scn = scenario_from_data(data, "mag.toml")
    py, cpp = simulate(scn, engine="python"), simulate(scn, engine="cpp")
    for run in (py, cpp):
        _check_by_hand(run)
    _equal(py, cpp)


def test_rods_without_magnetic_control_record_their_own_dipole_and_no_rods_none():
    # no [momentum]: no rod command, the rods hold a zero command's dipole (the stuck rod's)
    scn = scenario_from_data(_data(""), "mag.toml")
    py, cpp = simulate(scn, engine="python"), simulate(scn, engine="cpp")
    _equal(py, cpp)
    t = np.asarray(cpp["t"])
    assert np.isnan(np.asarray(cpp["rod_dipole_cmd"])).all()
    want = _by_hand(t, np.zeros((t.size, 3)))
    np.testing.assert_array_equal(np.asarray(cpp["rod_dipole"])[:, :3], want)
    np.testing.assert_allclose(np.asarray(cpp["m_B"]), want @ np.array(AXES), rtol=0, atol=1e-15)
    norm = np.linalg.norm(np.asarray(cpp["m_B"]), axis=1)  # the stuck rod's 5 A m^2 from its onset, 0 before
    assert np.all(np.abs(norm[t >= STUCK_ON] - STUCK_D) < 1e-14) and np.all(norm[t < STUCK_ON] == 0.0)
    # a plant without rods: NaN
    plain = with_overrides(load_scenario("paper_fault_free"), duration=0.5)
    for engine in ("python", "cpp"):
        r = simulate(plain, engine=engine)
        assert np.isnan(np.asarray(r["m_B"])).all() and np.isnan(np.asarray(r["rod_dipole"])).all()


def test_the_recorded_dipole_is_the_one_that_acts_on_the_spacecraft():
    """Every external torque off but the rods (no gravity gradient, no secular torque, no
    residual dipole): the change of the total angular momentum H_N over each period is
    Simpson's integral of (C_NB m_B) x B_N with the recorded m_B (held over the period: the
    faults' onsets and end are on rows) and the field from the ppigrf package
    (tests/test_mag_record.py's check, here under the faults); with m_B_cmd it is not."""
    import datetime as dt

    pytest.importorskip("ppigrf")
    from magscn import ppigrf_field_N
    from refmath import mrp_dcm

    data = _data(MOMENTUM, wheel_speed=tuple(10 * v for v in H0))
    data["spacecraft"]["w0"] = 0.0
    data["disturbance"]["bias"] = [0.0, 0.0, 0.0]
    scn = scenario_from_data(data, "mag.toml")
    assert not np.any(scn.plant.residual_dipole)
    scn = dataclasses.replace(scn, plant=dataclasses.replace(scn.plant, orbit_gravity_gradient=False))
    run = simulate(scn, engine="cpp")
    t, H, sig = np.asarray(run.t), np.asarray(run["H_N"]), np.asarray(run["sigma_BN"])
    T = float(t[1] - t[0])
    orbit = scn.plant.orbit
    when = dt.datetime(2026, 3, 20)  # magscn's epoch
    B0 = ppigrf_field_N(orbit, orbit.jd_epoch, t, when)
    Bm = ppigrf_field_N(orbit, orbit.jd_epoch, t[:-1] + T / 2, when)

    def integral(m_B):
        m_N = [np.array([mrp_dcm(s).T @ m for s, m in zip(ss, m_B[:-1])])
               for ss in (sig[:-1], 0.5 * (sig[:-1] + sig[1:]), sig[1:])]
        tau = [np.cross(m, B) for m, B in zip(m_N, (B0[:-1], Bm, B0[1:]))]
        return (T / 6.0) * (tau[0] + 4.0 * tau[1] + tau[2])

    dH = np.diff(H, axis=0)
    tol = 1e-9 * 60.0 * T  # ppigrf's field against the bench's: < 1 nT times |m| <= 60 A m^2 over T
    np.testing.assert_allclose(dH, integral(np.asarray(run["m_B"])), rtol=0, atol=tol)
    off = np.linalg.norm(dH - integral(np.asarray(run["m_B_cmd"])), axis=1)
    # the command is not what acted under the faults (measured: m_B within 1.7e-10 N m s of the
    # integral, m_B_cmd at least 1.2e-6 off on every row from the stuck rod's onset)
    assert off[t[:-1] >= STUCK_ON].min() > 100 * tol


def test_the_figure_draws_the_applied_dipole_beside_the_command_under_a_fault(runs, tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    from sc_rt.results.present import magnetic_figure as mf

    _, cpp = runs
    s = mf.magnetic_series(cpp)
    # rods 1 and 3 are faulted (drawn), rod 2 is not (its applied dipole is its command)
    assert s["applied"] is not None
    assert np.isnan(s["applied"][:, 1]).all() and np.isfinite(s["applied"][:, [0, 2]]).all()
    seen = []

    def save(fig, path):  # the figure's lines, as saved
        seen.extend(line.get_gid() for ax in fig.axes for line in ax.get_lines())
        return path

    monkeypatch.setattr(mf, "save_figure", save)
    assert mf.magnetic_figure(cpp, tmp_path) is not None
    assert {"rod-applied-1", "rod-applied-3"} <= set(seen) and "rod-applied-2" not in seen
    # a run without a fault draws none (its applied dipole is its command)
    healthy = simulate(scenario_from_data(mag_data(MOMENTUM, duration=1.0, wheel_speed=tuple(10 * v for v in H0)),
                                          "mag.toml"), engine="cpp")
    assert mf.magnetic_series(healthy)["applied"] is None


# --- over real LCM -------------------------------------------------------------

@pytest.mark.lcm
def test_a_lockstep_run_with_rod_faults_records_the_applied_dipole_as_the_cpp_engine(tmp_path):
    lcmnet.require()
    # day_hold's armed fault (rod 2 stuck, never reached) brought into the run, and rod 3 reversed beside it
    text = Path(resolve("day_hold")).read_text()
    armed = "dipole = 0.0                    # [A m^2]\nonset = 1.0e9                   # [s] long after the day\n"
    assert armed in text
    text = text.replace(armed, 'dipole = -40.0\nonset = 5.0\n\n[[magnetorquers.faults]]\nrod = 3\nkind = "reversed"\n'
                                'onset = 10.0\nend = 20.0\n')
    path = tmp_path / "day_faults.toml"
    path.write_text(text)
    out, duration = tmp_path / "hil", 30.0
    r = lcmnet.run_cli(["hil", str(path), "--mode", "lockstep", "--duration", f"{duration:g}", "--out", str(out),
                        "--no-plots"])
    assert r.returncode == 0, r.stderr + r.stdout
    hil = load_traj(out)
    scn = with_overrides(load_scenario(str(path)), duration=duration)
    run = simulate(scn, engine="cpp")
    every = scn.record.every
    sim = {k: np.asarray(run[k])[::every] for k in hil.files if k != "meta_json" and k in run}
    done = compared_fields(hil, sim)  # every field both produced, bit for bit
    assert {"m_B", "rod_dipole", "rod_dipole_cmd"} <= set(done), done
    # the faults show: rod 2 stuck at -40 from 5 s, rod 3 reversed on [10, 20) s
    t, rod, cmd = hil["t"], hil["rod_dipole"], hil["rod_dipole_cmd"]
    assert np.all(rod[t >= 5.0, 1] == -40.0) and np.any(cmd[t >= 5.0, 1] != -40.0)
    rev = (t >= 10.0) & (t < 20.0)
    assert np.all(rod[rev, 2] == -np.clip(cmd[rev, 2], -100.0, 100.0)) and np.any(cmd[rev, 2] != 0.0)
    assert np.isnan(rod[:, 3:]).all() and json.loads((out / "metrics.json").read_text())["valid"] is True
    # sc-rt report rebuilds the same columns from the log alone (every row; the run kept 1 in `every`)
    rep_dir = tmp_path / "rep"
    r = lcmnet.run_cli(["report", str(out / "run.lcmlog"), "--out", str(rep_dir), "--no-plots"], netns=False)
    assert r.returncode == 0, r.stderr + r.stdout
    rep = load_traj(rep_dir)
    for k in ("m_B", "rod_dipole"):
        np.testing.assert_array_equal(rep[k][::every], hil[k], err_msg=k)
