"""The calibrating filter (issue #30, item 2): ``[controller.estimator]
calibrate = true`` runs a 15-state MEKF that also estimates the gyro's
scale factors and misalignments (docs/MODEL.md, "Calibrating filter").

Checks: with nothing to calibrate (no initial uncertainty) it is the 6-state
filter; from noise-free data of a gyro with a known S it finds S; in a
closed loop with 1000-2000 ppm scale factors and 200-300 arcsec
misalignments in the truth, the 6-state filter is inconsistent (its errors
leave its 3 sigma) and the calibrating one is not; the default runs are
bitwise unchanged (tests/test_sensors.py pins them)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from sc_rt import _core
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate

ROOT = Path(__file__).resolve().parent.parent
ARCSEC = math.pi / 180.0 / 3600.0
S_TRUE = np.array([1500e-6, -1000e-6, 2000e-6, 800e-6, -600e-6, 1200e-6, -900e-6, 700e-6, -1100e-6])


def _params(calibrate: bool, sf_sigma: float = 0.0, mis_sigma: float = 0.0, arw: float = 0.0):
    p = _core.MekfParams()
    p.arw = arw
    p.sigma_cross = p.sigma_boresight = 5.0 * ARCSEC
    p.initial_attitude_sigma = 100.0 * ARCSEC
    p.initial_bias_sigma = 1e-5
    p.calibrate = calibrate
    p.initial_scale_factor_sigma = sf_sigma
    p.initial_misalignment_sigma = mis_sigma
    return p


def _rates(t: float) -> np.ndarray:
    """A rich manoeuvre: every axis, both signs (scale factors and
    misalignments observable)."""
    return 0.02 * np.array([math.sin(0.05 * t), math.cos(0.031 * t), math.sin(0.017 * t + 1.0)])


def _truth(n: int, dt: float):
    """Attitudes and rates at 1/dt Hz: the rate held over each step (exact
    attitude propagation with the step's mean rate: the increments are
    exact)."""
    sig = np.array([0.1, 0.2, -0.3])
    out = [(0.0, sig, _rates(0.0))]
    for k in range(1, n + 1):
        t = k * dt
        w = 0.5 * (_rates(t - dt) + _rates(t))
        sig = np.asarray(_core.mrp_rotate_body(sig, w * dt))
        out.append((t, sig, w))
    return out


def test_the_calibrating_filter_without_calibration_uncertainty_is_the_6_state_filter():
    truth = _truth(600, 1.0)
    six, cal = _core.Mekf(_params(False)), _core.MekfCal(_params(True))
    for f in (six, cal):
        f.reset(0.0, truth[0][1], np.zeros(3))
    rng = np.random.default_rng(3)
    for t, sig, w in truth:
        m = w + 1e-6 * rng.standard_normal(3)
        for f in (six, cal):
            f.gyro(t, m, _core.GYRO_MEAN_RATE)
        if t % 10 == 0:
            z = np.asarray(_core.mrp_rotate_body(sig, 5.0 * ARCSEC * rng.standard_normal(3)))
            for f in (six, cal):
                f.star(t, z)
        np.testing.assert_allclose(cal.state.sigma, six.state.sigma, rtol=0, atol=1e-13)
        np.testing.assert_allclose(cal.state.bias, six.state.bias, rtol=0, atol=1e-15)
        np.testing.assert_allclose(cal.state.P[:6, :6], six.state.P, rtol=1e-9, atol=1e-24)
        assert not np.any(cal.state.cal) and not np.any(cal.state.P[6:, :])


def test_it_finds_the_scale_factors_and_misalignments_of_a_noise_free_gyro():
    """A gyro measuring (I + S) omega, exactly, and a star tracker fix every
    10 s: the filter's S converges to the truth's."""
    dt, n = 1.0, 5400
    S = np.asarray(_core.gyro_calibration_matrix(S_TRUE))
    np.testing.assert_array_equal(S.diagonal(), S_TRUE[:3])  # [[s1 ku1 ku2], [kl1 s2 ku3], [kl2 kl3 s3]]
    assert (S[0, 1], S[0, 2], S[1, 2], S[1, 0], S[2, 0], S[2, 1]) == tuple(S_TRUE[3:])
    f = _core.MekfCal(_params(True, 3000e-6, 3000e-6, arw=1e-7))
    truth = _truth(n, dt)
    f.reset(0.0, truth[0][1], np.zeros(3))
    for t, sig, w in truth:
        f.gyro(t, (np.eye(3) + S) @ w, _core.GYRO_MEAN_RATE)
        if t % 10 == 0:
            f.star(t, sig)
    err = np.asarray(f.state.cal) - S_TRUE
    assert np.max(np.abs(err)) < 20e-6, err  # from a 3000 ppm prior to within 20 ppm
    sd = np.sqrt(np.diag(f.state.P)[6:])
    assert np.all(np.abs(err) < 5 * sd + 1e-9), (err, sd)
    attitude = np.linalg.norm(_core.mrp_error_vector(truth[-1][1], f.state.sigma))
    assert attitude < 1.0 * ARCSEC


def _closed_loop(calibrate: bool, tmp_path: Path):
    text = (ROOT / "scenarios" / "ppc_feasible_10hz_sensors.toml").read_text()
    text, n = re.subn(r"(?m)^scale_factor = .*$", "scale_factor = [1500.0, -1000.0, 2000.0]", text)
    text, m = re.subn(r"(?m)^misalignment = .*$", "misalignment = [200.0, -300.0, 250.0]", text)
    assert n == m == 1
    line = f"[controller.estimator]\ncalibrate = {str(calibrate).lower()}"
    text, k = re.subn(r"(?m)^\[controller\.estimator\]$", line, text)
    assert k == 1
    p = tmp_path / f"cal_{calibrate}.toml"
    p.write_text(text)
    return simulate(load_scenario(p), engine="cpp", duration=300.0)


def test_in_the_loop_only_the_calibrating_filter_stays_consistent(tmp_path):
    six, cal = _closed_loop(False, tmp_path), _closed_loop(True, tmp_path)
    e6, e15 = six.metrics["estimation_error_arcsec"], cal.metrics["estimation_error_arcsec"]
    # errors against the filter's own 3 sigma (after 30 s): a consistent filter keeps ~99.7 % inside
    assert e15["within_3sigma_fraction"] > 0.99, e15
    assert e6["within_3sigma_fraction"] < 0.9, e6
    assert e15["rms_total"] < 0.5 * e6["rms_total"], (e15, e6)


DISPERSE = '''
[montecarlo]
[[montecarlo.disperse]]
key = "sensors.gyro.scale_factor"
dist = "uniform"
low = -2000.0
high = 2000.0
apply = "set"

[[montecarlo.disperse]]
key = "sensors.gyro.misalignment"
dist = "normal"
std = 300.0
apply = "set"
'''


def test_scale_factor_and_misalignment_are_dispersed_in_a_campaign(tmp_path):
    """[montecarlo] draws the gyro's scale factors and misalignments per run
    (any numeric key can be dispersed): each run's draw is in the dataset,
    the runs differ, and the calibrating filter stays consistent in every
    one of them."""
    from sc_rt.studies.montecarlo import run_montecarlo

    text = (ROOT / "scenarios" / "ppc_feasible_10hz_sensors.toml").read_text()
    text = re.sub(r"(?m)^\[controller\.estimator\]$", "[controller.estimator]\ncalibrate = true", text)
    p = tmp_path / "cal_mc.toml"
    p.write_text(text + DISPERSE)
    res = run_montecarlo(load_scenario(p), 4, workers=1, seed=5, progress=False)
    rows = res["per_run"]
    draws = np.array([[r[f"sensors.gyro.scale_factor[{i}]"] for i in range(3)] for r in rows])
    assert draws.shape == (4, 3) and np.all(np.abs(draws) <= 2000.0) and len(np.unique(draws)) == 12
    within = [r["estimation_error_arcsec.within_3sigma_fraction"] for r in rows]
    rms = [r["estimation_error_arcsec.rms_total"] for r in rows]
    assert min(within) > 0.99, within
    assert len(set(rms)) == 4, rms
