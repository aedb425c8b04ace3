"""The magnetometer's samples on the bus (issue 43; docs/PROTOCOL.md,
"Sensors" and "Magnetic control"; docs/HIL.md, "Magnetic control on the
bus"): with ``[sensors.magnetometer]`` the emulator publishes its samples
(``magnetometer_t``, SOURCE_SENSOR in the sensor frame, its own seq and
tick, at its rate) instead of the true field, controller_config_t carries
the known mounting (``nav_mag_*``), and both controller processes feed the
samples to their sensor intake, whose ``field_B`` is the offline loop's
``Navigation::field_B``.

Checked against what the bus did not compute: the offline ``Navigation``
(a second implementation of the hold and rotation, bitwise), the mounting
matrix from the test's own MRP formula (tests/refmath.py), the offline C++
engine's run of the same file bit for bit (tests/trajcmp.py), the scenario's
own rates for the samples' count in the log.

Fail on the old main: the bus commands refused [sensors] with magnetic
control (exit 2), controller_config_t had no ``nav_mag_*``, the
SensorIntake no ``offer_mag``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import sc_rt_lcm

from refmath import mrp_dcm
from sc_rt import _core
from sc_rt.scenario.overrides import with_overrides
from sc_rt.scenario.reader import load_scenario
from sc_rt.scenario.shipped import resolve
from sc_rt.scenario.tables.sensors import nav_config
from sc_rt.sim.engines import simulate

import lcmnet
from magscn import detumble_switch
from trajcmp import compared_fields, load_traj

HERE = Path(__file__).resolve().parent
PD_SPEC = str(HERE.parent / "examples" / "python_laws" / "pd.py") + ":PythonPD"
#: a mounting (sigma_SB), a bias, scale factors and noise: the controller knows only the mounting
MOUNT = (0.1, -0.2, 0.3)
MAGNETOMETER = ("[sensors]\nseed = 11\n[sensors.magnetometer]\nrate_hz = {rate}\nnoise = 100.0\n"
                "bias = [200.0, -150.0, 100.0]\nmounting = [0.1, -0.2, 0.3]\nlsb = 5.0\n"
                "scale_factor = [300.0, -200.0, 100.0]\n")
GYRO_STAR = ("[sensors.gyro]\nrate_hz = 10.0\narw = 0.01\nbias0 = 1.0\n[sensors.star_tracker]\nrate_hz = 5.0\n"
             "sigma_cross = 5.0\nsigma_boresight = 30.0\n")
HOLD_S, DETUMBLE_S = 60.0, 120.0


def _day_hold_sensed(tmp_path: Path) -> Path:
    """day_hold with a 5 Hz magnetometer (mounted, biased, noisy), a gyro and a star
    tracker, the law fed the MEKF's estimate and the manager the measured field."""
    text = Path(resolve("day_hold")).read_text()
    text, n = re.subn(r"(?m)^\[controller\]$", '[controller]\nmeasurement = "estimate"', text)
    assert n == 1
    p = tmp_path / "day_hold_sensed.toml"
    p.write_text(text + MAGNETOMETER.format(rate=5.0) + GYRO_STAR)
    return p


def _detumble_sensed(tmp_path: Path) -> Path:
    """detumble from 0.6 deg/s (tests/test_mag_bus.py's) with a 10 Hz magnetometer:
    B-dot's difference taken between its samples, then the switch to the law."""
    text = Path(resolve("detumble")).read_text()
    text = text.replace("omega_BN_B = [0.05, -0.06, 0.04]", "omega_BN_B = [0.006, -0.0065, 0.004]")
    assert "0.006, -0.0065" in text
    p = tmp_path / "detumble_sensed.toml"
    p.write_text(text + MAGNETOMETER.format(rate=10.0))
    return p


# --- without the bus ---------------------------------------------------------------------------------


def test_the_configuration_carries_the_mounting_and_an_older_one_reads_without(tmp_path):
    from sc_rt.wire.legacy import upgrade

    scn = load_scenario(_day_hold_sensed(tmp_path))
    msg = scn.controller_config_msg()
    assert msg.nav_enabled and msg.nav_mag_enabled
    np.testing.assert_allclose(msg.nav_mag_R_SB, mrp_dcm(np.array(MOUNT)), rtol=0, atol=1e-15)
    nav = _core.nav_from_config_bytes(msg.encode())
    np.testing.assert_array_equal(nav[4], np.array(msg.nav_mag_R_SB))
    # a non-rotation is refused by the controller's reader, with the field's name
    bad = sc_rt_lcm.controller_config_t.decode(msg.encode())
    bad.nav_mag_R_SB = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    with pytest.raises(ValueError, match="nav_mag_R_SB"):
        _core.nav_from_config_bytes(bad.encode())
    # the layout before (controller_config_v3_t): every field as it was, no magnetometer samples
    old = sc_rt_lcm.controller_config_v3_t()
    for k in old.__slots__:
        setattr(old, k, getattr(msg, k))
    new = upgrade(sc_rt_lcm.controller_config_v3_t.decode(old.encode()))
    assert isinstance(new, sc_rt_lcm.controller_config_t) and not new.nav_mag_enabled
    assert new.nav_enabled and new.mag_momentum_enabled and list(new.nav_sigma0) == list(msg.nav_sigma0)
    assert _core.nav_from_config_bytes(new.encode())[4] is None


def test_the_intake_holds_the_samples_rotated_to_B_as_the_offline_navigation_does(tmp_path):
    """The emulator's SensorSuite and the offline Navigation from one NavConfig, the same true
    field: the intake fed the suite's samples (as the bus carries them) has, at every control
    instant after use(), the Navigation's field_B with ==, and R_SB' B_S of the test's own matrix."""
    scn = load_scenario(_day_hold_sensed(tmp_path))
    nc = nav_config(scn.sensors, scn.run.plant_step, "t")
    suite, nav = _core.SensorSuite(nc.sensors), _core.Navigation(nc)
    x = np.concatenate([scn.initial.sigma_BN, scn.initial.omega_BN_B, scn.initial.wheel_speed])
    nav.reset(x)
    suite.reset()
    intake = _core.SensorIntake(nc.mekf, False, np.zeros(3))
    intake.mount_magnetometer(nc.sensors.magnetometer.R_SB)
    R = mrp_dcm(np.array(MOUNT))
    rng = np.random.default_rng(3)
    session, seq, samples = 77, 0, 0
    assert np.all(np.isnan(intake.field_B))
    for i in range(60):
        t = i * scn.run.plant_step
        B = tuple(3e-5 * rng.standard_normal(3))  # any field: both get the same
        due = suite.magnetometer_due(i)
        assert due == nav.magnetometer_due(i) == (i % 2 == 0)  # 5 Hz on the 10 Hz grid
        suite.tick(i, t, x, B if due else None)
        nav.tick(i, t, x, B if due else None)
        if suite.mag_new:
            tm, B_S = suite.mag
            intake.offer_mag(session, seq, tm, B_S)
            seq += 1
            samples += 1
            # the test's own rotation, to rounding of the field's magnitude
            np.testing.assert_allclose(nav.field_B, R.T @ np.asarray(B_S), rtol=0,
                                       atol=1e-14 * np.linalg.norm(B_S))
        intake.use(session, t)
        assert np.array_equal(intake.field_B, nav.field_B), i
    assert samples == 30 and intake.counts().mag_used == 30
    # the other sensors' rules: a repeated seq or a non-finite sample is counted and changes nothing
    held = np.array(intake.field_B)
    intake.offer_mag(session, seq - 1, 5.95, (1e-5, 2e-5, 3e-5))
    intake.offer_mag(session, seq, 5.95, (np.nan, 0.0, 0.0))
    intake.use(session, 5.95)
    c = intake.counts()
    assert (c.out_of_order, c.invalid, c.mag_used) == (1, 1, 30) and np.array_equal(intake.field_B, held)
    # a sample of another session is not this session's field; a new session starts without one
    intake.use(session + 1, 6.0)
    assert np.all(np.isnan(intake.field_B))


# --- over real LCM -----------------------------------------------------------------------------------


def _hil(path, out, duration, *extra) -> None:
    r = lcmnet.run_cli(["hil", str(path), "--mode", "lockstep", "--duration", f"{duration:g}", "--out", str(out),
                        "--no-plots", *extra])
    assert r.returncode == 0, r.stderr + r.stdout


def _same_as_sim(path, out, duration, law=None) -> tuple:
    """The lockstep run against the C++ engine's sensed run of the file: every field both
    produced bit for bit, the field, the rods' commands and the navigation's among them."""
    hil = load_traj(out)
    scn = with_overrides(load_scenario(path), duration=duration)
    run = simulate(scn, engine="cpp") if law is None else simulate(scn, law=law, engine="cpp")
    every = scn.record.every
    sim = {k: np.asarray(run[k])[::every] for k in hil.files if k != "meta_json" and k in run}
    assert len(hil["t"]) == len(sim["t"]) == len(run["t"][::every])
    done = compared_fields(hil, sim)
    assert {"rod_dipole_cmd", "m_B_cmd", "B_B"} <= set(done), done
    # the field the controller used is the magnetometer's, not the truth
    assert np.all(np.isfinite(run["B_B"][1:])) and np.any(run["B_B"] != run["B_B_true"])
    return hil, run


@pytest.mark.lcm
def test_day_hold_sensed_in_lockstep_is_bitwise_the_cpp_engine(tmp_path):
    lcmnet.require()
    path, out = _day_hold_sensed(tmp_path), tmp_path / "hil"
    _hil(path, out, HOLD_S)
    hil, run = _same_as_sim(path, out, HOLD_S)
    done = compared_fields(hil, {k: np.asarray(run[k])[::10] for k in hil.files if k in run})
    assert {"sigma_BN_est", "bias_est", "P_diag"} <= set(done), done  # the MEKF's estimate too
    assert np.abs(hil["rod_dipole_cmd"][:, :3]).max() > 1.0
    timing = json.loads((out / "timing.json").read_text())
    n_mag = int(HOLD_S * 5) + 1  # 5 Hz from t = 0 to the last state's tick
    assert timing["emulator_counters"]["mag_sent"] == n_mag and not any(timing["log_missing"].values())
    summary = json.loads((out / "controller_summary.json").read_text())
    assert summary["nav"]["mag_used"] == n_mag and summary["magnetic"]["field_missing"] == 0
    # the log's report: the magnetometer among the sensors, every sample there at its rate
    rep = tmp_path / "rep"
    r = lcmnet.run_cli(["report", str(out / "run.lcmlog"), "--out", str(rep), "--no-plots"])
    assert r.returncode == 0, r.stderr + r.stdout
    sens = json.loads((rep / "report.json").read_text())["sensors"]["magnetometer"]
    assert sens["samples"] == n_mag and sens["seq_missing"] == 0 and sens["rate_hz"] == pytest.approx(5.0)


@pytest.mark.lcm
def test_detumble_sensed_in_lockstep_is_bitwise_the_cpp_engine_through_its_mode_switch(tmp_path):
    lcmnet.require()
    path, out = _detumble_sensed(tmp_path), tmp_path / "hil"
    _hil(path, out, DETUMBLE_S)
    hil, _ = _same_as_sim(path, out, DETUMBLE_S)
    detumble_switch(hil)


@pytest.mark.lcm
def test_the_samples_with_authentication_are_still_bitwise(tmp_path):
    """--auth-key: every magnetometer_t carries its tag, sc-rt-controller verifies it before
    decoding; nothing fails to verify, every sample applied, the numbers stay."""
    lcmnet.require()
    key = tmp_path / "key"
    key.write_bytes(b"a lab key of our own, 32 bytes!!")
    path, out = _detumble_sensed(tmp_path), tmp_path / "hil"
    _hil(path, out, 40.0, "--auth-key", str(key))
    _same_as_sim(path, out, 40.0)
    summary = json.loads((out / "controller_summary.json").read_text())
    assert summary["auth"] and summary["auth_failed"] == 0
    assert summary["nav"]["mag_used"] == 40 * 10 + 1 and sum(summary["nav"]["rejected"].values()) == 0
    assert summary["magnetic"]["field_rejected"] == 0 and summary["magnetic"]["field_missing"] == 0


@pytest.mark.lcm
def test_hostile_magnetometer_messages_during_a_lockstep_run_change_nothing(tmp_path):
    """5,000 malformed, truncated, foreign, replayed and non-finite magnetometer_t (and gyro_t)
    messages while the sensed day_hold runs in lockstep: sc-rt-controller counts them and
    applies none, every genuine sample once (the run is bitwise the offline one)."""
    import shlex
    import sys

    lcmnet.require()
    py = shlex.quote(sys.executable)
    url = "udpm://239.255.76.67:7716?ttl=0&recv_buf_size=4194304"
    path, out, sent = _day_hold_sensed(tmp_path), tmp_path / "hil", tmp_path / "sent.json"
    script = f"""
set -e
{py} -m sc_rt.cli hil {path} --duration {HOLD_S:g} --no-plots --out {out} --lcm-url '{url}' > {tmp_path}/hil.log 2>&1 &
HIL=$!
SCRT_WAIT_PID=$HIL {py} {HERE / 'fuzz_lcm.py'} '{url}' 5000 {sent} 5 SCRT_MAG,SCRT_GYRO
wait $HIL
"""
    r = lcmnet.run_script(script, timeout=600)
    assert r.returncode == 0, r.stderr + (tmp_path / "hil.log").read_text()
    assert json.loads(sent.read_text())["n"] == 5000
    _same_as_sim(path, out, HOLD_S)
    summary = json.loads((out / "controller_summary.json").read_text())
    nav, mag = summary["nav"], summary["magnetic"]
    assert mag["field_rejected"] > 0 and nav["rejected"]["foreign"] > 0, summary
    assert nav["mag_used"] == int(HOLD_S * 5) + 1 and mag["field_missing"] == 0, summary


@pytest.mark.lcm
def test_a_short_real_time_sensed_day_hold_uses_the_samples(tmp_path):
    """Real time (timer trigger): the samples of a period go out together at its end, each
    applied once its state's time reaches it; the rods are commanded from the measured
    field, and no step lacks a field."""
    lcmnet.require()
    out = tmp_path / "rt"
    r = lcmnet.run_cli(["hil", str(_day_hold_sensed(tmp_path)), "--mode", "realtime", "--duration", "5",
                        "--trigger", "timer", "--floor", "off", "--out", str(out), "--no-plots"])
    lcmnet.realtime_outcome(r, out)  # (a loaded machine may not keep real time: judged so, not the subject)
    timing = json.loads((out / "timing.json").read_text())
    assert timing["emulator_counters"]["mag_sent"] == 26 and not any(timing["log_missing"].values()), timing
    summary = json.loads((out / "controller_summary.json").read_text())
    assert summary["nav"]["mag_used"] >= 25 and summary["magnetic"]["field_missing"] == 0, summary
    hil = load_traj(out)
    rods = hil["rod_dipole_cmd"][:, :3]
    assert np.isfinite(rods).all() and np.abs(rods).max() > 1.0
    B = np.linalg.norm(hil["B_B"], axis=1)  # the field of the rows whose status arrived: a LEO's
    assert np.isfinite(B).sum() > len(B) // 2 and np.all((B[np.isfinite(B)] > 1e-5) & (B[np.isfinite(B)] < 7e-5))


@pytest.mark.lcm
def test_a_python_law_in_sc_rt_controller_takes_the_samples_bitwise_as_sim(tmp_path):
    # sc-rt controller (pycontroller.py, maglink.py) feeds its intake the same samples
    lcmnet.require()
    path, out = _detumble_sensed(tmp_path), tmp_path / "hil"
    _hil(path, out, 80.0, "--law", PD_SPEC)
    _same_as_sim(path, out, 80.0, PD_SPEC)
    assert json.loads((out / "controller_summary.json").read_text())["magnetic"]["field_missing"] == 0
