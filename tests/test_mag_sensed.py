"""The magnetometer in the loop, offline (issue 43 item 3; docs/MODEL.md
sections 13 and 17): ``[sensors.magnetometer]`` read and converted from nT,
``SensorSuite`` ticking it from the plant's true field without moving the
other sensors' draws, and the controller's magnetic part fed the measured
field (the latest sample rotated to B with the known mounting) in both
sensed engines, bitwise equal.

Checked against what the code under test does not compute: the configured
bias and noise (sample mean and standard deviation of the record's
``B_B - B_B_true``, rotated by the test's own MRP matrix, tests/refmath.py),
the quantum (integer multiples), the true-field run (bitwise), the other
engine (bitwise), the wheel momentum from the record's wheel speeds.

All fail on the old main: ``[sensors.magnetometer]`` is an unknown table
there, ``[momentum]``/``[bdot]`` with ``[sensors]`` are refused, and
``SensorParams`` has no magnetometer.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from magscn import H0, MAG, MOMENTUM, mag_data, mag_scenario
from refmath import mrp_dcm
from sc_rt import _core, simulate
from sc_rt.cli.main import main
from sc_rt.scenario.reader import load_scenario, scenario_from_data
from sc_rt.scenario.shipped import resolve
from sc_rt.scenario.tables.sensors import nav_config

NT = 1e-9
BASE_MAG = Path(resolve("flight_wheels")).read_text() + MAG
#: a mounting (sigma_SB), a bias in S and noise: what the controller does not know but the mounting
MOUNT = (0.1, -0.2, 0.3)
BIAS_NT = (200.0, -150.0, 100.0)


def _mag(rate_hz: float = 10.0, **kw) -> str:
    keys = {"rate_hz": rate_hz, **kw}
    body = "".join(f"{k} = {list(v) if isinstance(v, tuple) else v}\n" for k, v in keys.items())
    return "[sensors]\nseed = 11\n[sensors.magnetometer]\n" + body


def _run(capsys, args) -> tuple[int, list[str]]:
    capsys.readouterr()
    try:
        rc = main(args)
    except SystemExit as e:
        rc = e.code
    cap = capsys.readouterr()
    return rc, (cap.err + cap.out).strip().splitlines()


# --- the table -------------------------------------------------------------------------------------


def test_the_table_is_read_in_nT_and_converted_to_tesla(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text(BASE_MAG + _mag(5.0, noise=100.0, bias=BIAS_NT, scale_factor=(1000.0, 0.0, -500.0),
                                 misalignment=(0.0, 0.0, 36.0), mounting=MOUNT, lsb=10.0, range=65000.0))
    scn = load_scenario(p)
    m = nav_config(scn.sensors, scn.run.plant_step).sensors.magnetometer
    assert m.enabled and m.period_ticks == round(1.0 / (5.0 * scn.run.plant_step))
    np.testing.assert_allclose([m.noise, m.lsb, m.range], [100e-9, 10e-9, 65e-6], rtol=1e-15)
    np.testing.assert_allclose(m.bias, np.array(BIAS_NT) * NT, rtol=1e-15)
    np.testing.assert_allclose(m.R_SB, mrp_dcm(np.array(MOUNT)), atol=1e-15)
    a = 36.0 * np.pi / 180 / 3600  # a small rotation about z: (I + diag(s)) (I - a^)
    want = np.diag([1.001, 1.0, 0.9995]) @ np.array([[1.0, a, 0.0], [-a, 1.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(m.M, want, rtol=0, atol=1e-15)


@pytest.mark.parametrize(("extra", "key", "needle"), [
    (_mag(noise=-1.0), "sensors.magnetometer.noise", "-1"),
    (_mag(mounting=(1.0, 1.0, 0.0)), "sensors.magnetometer.mounting", "mounting"),
    (_mag(rate_hz=3.0), "sensors.magnetometer.rate_hz", "whole number"),
    (_mag(bais=1.0), "sensors.magnetometer.bais", "did you mean"),
    ("[momentum]\ncapacity = 1.0\n[sensors]\n[sensors.gyro]\n", "momentum.", "[sensors.magnetometer]"),
    ("[bdot]\n[sensors]\n[sensors.gyro]\n", "bdot.", "[sensors.magnetometer]"),
])
def test_a_bad_table_exits_2_with_one_line_naming_the_key(tmp_path, capsys, extra, key, needle):
    p = tmp_path / "m.toml"
    p.write_text(BASE_MAG + extra)
    rc, err = _run(capsys, ["check", str(p)])
    assert rc == 2
    hit = [line for line in err if key in line]
    assert len(hit) == 1 and needle in hit[0], err


def test_a_magnetometer_needs_a_field(tmp_path, capsys):
    p = tmp_path / "m.toml"
    p.write_text(Path(resolve("flight_wheels")).read_text() + _mag())
    rc, err = _run(capsys, ["check", str(p)])
    assert rc == 2 and any("sensors.magnetometer" in line and "[orbit]" in line for line in err), err


# --- the sensor suite ------------------------------------------------------------------------------


def _suite_params(mag: bool) -> _core.SensorParams:
    p = _core.SensorParams()
    p.seed, p.dt = 3, 0.01
    p.gyro.enabled, p.gyro.period_ticks, p.gyro.arw, p.gyro.bias_sigma = True, 2, 1e-5, 1e-6
    p.star_tracker.enabled, p.star_tracker.period_ticks = True, 10
    p.star_tracker.sigma_cross, p.star_tracker.sigma_boresight = 5e-5, 2e-4
    p.star_tracker.loss_probability = 0.1
    if mag:
        p.magnetometer.enabled, p.magnetometer.period_ticks, p.magnetometer.noise = True, 5, 1e-7
    return p


def test_the_magnetometer_leaves_the_other_sensors_draws_bitwise_unchanged():
    """The gyro and star tracker samples of 400 ticks, with the magnetometer ticking beside them
    (its own stream) and without it: equal with ==; the magnetometer's samples are the core's
    Magnetometer of the same seed fed the same field, one every period."""
    x = np.array([0.1, -0.2, 0.05, 0.01, -0.02, 0.03, 10.0, -20.0, 5.0, 1.0])
    B = np.array([2e-5, -1e-5, 3e-5])
    runs = {}
    for mag in (False, True):
        s = _core.SensorSuite(_suite_params(mag))
        gyro, star, m = [], [], []
        for i in range(400):
            s.tick(i, i * 0.01, x, B)
            if s.gyro_new:
                gyro.append((s.gyro[0], *s.gyro[1]))
            if s.star_new:
                star.append((s.star[0], *s.star[2]))
            if s.mag_new:
                m.append((s.mag[0], *s.mag[1]))
        runs[mag] = (np.array(gyro), np.array(star), np.array(m))
    assert runs[False][0].shape == (200, 4) and len(runs[False][1]) > 30
    np.testing.assert_array_equal(runs[True][0], runs[False][0])
    np.testing.assert_array_equal(runs[True][1], runs[False][1])
    assert runs[False][2].size == 0 and runs[True][2].shape == (80, 4)
    ref = _core.Magnetometer(_suite_params(True).magnetometer, 3)
    want = np.array([ref.sample(B) for _ in range(80)])
    np.testing.assert_array_equal(runs[True][2][:, 1:], want)
    np.testing.assert_array_equal(runs[True][2][:, 0], [5 * k * 0.01 for k in range(80)])  # every 5th tick


# --- in the loop -----------------------------------------------------------------------------------


def _sensed(extra_mag: str, *, duration: float, **kw):
    return mag_scenario(MOMENTUM + extra_mag, duration=duration,
                        wheel_speed=kw.pop("wheel_speed", tuple(10 * v for v in H0)), **kw)


def test_the_recorded_field_error_has_the_configured_bias_and_noise():
    """B_B (what the controller used) - B_B_true = R_SB' (bias + n) with a perfect scale: rotated
    back by the test's own R_SB, its sample mean is the bias to within 4 standard errors and its
    sample standard deviation the noise to within 6 % (5 sigma of a 3000-sample estimate)."""
    scn = _sensed(_mag(noise=100.0, bias=BIAS_NT, mounting=MOUNT), duration=300.0)
    run = simulate(scn, engine="cpp")
    err = (run["B_B"] - run["B_B_true"]) @ mrp_dcm(np.array(MOUNT)).T / NT  # [nT] sensor frame
    n = len(err)
    assert n == 3001 and np.all(np.isfinite(err))
    assert np.all(np.abs(err.mean(axis=0) - BIAS_NT) < 4 * 100.0 / np.sqrt(n)), err.mean(axis=0)
    np.testing.assert_allclose(err.std(axis=0, ddof=1), 100.0, rtol=0.06)
    assert np.any(run["m_B_cmd"] != 0.0)  # the manager drove the rods from it


def test_quantised_samples_are_multiples_of_the_lsb_and_held_between_samples():
    """An identity mounting (B_B is the sample itself): every B_B a multiple of the 50 nT lsb, within
    half of it of (I + diag(s)) B_B_true at the sample's row, and held (zero-order) over the
    five control periods between two samples at 2 Hz."""
    s = np.array([2000.0, -1000.0, 500.0]) * 1e-6
    scn = _sensed(_mag(2.0, lsb=50.0, scale_factor=(2000.0, -1000.0, 500.0)), duration=30.0)
    run = simulate(scn, engine="cpp")
    B, Bt = run["B_B"], run["B_B_true"]
    q = B / (50 * NT)  # whole numbers, to the rounding of the division
    assert np.all(np.abs(q - np.round(q)) < 1e-9) and np.any(np.round(q) != 0)
    sampled = np.arange(0, len(B), 5)  # 10 Hz control, 2 Hz magnetometer
    assert np.all(np.abs(B[sampled] - (1 + s) * Bt[sampled]) <= 25 * NT * (1 + 1e-9))
    for k in range(len(B)):
        np.testing.assert_array_equal(B[k], B[5 * (k // 5)])
    assert len(np.unique(B, axis=0)) > 10  # and the field moved along the orbit meanwhile


def _core_fields(run):
    return [k for k in run.trajectory if k not in ("flags",) and np.asarray(run[k]).ndim >= 1]


@pytest.mark.parametrize("engine", ["cpp", "python"])
def test_a_perfect_magnetometer_gives_the_true_field_run_bitwise(engine):
    """No noise, no bias, identity mounting and scale, sampled at the control rate: every field of
    the true-field run (no [sensors]) equal with == (the sensed run's navigation fields aside)."""
    truth = _sensed("", duration=15.0)
    perfect = _sensed(_mag(), duration=15.0)
    a, b = simulate(truth, engine=engine), simulate(perfect, engine=engine)
    assert np.any(a["m_B_cmd"] != 0.0)
    # the sensed run's own: the navigation's telemetry and the true errors derived with sensors
    nav = {r["name"] for r in _core.FIELD_TABLE if r["group"] == "nav"} | {"sigma_BD_true", "omega_BD_B_true"}
    diff = [k for k in a.trajectory if k not in nav and k != "flags" and not np.array_equal(
        np.asarray(a[k]), np.asarray(b[k]), equal_nan=np.asarray(a[k]).dtype.kind == "f")]
    assert diff == []
    np.testing.assert_array_equal(a["B_B"], a["B_B_true"])
    np.testing.assert_array_equal(a["flags"], b["flags"] & ~_core.FLAG_NAV_DEGRADED)


MAGNETOMETER = _mag(5.0, noise=100.0, bias=BIAS_NT, mounting=MOUNT, lsb=5.0, scale_factor=(300.0, -200.0, 100.0))
GYRO_STAR = ("[sensors.gyro]\nrate_hz = 10.0\narw = 0.01\nbias0 = 1.0\n[sensors.star_tracker]\nrate_hz = 5.0\n"
             "sigma_cross = 5.0\nsigma_boresight = 30.0\n")


@pytest.mark.parametrize("extra, kw", [
    (MOMENTUM + MAGNETOMETER + GYRO_STAR, {"wheel_speed": tuple(10 * v for v in H0)}),
    ('[bdot]\nderivative = "difference"\nfilter_tau = 0.3\nrate_on = 0.0466\nrate_off = 0.0464\n'
     + MAGNETOMETER.replace("5.0\n", "10.0\n", 1), {"omega": (0.03, -0.03, 0.02)}),
])
def test_cpp_and_python_sensed_engines_are_bitwise_equal(extra, kw):
    """Every field of the two engines' runs equal with ==, the manager (fed the estimate) and B-dot
    fed the magnetometer's field."""
    data = mag_data(extra, duration=40.0, **kw)
    if "[sensors.gyro]" in extra:  # the law fed the MEKF's estimate
        data["controller"]["measurement"] = "estimate"
    scn = scenario_from_data(data, "mag.toml")
    py, cpp = simulate(scn, engine="python"), simulate(scn, engine="cpp")
    assert len(py.t) == len(cpp.t) == 401
    diff = [k for k in py.trajectory if not np.array_equal(np.asarray(py[k]), np.asarray(cpp[k]),
                                                           equal_nan=np.asarray(py[k]).dtype.kind == "f")]
    assert diff == []
    assert np.any(cpp["m_B_cmd"] != 0.0) and np.all(np.isfinite(cpp["B_B"]))
    assert np.any(cpp["B_B"] != cpp["B_B_true"])


# --- the shipped scenarios with a realistic magnetometer (slow) -----------------------------------

#: [sensors.magnetometer] of a realistic sensor (nT): 100 nT noise, 200 nT bias per axis, 5 nT lsb
REALISTIC = {"rate_hz": 10.0, "noise": 100.0, "bias": 200.0, "lsb": 5.0}


def _shipped(name: str, duration: float):
    data = tomllib.loads(resolve(name).read_text())
    data["run"]["duration"] = duration
    data.pop("requirements", None)
    data["sensors"] = {"seed": 5, "magnetometer": dict(REALISTIC)}
    return scenario_from_data(data, f"{name}.toml")


def test_day_hold_with_a_realistic_magnetometer_still_unloads():
    """day_hold, 4 h, its manager fed a 100 nT noise, 200 nT bias magnetometer: the wheels' momentum
    (Cbar Jw Omega from the record's wheel speeds) is unloaded from 45 N m s to the off band
    (5 N m s) within the 4 h (the true-field run reaches it at 13048 s; this one at 13055 s),
    never rising on the way, and the pointing stays within day_hold's 0.1 deg."""
    scn = _shipped("day_hold", 4 * 3600.0)
    run = simulate(scn, engine="cpp")
    m = scn.magnetic_control.momentum
    cap = 50.0  # [N m s] min Jw omega_max: 0.0796 kg m^2 at 628.3 rad/s (HR16)
    h = np.linalg.norm(run["wheel_speed"] @ (np.asarray(scn.plant.Cbar) * np.asarray(scn.plant.Jw)).T, axis=1)
    t = run["t"]
    assert h[0] > 0.85 * cap and run["unloading"][0] == 1
    off = np.flatnonzero(h < m.off_fraction * cap * 1.01)
    assert off.size, f"not unloaded to the off band: {h.min():.2f} N m s at best"
    assert 3 * 3600.0 < t[off[0]] < 4 * 3600.0 and h[off[0]:].max() < m.on_fraction * cap
    assert h[:off[0]].max() <= 1.01 * h[0]  # on the way down, never above where it started
    angle = np.degrees(4 * np.arctan(np.linalg.norm(run["sigma_BD"], axis=1)))
    assert angle.max() < 0.1, angle.max()
    err = np.linalg.norm(run["B_B"] - run["B_B_true"], axis=1)
    assert 200 * NT < np.median(err) < 600 * NT  # the magnetometer's error was in the loop


def test_detumble_from_a_noisy_magnetometer():
    """detumble, B-dot's difference taken from the 100 nT noise magnetometer's samples: |omega|
    from 5 deg/s below rate_off (0.5 deg/s) and the mode switched to the attitude law within
    the shortened 3000 s run (at 2100 s; 1887 s with the true field)."""
    scn = _shipped("detumble", 3000.0)
    run = simulate(scn, engine="cpp")
    rate = np.linalg.norm(run["omega_BN_B"], axis=1)
    mode = run["detumble_mode"]
    assert rate[0] > 0.08 and mode[0] == 0
    switched = np.flatnonzero(mode == 1)
    assert switched.size, f"never detumbled: |omega| at the end {rate[-1]:.4f} rad/s"
    k = switched[0]
    assert rate[k] < scn.magnetic_control.bdot.rate_off and np.all(rate[:k] >= scn.magnetic_control.bdot.rate_off)


def test_a_magnetometer_beside_the_gyro_and_star_tracker_changes_no_other_field():
    """A sensed run without magnetic control, with and without [sensors.magnetometer]: every field
    (the MEKF's estimate, its covariance, the law's rows) equal with ==, on both engines."""
    base = GYRO_STAR.replace("[sensors.gyro]", "[sensors]\nseed = 11\n[sensors.gyro]")
    without = mag_scenario(base, duration=10.0)
    with_mag = mag_scenario(MAGNETOMETER + GYRO_STAR, duration=10.0)
    assert with_mag.sensors.magnetometer is not None and without.sensors.magnetometer is None
    for engine in ("cpp", "python"):
        a, b = simulate(without, engine=engine), simulate(with_mag, engine=engine)
        assert np.all(np.isfinite(a["sigma_BN_est"]))
        diff = [k for k in a.trajectory if not np.array_equal(np.asarray(a[k]), np.asarray(b[k]),
                                                              equal_nan=np.asarray(a[k]).dtype.kind == "f")]
        assert diff == [], engine


def test_the_table_round_trips_through_the_scenarios_data():
    """What Monte Carlo workers and reruns rebuild a scenario from (sc_rt.scenario.keys.scenario_data):
    the same magnetometer, the same run bitwise."""
    from sc_rt.scenario.keys import scenario_data

    scn = _sensed(_mag(5.0, noise=50.0, bias=BIAS_NT, mounting=MOUNT, lsb=2.0), duration=5.0)
    back = scenario_from_data(scenario_data(scn), "rt.toml")
    a, b = scn.sensors.magnetometer, back.sensors.magnetometer
    assert all(np.array_equal(getattr(a, k), getattr(b, k)) for k in a.__dataclass_fields__)
    np.testing.assert_array_equal(simulate(scn, engine="cpp")["B_B"], simulate(back, engine="cpp")["B_B"])
