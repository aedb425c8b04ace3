"""Prescribed-performance transform (29)-(35)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sc_rt import _core

P = _core.PpcParams()  # Table 1


def test_chi_matches_29_and_its_derivative():
    for t in [0.0, 1.0, 10.0, 100.0, 300.0]:
        expected = (np.array(P.chi0) - P.chiinf) * np.exp(-np.array(P.gamma) * t) + P.chiinf
        np.testing.assert_allclose(_core.ppc_chi(P, t), expected, rtol=1e-15)
        h = 1e-4
        fd = (_core.ppc_chi(P, t + h) - _core.ppc_chi(P, t - h)) / (2 * h) if t > 0 else None
        if fd is not None:
            np.testing.assert_allclose(_core.ppc_chi_dot(P, t), fd, rtol=1e-7, atol=1e-15)


def test_zero_error_gives_zero_e1():
    # (36): e1 = eps - 1/2 ln(dmin/dmax) vanishes at x1 = 0 even for dmin != dmax
    for t in [0.0, 50.0]:
        r = _core.ppc_transform(P, np.zeros(3), t)
        np.testing.assert_allclose(r.e1, 0.0, atol=1e-15)
        assert r.violated == 0


def test_inverse_round_trip(rng):
    for _ in range(200):
        t = rng.uniform(0, 300)
        chi = _core.ppc_chi(P, t)
        lam = rng.uniform(-np.array(P.dmin), np.array(P.dmax)) * 0.999
        x1 = lam * chi
        r = _core.ppc_transform(P, x1, t)
        assert r.violated == 0
        np.testing.assert_allclose(_core.ppc_inverse(P, r.e1, t), x1, rtol=1e-9, atol=1e-18)


def test_r_is_the_derivative_of_eps(rng):
    # (35): d eps / d x1 = r (element-wise), by central differences
    for _ in range(100):
        t = rng.uniform(0, 100)
        chi = _core.ppc_chi(P, t)
        x1 = rng.uniform(-np.array(P.dmin), np.array(P.dmax)) * 0.9 * chi
        h = 1e-7 * chi
        fd = (_core.ppc_transform(P, x1 + h, t).eps - _core.ppc_transform(P, x1 - h, t).eps) / (2 * h)
        np.testing.assert_allclose(_core.ppc_transform(P, x1, t).r, fd, rtol=1e-5)


def test_e1_dot_matches_35_along_a_trajectory(rng):
    # e1_dot = r (x1_dot - Lambda chi_dot) for x1(t) moving inside the funnel
    t = 3.0
    chi = _core.ppc_chi(P, t)
    x1 = 0.3 * chi * np.array([1, -1, 0.5])
    x1dot = np.array([1e-3, -2e-3, 5e-4])
    h = 1e-5
    e1p = _core.ppc_transform(P, x1 + h * x1dot, t + h).e1
    e1m = _core.ppc_transform(P, x1 - h * x1dot, t - h).e1
    q = _core.ppc_transform(P, x1, t)
    np.testing.assert_allclose(q.r * (x1dot - q.lambda_ * q.chi_dot), (e1p - e1m) / (2 * h), rtol=1e-6)


def test_outside_the_bound_clamps_and_flags():
    t = 10.0
    chi = _core.ppc_chi(P, t)
    x1 = np.array([2.0 * P.dmax[0] * chi[0], -5.0 * P.dmin[1] * chi[1], 0.0])
    r = _core.ppc_transform(P, x1, t)
    assert r.violated == 0b011
    assert -P.dmin[0] < r.lambda_[0] < P.dmax[0] and r.lambda_[0] > 0.999 * P.dmax[0]
    assert -P.dmin[1] < r.lambda_[1] < P.dmax[1] and r.lambda_[1] < -0.999 * P.dmin[1]
    assert np.all(np.isfinite([r.eps, r.e1, r.r]))


def test_on_the_bound_is_a_violation():
    chi = _core.ppc_chi(P, 0.0)
    r = _core.ppc_transform(P, np.array([P.dmax[0] * chi[0], 0, 0]), 0.0)
    assert r.violated == 0b001


@settings(max_examples=500, deadline=None)
@given(
    st.tuples(*[st.floats(-1e300, 1e300, allow_nan=False)] * 3),
    st.floats(0, 1e6, allow_nan=False),
)
def test_never_nan_for_finite_input(x1, t):
    r = _core.ppc_transform(P, np.array(x1), t)
    for v in (r.lambda_, r.eps, r.e1, r.r, r.chi):
        assert np.all(np.isfinite(v))


def test_nan_input_is_flagged_not_propagated():
    r = _core.ppc_transform(P, np.array([np.nan, 0.0, 0.0]), 1.0)
    assert r.violated & 1
    assert np.all(np.isfinite(r.e1)) and np.all(np.isfinite(r.r))


@pytest.mark.parametrize(
    "field, value, fragment",
    [("chiinf", [0.0, 1e-6, 1e-6], "chiinf of axis 1 must be > 0"),
     ("chi0", [1e-7, 0.14, 0.2], "chi0 of axis 1 must be >= chiinf"),
     ("dmin", [0.7, -1.0, 1.0], "dmin of axis 2 must be > 0"),
     ("gamma", [0.1, 0.1, -0.1], "gamma of axis 3 must be >= 0")],
)
def test_validation_names_the_bad_value(field, value, fragment):
    p = _core.PpcParams()
    setattr(p, field, np.array(value))
    errs = _core.validate(p)
    assert any(fragment in e for e in errs), errs


def test_vectorised_envelope_equals_the_cores():
    """results.judge.metrics.prescribed_chi (numpy over all rows, used by the bound
    check and the figures) is the core's chi(t) (29) at every sample."""
    from sc_rt.results.judge.metrics import prescribed_chi
    from sc_rt.scenario.reader import load_scenario

    scn = load_scenario("paper_faults")
    p = scn.core_config().ppc
    t = np.concatenate([[0.0], np.random.default_rng(7).uniform(0.0, 400.0, 200)])
    got = prescribed_chi(scn.controller.ppc, t)
    want = np.array([np.asarray(_core.ppc_chi(p, float(tk))) for tk in t])
    np.testing.assert_allclose(got, want, rtol=1e-14, atol=0)
