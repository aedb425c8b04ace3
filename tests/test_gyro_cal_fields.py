"""The calibrating filter's states as per-row fields (issue 39 item 5):
``gyro_cal_est`` and ``gyro_cal_3sigma`` in the record, in
controller_status_t, in the MCAP and live rows (export/channels.py, one code
path for both), in the report (gyro_calibration.png); an initial calibration
estimate from the scenario; old status layouts still read.

The truth the estimates are checked against is the scenario's gyro
(``[sensors.gyro] scale_factor`` [ppm], ``misalignment`` [arcsec]) through the
sensor model of cpp/include/sc_rt/sensors.hpp, omega_m = (I + diag(sf))
(I - m^) omega, written out here: not the filter's own numbers."""

from __future__ import annotations

import json
import math
import re
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import sc_rt_lcm

from sc_rt.export.channels import JsonRows, channel_schema
from sc_rt.results.present.calibration_figure import calibration_figure
from sc_rt.scenario.reader import load_scenario
from sc_rt.scenario.schema import ScenarioError
from sc_rt.sim.engines import simulate
from sc_rt.wire import codec
from sc_rt.wire.lcmdefs import load_definitions
from sc_rt.wire.legacy import decode_current

ROOT = Path(__file__).resolve().parent.parent
ARCSEC = math.pi / 180.0 / 3600.0
SF_PPM = [1500.0, -1000.0, 2000.0]
MIS_ARCSEC = [200.0, -300.0, 250.0]


def _scenario(tmp_path: Path, calibrate: bool = True, estimator_extra: str = "") -> Path:
    text = (ROOT / "scenarios" / "ppc_feasible_10hz_sensors.toml").read_text()
    text, n = re.subn(r"(?m)^scale_factor = .*$", f"scale_factor = {SF_PPM}", text)
    text, m = re.subn(r"(?m)^misalignment = .*$", f"misalignment = {MIS_ARCSEC}", text)
    line = f"[controller.estimator]\ncalibrate = {str(calibrate).lower()}\n{estimator_extra}"
    text, k = re.subn(r"(?m)^\[controller\.estimator\]$", line, text)
    assert n == m == k == 1
    p = tmp_path / f"cal_{calibrate}_{len(estimator_extra)}.toml"
    p.write_text(text)
    return p


def true_calibration(sf_ppm, mis_arcsec) -> np.ndarray:
    """[s1 s2 s3, ku1 ku2 ku3, kl1 kl2 kl3] of S = (I + diag(sf)) (I - m^) - I."""
    sf, m = np.asarray(sf_ppm) * 1e-6, np.asarray(mis_arcsec) * ARCSEC
    mx = np.array([[0.0, -m[2], m[1]], [m[2], 0.0, -m[0]], [-m[1], m[0], 0.0]])
    S = (np.eye(3) + np.diag(sf)) @ (np.eye(3) - mx) - np.eye(3)
    return np.array([S[0, 0], S[1, 1], S[2, 2], S[0, 1], S[0, 2], S[1, 2], S[1, 0], S[2, 0], S[2, 1]])


@pytest.fixture(scope="module")
def cal_run(tmp_path_factory):
    p = _scenario(tmp_path_factory.mktemp("cal"))
    return simulate(load_scenario(p), engine="cpp", duration=300.0)


def test_the_record_holds_the_calibration_converging_to_the_truth(cal_run):
    est, sd3 = np.asarray(cal_run["gyro_cal_est"]), np.asarray(cal_run["gyro_cal_3sigma"])
    assert est.shape == sd3.shape == (len(cal_run["t"]), 9)
    assert np.isfinite(est).all() and (sd3 > 0).all()
    truth = true_calibration(SF_PPM, MIS_ARCSEC)
    err = est - truth
    # at the end every one of the nine is within its 3 sigma ...
    assert np.all(np.abs(err[-1]) < sd3[-1]), (err[-1], sd3[-1])
    # ... and it converged: every 3 sigma shrank from the prior's (3000 ppm,
    # 600 arcsec; at 300 s the widest is 0.46 of it) and every error from the
    # truth itself (the start is 0; at 300 s the largest is 0.17 of it)
    assert np.all(sd3[-1] < 0.6 * sd3[0]), (sd3[0], sd3[-1])
    assert np.all(np.abs(err[-1]) < 0.5 * np.abs(truth)), (err[-1], truth)
    # the estimate starts at the scenario's initial estimate (none given: 0)
    np.testing.assert_array_equal(est[0], np.zeros(9))


def test_the_report_draws_the_calibration(cal_run, tmp_path):
    p = calibration_figure(cal_run, tmp_path, truth=true_calibration(SF_PPM, MIS_ARCSEC))
    assert p == tmp_path / "gyro_calibration.png" and p.stat().st_size > 10_000


def test_the_6_state_filter_has_none_and_draws_none(tmp_path):
    run = simulate(load_scenario(_scenario(tmp_path, calibrate=False)), engine="cpp", duration=1.0)
    assert np.isnan(run["gyro_cal_est"]).all() and np.isnan(run["gyro_cal_3sigma"]).all()
    assert np.isfinite(run["P_diag"]).all()
    assert calibration_figure(run, tmp_path) is None


def test_an_initial_calibration_estimate_from_the_scenario(tmp_path):
    extra = ("initial_scale_factor = [100.0, -200.0, 300.0]\n"
             "initial_misalignment = [10.0, 20.0, 30.0, -10.0, -20.0, -30.0]")
    scn = load_scenario(_scenario(tmp_path, estimator_extra=extra))
    run = simulate(scn, engine="cpp", duration=1.0)
    want = np.concatenate([np.array([100.0, -200.0, 300.0]) * 1e-6,
                           np.array([10.0, 20.0, 30.0, -10.0, -20.0, -30.0]) * ARCSEC])
    np.testing.assert_allclose(run["gyro_cal_est"][0], want, rtol=1e-15, atol=0)
    py = simulate(scn, engine="python", duration=1.0)  # the python engine's loop: the same numbers
    np.testing.assert_array_equal(py["gyro_cal_est"], run["gyro_cal_est"])
    np.testing.assert_array_equal(py["gyro_cal_3sigma"], run["gyro_cal_3sigma"])
    # the bus cannot carry it (controller_config_t): sc-rt hil refuses instead of starting from 0
    with pytest.raises(ValueError, match="initial_scale_factor / initial_misalignment"):
        scn.controller_config_msg()


def test_an_initial_calibration_needs_the_calibrating_filter(tmp_path):
    with pytest.raises(ScenarioError, match="initial_scale_factor.*needs calibrate = true"):
        load_scenario(_scenario(tmp_path, calibrate=False, estimator_extra="initial_scale_factor = 100.0"))
    with pytest.raises(ScenarioError, match="initial_misalignment"):
        load_scenario(_scenario(tmp_path, estimator_extra="initial_misalignment = [1.0, 2.0, 3.0]"))


def _status(**values):
    s = sc_rt_lcm.controller_status_t()
    for k, v in values.items():
        setattr(s, k, v)
    return s


def test_the_status_mcap_and_live_rows_carry_the_calibration():
    assert {"gyro_cal_est", "gyro_cal_3sigma"} <= set(codec.STATUS_NAV_FIELDS)
    cal = [1e-3 * (i + 1) for i in range(9)]
    sd = [2e-4 * (i + 1) for i in range(9)]
    data = _status(t=1.5, nav=True, gyro_cal_est=cal, gyro_cal_3sigma=sd).encode()
    back = sc_rt_lcm.controller_status_t.decode(data)
    assert list(back.gyro_cal_est) == cal and list(back.gyro_cal_3sigma) == sd
    # the MCAP export's and the live view's rows and schema (export/channels.py)
    name, schema = channel_schema(sc_rt_lcm.controller_status_t, load_definitions(codec.lcm_sources()))
    assert schema["properties"]["gyro_cal_est"]["type"] == "array"
    assert "-, rad" in schema["properties"]["gyro_cal_est"].get("description", "")
    rows = JsonRows(sc_rt_lcm.controller_status_t).decode([data], Counter(), [0])
    row = json.loads(rows.rows[0])
    assert row["gyro_cal_est"] == cal and row["gyro_cal_3sigma"] == sd


def test_old_status_layouts_still_read():
    """A log of the layout before the table (controller_status_v2_t) and of the
    one before #26 (v1) decode as today's, the fields they lack NaN."""
    v2 = sc_rt_lcm.controller_status_v2_t()
    v2.t, v2.nav, v2.sigma_BD, v2.x2d, v2.nis, v2.n_telemetry = 2.5, True, [0.1, -0.2, 0.3], [1.0, 2.0, 3.0], 4.0, 2
    v1 = sc_rt_lcm.controller_status_v1_t()
    v1.t, v1.sigma_BD = 3.5, [0.4, 0.5, 0.6]
    new = _status(t=4.5, sigma_BD=[0.7, 0.8, 0.9], gyro_cal_est=[1.0] * 9)
    datas = [v2.encode(), v1.encode(), new.encode()]
    assert len({d[:8] for d in datas}) == 3  # three layouts, three fingerprints
    rec, idx = decode_current(sc_rt_lcm.controller_status_t, datas, Counter())
    assert list(idx) == [0, 1, 2]
    np.testing.assert_array_equal(rec["t"], [2.5, 3.5, 4.5])
    np.testing.assert_array_equal(rec["sigma_BD"], [[0.1, -0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9]])
    np.testing.assert_array_equal(rec["x2d"][0], [1.0, 2.0, 3.0])
    assert rec["nis"][0] == 4.0 and rec["n_telemetry"][0] == 2
    assert np.isnan(rec["gyro_cal_est"][:2]).all() and (rec["gyro_cal_est"][2] == 1.0).all()
    assert np.isnan(rec["x2d"][1]).all()  # v1 had no x2d
