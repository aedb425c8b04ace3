"""What a run with magnetic control records and reports (issue 43's
follow-ups; docs/MODEL.md section 17): the rows' wheel accelerations with
the commanded dipole, the total angular momentum in N (``H_N``) and the
report's figure of wheel momentum and dipoles.

Checked against what the code under test does not compute: the wheel
speeds' difference quotient, the ``ppigrf`` package's field and numpy's
angular momentum from the Euler parameters, Simpson's integral of m x B
(tests/test_mag_plant.py's method), the record's own columns through numpy.
All fail on the old main: its rows' accelerations leave the commanded
dipole out, it has no ``H_N`` field and no magnetic_control.png.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math

import numpy as np
import pytest

from magscn import H0, MOMENTUM, mag_data, ppigrf_field_N
from refmath import mrp_dcm
from sc_rt import simulate
from sc_rt.results.present.html_report import write_html_report
from sc_rt.results.present.magnetic_figure import FILE, magnetic_figure, magnetic_series
from sc_rt.results.present.output import write_run
from sc_rt.scenario.reader import scenario_from_data

ppigrf = pytest.importorskip("ppigrf")

#: magscn's orbit epoch (MAG: 2026-03-20T00:00:00Z)
WHEN = dt.datetime(2026, 3, 20, 0, 0, 0)


def _scenario(extra: str, *, duration: float, bias: bool = True, **kw):
    """magscn's flight wheels with rods, without gravity gradient (the orbit's nor the w0
    form); ``bias`` False: no secular torque either (every external torque off but the rods)."""
    data = mag_data(extra, duration=duration, **kw)
    data["spacecraft"]["w0"] = 0.0
    if not bias:
        data["disturbance"]["bias"] = [0.0, 0.0, 0.0]
    scn = scenario_from_data(data, "mag.toml")
    return dataclasses.replace(scn, plant=dataclasses.replace(scn.plant, orbit_gravity_gradient=False))


def _H_N(scn, run) -> np.ndarray:
    """[N m s] numpy's C_NB (J omega + Cbar Jw Omega) from the record's state."""
    J = np.asarray(scn.plant.J0, float) + np.asarray(scn.plant.dJ, float)
    CJ = np.asarray(scn.plant.Cbar, float) * np.asarray(scn.plant.Jw, float)
    H_B = run["omega_BN_B"] @ J.T + run["wheel_speed"] @ CJ.T
    return np.array([mrp_dcm(s).T @ h for s, h in zip(run["sigma_BN"], H_B)])


def _field_N(orbit, times) -> np.ndarray:
    """[T] IGRF-14 by ppigrf at the orbit's positions (ECI), (n, 3)."""
    return ppigrf_field_N(orbit, orbit.jd_epoch, times, WHEN)


@pytest.mark.parametrize("engine", ["cpp", "python"])
def test_row_wheel_accel_is_the_step_with_the_commanded_dipole(engine):
    """Unloading on flight wheels: each row's wheel_accel against the wheel
    speeds' difference quotient over the period after it (the period's mean
    acceleration; a first-order difference, so off by about T/2 times the
    acceleration's rate). The commanded dipole's share, measured from the
    record as the rods' torque through the body, is far above that error."""
    scn = _scenario(MOMENTUM, duration=3.0, wheel_speed=tuple(10 * v for v in H0))
    run = simulate(scn, engine=engine, control_rate_hz=100.0)
    assert np.all(run["unloading"] == 1)
    T = float(np.diff(run.t[:2])[0])
    fd = np.diff(run["wheel_speed"], axis=0) / T
    err = np.abs(run["wheel_accel"][:-1] - fd)[100:]  # after the first second (the law settles)
    # the commanded torque m x B seen by the wheels through the body: a_i' J^-1 (m x B) [rad/s^2]
    J = np.asarray(scn.plant.J0, float) + np.asarray(scn.plant.dJ, float)
    tau = np.cross(run["m_B_cmd"], run["B_B"])[:-1][100:]
    share = np.abs(np.linalg.solve(J, tau.T).T @ np.asarray(scn.plant.Cbar, float))
    assert share.max() > 1e-6
    # measured: err 7.9e-9 against a share of 4.3e-5 (the old main's rows: 4.4e-5 off)
    assert err.max() < 0.01 * share.max(), (err.max(), share.max())


def test_total_momentum_changes_by_the_integral_of_m_cross_b():
    """Every external torque off but the rods: H_N (the record's) is numpy's
    C_NB (J omega + Cbar Jw Omega) of the record's state, and its change
    over each period is Simpson's integral of (C_NB m_B) x B_N with the
    field from ppigrf at the period's ends and middle (attitude interpolated
    there: the body is held)."""
    scn = _scenario(MOMENTUM, duration=60.0, bias=False, wheel_speed=tuple(10 * v for v in H0))
    run = simulate(scn, engine="cpp")
    H = run["H_N"]
    np.testing.assert_allclose(H, _H_N(scn, run), rtol=0, atol=1e-12 * np.abs(H).max())
    t, T = run.t, float(run.t[1] - run.t[0])
    tm = t[:-1] + T / 2
    B0, Bm = _field_N(scn.plant.orbit, t), _field_N(scn.plant.orbit, tm)
    sig = run["sigma_BN"]
    m_B = run["m_B_cmd"][:-1]  # healthy rods: the plant's dipole is the command
    m_N = [np.array([mrp_dcm(s).T @ m for s, m in zip(ss, m_B)])
           for ss in (sig[:-1], 0.5 * (sig[:-1] + sig[1:]), sig[1:])]
    tau = [np.cross(m, B) for m, B in zip(m_N, (B0[:-1], Bm, B0[1:]))]
    integral = (T / 6.0) * (tau[0] + 4.0 * tau[1] + tau[2])
    dH = np.diff(H, axis=0)
    assert np.linalg.norm(integral, axis=1).max() > 1e-5  # [N m s] per period: the rods do unload
    # ppigrf's field against the bench's: < 1 nT times |m| <= 52 A m^2 over T = 0.1 s
    np.testing.assert_allclose(dH, integral, rtol=0, atol=1e-9 * 52.0 * T)
    # and over the whole run, the removed momentum is the sum
    np.testing.assert_allclose(H[-1] - H[0], integral.sum(axis=0), rtol=0, atol=1e-9 * 52.0 * 60.0)


def test_total_momentum_constant_without_external_torques():
    """No rods commanded, no secular torque, no gravity gradient: H_N
    constant to 1e-10 relative while the law moves momentum between the
    body and the wheels."""
    scn = _scenario("", duration=60.0, bias=False, wheel_speed=(20.0, -10.0, 30.0, 5.0), omega=(0.01, -0.02, 0.015))
    for engine in ("cpp", "python"):
        run = simulate(scn, engine=engine)
        H = run["H_N"]
        drift = np.max(np.linalg.norm(H - H[0], axis=1)) / np.linalg.norm(H[0])
        assert drift < 1e-10, drift
        assert np.ptp(run["wheel_speed"], axis=0).max() > 1.0  # [rad/s] momentum did move to the wheels


def test_report_has_the_magnetic_figure_only_with_magnetic_control(tmp_path):
    """A short run with the manager: magnetic_control.png in the output and
    in report.html, its |h_wheels| the numpy norm of the record's column and
    its band the scenario's; without magnetic control, no such figure."""
    on = _scenario(MOMENTUM, duration=5.0, wheel_speed=tuple(10 * v for v in H0))
    off = dataclasses.replace(on, magnetic_control=None)
    for name, scn in (("on", on), ("off", off)):
        run = simulate(scn, engine="cpp")
        out = tmp_path / name
        paths = write_run(run, out)
        page = write_html_report(out).read_text()
        has = FILE in {p.name for p in paths}
        assert has == (name == "on")
        assert (f'data-file="{FILE}"' in page) == (name == "on")
        if name == "on":
            s = magnetic_series(run)
            np.testing.assert_array_equal(s["h_norm"], np.linalg.norm(run["h_wheels_B"], axis=1))
            assert s["h_unit"] == "N m s" and s["t_unit"] == "s"
            assert s["band"]["on_h"] == 0.5 and math.isclose(s["band"]["off_h"], 0.1)  # capacity 1 N m s
            assert s["limits"] == (30.0, 30.0, 30.0) and s["dipole"].shape == (len(run.t), 3)
            assert s["detumble"] is None


def test_bdot_alone_draws_dipoles_and_mode(tmp_path):
    """B-dot without a manager: no momentum panels (h_wheels_B is NaN), the
    mode series the record's detumble_mode, the figure written."""
    bdot = '[bdot]\nderivative = "analytic"\nrate_on = 0.0466\nrate_off = 0.0464\n'
    run = simulate(_scenario(bdot, duration=3.0, omega=(0.03, -0.03, 0.02)), engine="cpp")
    s = magnetic_series(run)
    assert np.all(np.isnan(s["h_norm"])) and s["band"] is None
    np.testing.assert_array_equal(s["detumble"], run["detumble_mode"])
    assert s["detumble"][0] == 0  # detumbling from the first row
    assert magnetic_figure(run, tmp_path).name == FILE


def test_row_with_a_dipole_is_bitwise_in_the_two_plants():
    """sc_rt.model.truth.row and _core.plant_row with the same held dipole:
    equal with ==, and not the row without it (the dipole moves the wheels
    of flight wheels through the body)."""
    from sc_rt import _core
    from sc_rt.model import truth
    from sc_rt.model.actuators import actuator_params_to_cpp
    from sc_rt.model.plant import plant_params_to_cpp

    scn = _scenario(MOMENTUM, duration=1.0)
    p, act = scn.plant, scn.actuators
    pc, ac = plant_params_to_cpp(p), actuator_params_to_cpp(act)
    x = np.array([0.1, -0.2, 0.3, 0.01, -0.02, 0.005, 30.0, -60.0, 50.0, 40.0])
    u = np.array([0.01, -0.02, 0.005, 0.0])
    m = [25.0, -30.0, 12.0]  # [A m^2]
    mot = truth.new_motor(act)
    rows = [(truth.row(p, act, 100.0, x, u, None if mot is None else list(mot), d)[1],
             _core.plant_row(pc, ac, 100.0, _core.PlantState.from_vector(x), u,
                             None if mot is None else np.array(mot), d).accel) for d in (m, None)]
    for py, cpp in rows:
        assert np.array_equal(np.asarray(py), np.asarray(cpp))
    assert not np.array_equal(np.asarray(rows[0][0]), np.asarray(rows[1][0]))
