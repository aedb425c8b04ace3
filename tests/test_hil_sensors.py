"""Sensors on the bus (issue #15): the emulator publishes the gyro, star
tracker and tachometer samples (gyro_t, star_tracker_t, tachometer_t) at
their own rates, sc-rt-controller runs the MEKF on them, and

- a lockstep run is bit-identical to ``sc-rt sim`` with the sensors on, in
  both measurement modes, estimator fields and metrics included (a sample
  lost, reordered, applied twice or at another time would change them);
- the log holds every sample (seqs 0..n-1, one per sensor period) and
  ``sc-rt report`` rebuilds the estimator's fields from it bit for bit;
- the controller counts what it used, and it equals what was published;
- ``sc-rt spy`` shows the samples and the estimate;
- a real-time run with sensors stays up and keeps its estimate finite."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import sc_rt_lcm

from sc_rt.tools.spy import Spy
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate

import lcmnet
from trajcmp import compared_fields, load_traj

ROOT = Path(__file__).resolve().parent.parent
LIB = ROOT / "scenarios"
pytestmark = pytest.mark.lcm
NAV_FIELDS = ("sigma_BN_est", "bias_est", "bias_true", "P_diag", "att_est_error", "innovation", "nis", "flags")


def _scenario(tmp_path: Path, name: str, measurement: str, gyro: str = "rate", calibrate: bool = False) -> Path:
    """A shipped sensors scenario with [controller] measurement and the
    gyro's output ([sensors.gyro] output) set; calibrate: scale factors and
    misalignments in the gyro, and the calibrating filter."""
    text = (LIB / f"{name}.toml").read_text()
    text, n = re.subn(r'(?m)^measurement\s*=\s*"\w+"', f'measurement = "{measurement}"', text)
    assert n == 1
    if gyro != "rate":
        text, n = re.subn(r"(?m)^\[sensors\.gyro\]$", f'[sensors.gyro]\noutput = "{gyro}"', text)
        assert n == 1
    if calibrate:
        text, n = re.subn(r"(?m)^scale_factor = .*$", "scale_factor = [1500.0, -1000.0, 2000.0]", text)
        text, m = re.subn(r"(?m)^misalignment = .*$", "misalignment = [200.0, -300.0, 250.0]", text)
        text, k = re.subn(r"(?m)^\[controller\.estimator\]$", "[controller.estimator]\ncalibrate = true", text)
        assert n == m == k == 1
    p = tmp_path / f"{name}_{measurement}_{gyro}_{calibrate}.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("name,measurement,duration,gyro,calibrate", [
    ("ppc_feasible_10hz_sensors", "estimate", 30.0, "rate", False),
    ("ppc_feasible_10hz_sensors", "truth", 10.0, "rate", False),
    ("ppc_feasible_100hz_sensors", "estimate", 6.0, "rate", False),
    # an integrating gyro (issue #30): gyro_t carries its kind, the controller's MEKF propagates with it
    ("ppc_feasible_10hz_sensors", "estimate", 20.0, "increment", False),
    # and the calibrating filter, configured through controller_config_t
    ("ppc_feasible_10hz_sensors", "estimate", 20.0, "increment", True),
])
def test_lockstep_with_sensors_is_bit_identical_to_sim(tmp_path, name, measurement, duration, gyro, calibrate):
    lcmnet.require()
    path = _scenario(tmp_path, name, measurement, gyro, calibrate)
    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", str(path), "--mode", "lockstep", "--duration", str(duration),
                        "--out", str(out), "--no-plots"])
    assert r.returncode == 0, r.stderr + r.stdout
    hil = load_traj(out)
    scn = load_scenario(path)
    sim = simulate(scn, engine="cpp", duration=duration)
    rows = int(round(duration * scn.run.control_rate_hz)) + 1
    assert len(hil["t"]) == len(sim["t"]) == rows
    done = compared_fields(hil, sim)
    for k in NAV_FIELDS:  # the estimator's fields were there, and compared
        assert k in done, k
    assert np.isfinite(hil["nis"]).sum() > 5  # star tracker updates happened
    metrics = json.loads((out / "metrics.json").read_text())
    for k in ("estimation_error_arcsec", "pointing_error_arcsec", "first_bound_violation_s", "max_abs_u_cmd"):
        assert metrics[k] == sim.metrics[k], k
    # the controller used every sample the emulator published, none rejected
    summary = json.loads((out / "controller_summary.json").read_text())
    nav = summary["nav"]
    assert nav["measurement"] == measurement
    assert sum(nav["rejected"].values()) == 0, nav
    # the log: every sample, in order, at the sensor's rate
    from sc_rt.logs.logread import read_log
    from sc_rt.logs.rebuild import sensor_summary

    # the emulator sent every sample once, at the sensor's rate, and the controller used each
    timing = json.loads((out / "timing.json").read_text())
    emu = timing["emulator_counters"]
    s = scn.sensors
    n_gyro = int(np.floor(duration * s.gyro.rate_hz + 1e-9)) + 1  # samples at 0, 1/rate, ..., duration
    n_tach = int(np.floor(duration * s.tachometer.rate_hz + 1e-9)) + 1
    assert emu["gyro_sent"] == nav["gyro_used"] == n_gyro
    assert emu["tach_sent"] == nav["tach_used"] == n_tach
    assert emu["star_sent"] == nav["star_used"] > 0
    # the log is complete (sc-rt-logger's deep queue; before, lcm-logger's
    # 30-message queue lost up to 162 of 601 states in a lockstep burst, and
    # the run only warned): every sample, in order, at the sensor's rate
    d = read_log(out / "run.lcmlog")
    ss = sensor_summary(d)
    assert not any(timing["log_missing"].values()), timing["log_missing"]
    for key, _ch, sent in (("gyro", "SCRT_GYRO", "gyro_sent"), ("star_tracker", "SCRT_STAR", "star_sent"),
                          ("tachometer", "SCRT_TACH", "tach_sent")):
        got = ss[key]
        assert got["repeated"] == 0 and got["other_sessions"] == 0, (key, got)
        assert got["samples"] == emu[sent], (key, got)
    for key, part in (("gyro", s.gyro), ("star_tracker", s.star_tracker), ("tachometer", s.tachometer)):
        assert ss[key]["seq_first"] == 0 and ss[key]["seq_missing"] == 0, (key, ss[key])
        assert ss[key]["rate_hz"] == pytest.approx(part.rate_hz, rel=1e-6), key
    lat = ss["star_tracker"]["latency_s"]
    assert lat["min"] == pytest.approx(s.star_tracker.latency) and lat["max"] == pytest.approx(lat["min"])
    # sc-rt report rebuilds the estimator's fields from the log, bit for bit (the rows it has whole)
    rep = tmp_path / "report"
    r2 = lcmnet.run_cli(["report", str(out / "run.lcmlog"), "--out", str(rep), "--no-plots"], netns=False)
    assert r2.returncode == 0, r2.stderr + r2.stdout
    back = load_traj(rep)
    rows_back = np.searchsorted(hil["t"], back["t"])
    assert np.array_equal(hil["t"][rows_back], back["t"]) and len(back["t"]) >= 0.5 * rows
    for k in NAV_FIELDS + ("sigma_BN", "u_cmd"):
        assert np.array_equal(back[k], hil[k][rows_back], equal_nan=back[k].dtype.kind == "f"), k
    report = json.loads((rep / "report.json").read_text())
    assert report["sensors"]["gyro"]["samples"] == ss["gyro"]["samples"]
    assert json.loads((rep / "metrics.json").read_text())["estimation_error_arcsec"] == metrics[
        "estimation_error_arcsec"]


def test_spy_shows_the_samples_and_the_estimate():
    spy = Spy("memq://", window=10.0)
    g = sc_rt_lcm.gyro_t()
    g.seq, g.t, g.omega = 3, 0.3, [1e-3, -2e-3, 3e-3]
    st = sc_rt_lcm.star_tracker_t()
    st.seq, st.t_exposure, st.t_delivery, st.sigma_BN, st.lost = 1, 0.25, 0.5, [0.1, 0.2, 0.3], 2
    tc = sc_rt_lcm.tachometer_t()
    tc.seq, tc.t, tc.wheel_speed = 5, 0.5, [10.0, -5.0, 3.0, 0.5]
    s = sc_rt_lcm.controller_status_t()
    s.nav, s.P_diag = True, [1e-10, 4e-10, 9e-10, 0.0, 0.0, 0.0]
    s.innovation, s.nis, s.nav_flags, s.gyro_used = [1e-5, 0.0, 0.0], 1.5, 2048, 42
    spy.lc.publish("SCRT_GYRO", g.encode())
    spy.lc.publish("SCRT_STAR", st.encode())
    spy.lc.publish("SCRT_TACH", tc.encode())
    spy.lc.publish("SCRT_CTRL_STATUS", s.encode())
    spy.lc.publish("SCRT_GYRO", b"garbage")
    spy.listen(0.3)
    snap = json.loads(json.dumps(spy.snapshot()))
    ch = snap["channels"]
    assert ch["SCRT_GYRO"]["type"] == "gyro_t" and ch["SCRT_GYRO"]["undecodable"] == 1
    assert ch["SCRT_GYRO"]["summary"]["omega"] == [1e-3, -2e-3, 3e-3]
    assert ch["SCRT_STAR"]["summary"]["lost"] == 2 and ch["SCRT_STAR"]["summary"]["t_exposure"] == 0.25
    assert ch["SCRT_TACH"]["summary"]["wheel_speed"][0] == 10.0
    nav = ch["SCRT_CTRL_STATUS"]["summary"]["nav"]
    arcsec = 180 * 3600 / np.pi
    assert nav["att_sigma_arcsec"] == pytest.approx([1e-5 * arcsec, 2e-5 * arcsec, 3e-5 * arcsec])
    assert nav["degraded"] and nav["gyro_used"] == 42 and nav["nis"] == 1.5
    text = spy.render()
    assert "SCRT_GYRO" in text and "DEGRADED" in text and "exposed 0.250 s" in text


@pytest.mark.slow  # ~10 s: a 6 s real-time run
def test_realtime_with_sensors_stays_up_and_estimates(tmp_path):
    lcmnet.require()
    path = _scenario(tmp_path, "ppc_feasible_10hz_sensors", "estimate")
    out = tmp_path / "rt"
    r = lcmnet.run_cli(["hil", str(path), "--mode", "realtime", "--duration", "6", "--out", str(out),
                        "--no-plots"], timeout=240)
    assert r.returncode == 0, r.stderr + r.stdout
    hil = load_traj(out)
    summary = json.loads((out / "controller_summary.json").read_text())
    ss_rows = np.isfinite(hil["sigma_BN_est"]).all(axis=1)
    assert ss_rows.sum() >= 0.5 * len(hil["t"])  # the status of most rows carried the estimate
    err = hil["att_est_error"][ss_rows]
    assert np.all(np.isfinite(err))
    # the estimate stays within a few of its own sigmas of the truth (no divergence)
    sig = np.sqrt(hil["P_diag"][ss_rows][:, 0:3])
    assert np.all(np.abs(err) <= 6 * sig + 5e-6)
    nav = summary["nav"]
    assert nav["gyro_used"] >= 0.9 * 6 * 10 and nav["star_used"] >= 10


def test_sensor_messages_are_packed_as_the_generated_encoders_pack_them():
    from sc_rt.emulator.sensorpub import gyro_bytes, star_bytes, tach_bytes

    g = sc_rt_lcm.gyro_t()
    g.utime, g.seq, g.session, g.tick, g.t, g.omega = 1, 2, 3, 4, 0.5, [1e-3, -2.0, np.pi]
    assert gyro_bytes(1, 2, 3, 4, 0.5, g.omega) == g.encode()
    g.output = 1  # an integrating gyro's mean rate
    assert gyro_bytes(1, 2, 3, 4, 0.5, g.omega, 1) == g.encode()
    s = sc_rt_lcm.star_tracker_t()
    s.utime, s.seq, s.session, s.tick = 1, 2, 3, 4
    s.t_exposure, s.t_delivery, s.sigma_BN, s.lost, s.blacked_out = 0.25, 0.5, [0.1, -0.2, 0.3], 5, 6
    assert star_bytes(1, 2, 3, 4, 0.25, 0.5, s.sigma_BN, 5, 6) == s.encode()
    c = sc_rt_lcm.tachometer_t()
    c.utime, c.seq, c.session, c.tick, c.t, c.wheel_speed = 1, 2, 3, 4, 0.5, [10.0, -5.0, 3.0, 0.5]
    assert tach_bytes(1, 2, 3, 4, 0.5, c.wheel_speed) == c.encode()


def test_lockstep_with_sensors_and_authentication_is_still_bit_identical(tmp_path):
    """--auth-key: every sensor message carries its tag, the controller verifies
    it per channel before decoding; nothing fails to verify, the numbers stay."""
    lcmnet.require()
    key = tmp_path / "key"
    key.write_bytes(b"a lab key of our own, 32 bytes!!")
    out = tmp_path / "hil"
    path = LIB / "ppc_feasible_10hz_sensors.toml"
    r = lcmnet.run_cli(["hil", str(path), "--mode", "lockstep", "--duration", "8", "--out", str(out),
                        "--no-plots", "--auth-key", str(key)])
    assert r.returncode == 0, r.stderr + r.stdout
    hil = load_traj(out)
    sim = simulate(load_scenario(path), engine="cpp", duration=8.0)
    done = compared_fields(hil, sim)
    assert "sigma_BN_est" in done and "innovation" in done
    summary = json.loads((out / "controller_summary.json").read_text())
    assert summary["auth"] and summary["auth_failed"] == 0
    assert summary["nav"]["gyro_used"] == 8 * 100 + 1 and sum(summary["nav"]["rejected"].values()) == 0


def test_hostile_sensor_messages_during_a_lockstep_run_change_nothing(tmp_path):
    """20,000 malformed, truncated, foreign, replayed and non-finite gyro, star
    tracker and tachometer messages while a lockstep run with the estimate in
    the loop goes on: the controller counts them and applies none (the run is
    bit-identical to the offline one)."""
    import shlex
    import sys

    lcmnet.require()
    here = Path(__file__).resolve().parent
    py = shlex.quote(sys.executable)
    url = "udpm://239.255.76.67:7713?ttl=0&recv_buf_size=4194304"
    n, duration = 20_000, 300
    out, sent = tmp_path / "hil", tmp_path / "sent.json"
    path = LIB / "ppc_feasible_10hz_sensors.toml"
    script = f"""
set -e
{py} -m sc_rt.cli hil {path} --duration {duration} --no-plots --out {out} --lcm-url '{url}' > {tmp_path}/hil.log 2>&1 &
HIL=$!
SCRT_WAIT_PID=$HIL {py} {here / 'fuzz_lcm.py'} '{url}' {n} {sent} 3 SCRT_GYRO,SCRT_STAR,SCRT_TACH
wait $HIL
"""
    r = lcmnet.run_script(script, timeout=600)
    assert r.returncode == 0, r.stderr + (tmp_path / "hil.log").read_text()
    s = json.loads(sent.read_text())
    assert s["n"] == n
    summary = json.loads((out / "controller_summary.json").read_text())
    nav = summary["nav"]
    rejected = sum(nav["rejected"].values())
    # what the controller received of the storm (UDP may drop some of a burst) it rejected
    assert 0 < rejected <= n, nav
    for kind in ("malformed", "invalid", "foreign", "out_of_order"):
        assert nav["rejected"][kind] > 0, nav
    hil = load_traj(out)
    sim = simulate(load_scenario(path), engine="cpp", duration=float(duration))
    done = compared_fields(hil, sim)
    assert "sigma_BN_est" in done and "nis" in done
    # every genuine sample was used once
    assert nav["gyro_used"] == duration * 100 + 1 and nav["tach_used"] == duration * 10 + 1
