"""sc-rt's MEKF against a textbook case nobody here wrote: Markley & Crassidis (2014), Example 6.1
(a star tracker and three gyros at 1 Hz for 90 min), re-implemented in numpy in
tests/example61.py and tests/example61_filters.py (issue 30, item 4).

(a) the reference itself: Farrenkopf's closed form is the discrete Riccati equation's solution,
    and the Example's covariance recursion converges to it;
(b) sc-rt's 6-state filter (``_core.Mekf``) fed the Example's measurements: its covariance and
    estimates follow the Example's recursion, its errors its covariance (NEES in the chi-square
    band, the fraction inside 3 sigma), over seeded runs;
(c) with the Example's scale factors and misalignments in the gyros, 6-state filters (numpy's
    and sc-rt's) are inconsistent, the numpy 15-state filter is not; example61's
    check_calibrating_filter, which sc-rt's calibrating filter will be held to, is run on both.

sc-rt averages the two gyro samples bounding an interval; the Example holds the first over it (its
truth turns at the held rate). sc-rt is given each sample at both ends of its interval ("pairs",
example61_filters.scrt_filter), which makes its interval rate the Example's; given one sample per
second at its time it is half a sample off, and is right only for samples of a smooth rate.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg

import example61 as ex
import example61_filters as ef
from sc_rt import _core

P = ex.Example61()
RUNS, SEED, STRIDE = 20, 61, 10
K = np.arange(0, P.steps, STRIDE)  # the recorded epochs, every 10 s to 90 min
FK = ex.farrenkopf(P.sigma_v, P.sigma_u, P.sigma_star, P.dt)


@pytest.fixture(scope="module")
def bias_only():
    """The Example's truth with the bias only (the gyros have no scale factor nor misalignment)."""
    return ex.simulate(P, RUNS, SEED)


@pytest.fixture(scope="module")
def numpy_6(bias_only):
    return ef.mekf(bias_only, K, 6)


@pytest.fixture(scope="module")
def scrt_6(bias_only):
    return ef.scrt_filter("pairs")(bias_only, K)


@pytest.fixture(scope="module")
def calibrating():
    """The same with the Example's scale factors and misalignments in the gyros (the data of
    check_calibrating_filter with its defaults)."""
    return ex.simulate(P, RUNS, SEED, calibration=True)


# ----------------------------------------------------------------------------- (a) the reference

@pytest.mark.parametrize("sv, su, sn, dt", [(P.sigma_v, P.sigma_u, P.sigma_star, P.dt),
                                            (1e-4, 1e-6, 1e-4, 0.5), (1e-3, 1e-3, 1e-3, 2.0)],
                         ids=["example", "noisier", "bias-dominated"])
def test_farrenkopf_is_the_steady_state_of_the_discrete_riccati_equation(sv, su, sn, dt):
    Phi = np.array([[1.0, -dt], [0.0, 1.0]])
    q12 = -su ** 2 * dt ** 2 / 2
    Q = np.array([[sv ** 2 * dt + su ** 2 * dt ** 3 / 3, q12], [q12, su ** 2 * dt]])
    H, R = np.array([[1.0, 0.0]]), np.array([[sn ** 2]])
    pre = linalg.solve_discrete_are(Phi.T, H.T, Q, R)  # the predicted covariance
    post = pre - pre @ H.T @ np.linalg.solve(H @ pre @ H.T + R, H @ pre)
    f = ex.farrenkopf(sv, su, sn, dt)
    got = np.array([f["att_pre"], f["att_post"], f["bias_pre"], f["bias_post"]])
    want = np.sqrt([pre[0, 0], post[0, 0], pre[1, 1], post[1, 1]])
    assert np.allclose(got, want, rtol=1e-6, atol=0), got / want - 1


@pytest.mark.slow  # ~0.6 s: 20,000 steps of the recursion
def test_the_example_covariance_recursion_converges_to_farrenkopf():
    """The Example's 6-state covariance recursion, with its rate profile, at 90 min: within 0.5 %
    (attitude) and 1 % (bias, still settling; the body turns) of Farrenkopf's single-axis steady
    state. Without rotation, after 2 h: the book's closed-form discretisation (Farrenkopf's model)
    to 1e-5, the script's first-order one to 1e-3 (it leaves out the sigma_u^2 dt^2/2 and dt^3/3
    terms of Q, worth 2.3e-4 on the bias)."""
    t = np.arange(P.steps - 1) * P.dt
    sd = np.sqrt(np.diag(ef.covariance(P, P.rate(t))[-1]))
    assert np.allclose(sd[:3], FK["att_post"], rtol=5e-3, atol=0), sd[:3] / FK["att_post"]
    assert np.allclose(sd[3:], FK["bias_post"], rtol=1e-2, atol=0), sd[3:] / FK["bias_post"]
    for disc, tol in (("closed", 1e-5), ("example", 1e-3)):
        sd = np.sqrt(np.diag(ef.covariance(P, np.zeros((7200, 3)), discretisation=disc)[-1]))
        assert np.allclose(sd, [FK["att_post"]] * 3 + [FK["bias_post"]] * 3, rtol=tol, atol=0), (disc, sd)


@pytest.mark.slow  # ~2 s: the numpy filter, 20 runs batched
def test_the_numpy_6_state_filter_is_consistent(bias_only, numpy_6):
    c = ex.check_consistency(bias_only, numpy_6)
    assert c.sigma3_att == pytest.approx(3 * FK["att_post"], rel=5e-3)
    assert c.sigma3_bias == pytest.approx(3 * FK["bias_post"], rel=1e-2)


# ----------------------------------------------------------------------------- (b) sc-rt's 6 states

@pytest.mark.slow
def test_scrt_covariance_and_estimates_follow_the_example_recursion(numpy_6, scrt_6):
    """Same data, the same propagation (the held sample) and update: sc-rt's covariance within
    2e-3 of each sigma product of the Example's, its estimates within 0.01 sigma of the numpy
    filter's. The two discretise differently (sc-rt: Phi11 = exp(-(w dt)^), Phi12 = -dt I, Q with
    its dt^2 and dt^3 terms; the Example: I + F dt, dt G Q G'), by terms of order |w| dt = 1.7e-3
    at most."""
    ref, got = numpy_6, scrt_6
    sd = np.sqrt(np.diagonal(ref.P, axis1=-2, axis2=-1))
    dP = (got.P - ref.P) / (sd[..., :, None] * sd[..., None, :])
    assert np.abs(dP).max() < 2e-3, np.abs(dP).max()
    d_att = ex.attitude_error(ef.mrp_quat(ref.sigma), got.sigma) / sd[..., :3]
    d_bias = (got.bias - ref.bias) / sd[..., 3:]
    assert np.abs(d_att).max() < 0.01 and np.abs(d_bias).max() < 0.01, (np.abs(d_att).max(), np.abs(d_bias).max())


def test_scrt_6_state_filter_is_consistent_on_the_example(bias_only, scrt_6):
    c = ex.check_consistency(bias_only, scrt_6)  # NEES in its 99 % band at 30, 60, 90 min; >= 99 % within 3 sigma
    assert c.sigma3_att == pytest.approx(3 * FK["att_post"], rel=5e-3)
    assert c.sigma3_bias == pytest.approx(3 * FK["bias_post"], rel=1e-2)


@pytest.mark.slow  # ~0.8 s
def test_scrt_averaging_is_right_for_samples_of_a_smooth_rate_and_half_a_sample_off_for_held_ones(bias_only):
    """sc-rt given one sample per second at its time: consistent when they sample a smooth rate
    (its mean of two samples is then second order), NEES out of its band by orders of magnitude on
    the Example's held rate (the mean of two held samples is half a sample off the held one)."""
    smooth = ex.simulate(P, RUNS, SEED, truth="smooth")
    ex.check_consistency(smooth, ef.scrt_filter("samples")(smooth, K))
    c = ex.consistency(bias_only, ef.scrt_filter("samples")(bias_only, K))
    assert c.nees[-1] > 100 * c.band[1], c.nees[-1]


# ----------------------------------------------------------------------------- (c) scale factors

@pytest.mark.slow  # ~3 s
def test_the_calibrating_check_passes_the_numpy_15_state_filter():
    c = ex.check_calibrating_filter(ef.numpy_filter(15), RUNS, SEED, STRIDE)
    assert c.sigma3_att < 1.05 * 3 * FK["att_post"]  # calibrated: near the 6-state steady state


@pytest.mark.slow  # ~2 s
def test_6_state_filters_are_inconsistent_with_scale_factors_in_the_truth(calibrating):
    """Both the numpy and sc-rt's 6-state filters: the mean NEES far above its band (the attitude
    error tens of times its sigma), and check_calibrating_filter refuses sc-rt's."""
    for run_filter in (ef.numpy_filter(6), ef.scrt_filter("pairs")):
        c = ex.consistency(calibrating, run_filter(calibrating, K))
        assert c.nees[-1] > 100 * c.band[1], c.nees[-1]
        assert c.rms_att > 10 * c.sigma3_att / 3, c.rms_att / (c.sigma3_att / 3)
    with pytest.raises(AssertionError, match="inconsistent filter"):
        ex.check_calibrating_filter(ef.scrt_filter("pairs"), RUNS, SEED, STRIDE)


@pytest.mark.slow  # ~3 s
def test_scrt_calibrating_filter_passes_the_calibrating_check():
    """sc-rt's 15-state filter (``_core.MekfCal``, [controller.estimator]
    calibrate = true) on the Example with its scale factors and
    misalignments: consistent (NEES in its band, errors within 3 sigma) and
    near the numpy reference's 3 sigma."""
    c = ex.check_calibrating_filter(ef.scrt_filter("pairs", calibrating=True), RUNS, SEED, STRIDE)
    ref = ex.check_calibrating_filter(ef.numpy_filter(15), RUNS, SEED, STRIDE)
    assert c.sigma3_att == pytest.approx(ref.sigma3_att, rel=0.02), (c.sigma3_att, ref.sigma3_att)


@pytest.mark.slow  # ~3 s
def test_scrt_calibrating_filter_on_an_integrating_gyro_passes_too():
    """The same data as an integrating gyro's mean rates, delivered at the
    end of each interval (output GYRO_MEAN_RATE): the propagation has no
    half-sample lag and the check passes."""
    run = ef.scrt_filter("increments", calibrating=True, output=_core.GYRO_MEAN_RATE)
    ex.check_calibrating_filter(run, RUNS, SEED, STRIDE)
