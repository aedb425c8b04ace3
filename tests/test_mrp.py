"""MRP kinematics of the core against independent computations
(quaternions, rotation matrices, finite differences)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sc_rt import _core

import refmath as ref

finite = st.floats(-1.5, 1.5, allow_nan=False)
vec3 = st.tuples(finite, finite, finite).map(np.array)


@settings(max_examples=200, deadline=None)
@given(vec3)
def test_dcm_matches_quaternion_route(s):
    # (10) against the DCM of the equivalent quaternion
    np.testing.assert_allclose(_core.mrp_to_dcm(s), ref.mrp_dcm(s), atol=1e-13)


@settings(max_examples=200, deadline=None)
@given(vec3)
def test_dcm_is_a_proper_rotation(s):
    C = _core.mrp_to_dcm(s)
    np.testing.assert_allclose(C @ C.T, np.eye(3), atol=1e-13)
    assert np.linalg.det(C) == pytest.approx(1.0, abs=1e-13)


def test_skew_is_the_cross_product(rng):
    for _ in range(20):
        x, y = rng.normal(size=3), rng.normal(size=3)
        np.testing.assert_allclose(_core.skew(x) @ y, np.cross(x, y), atol=1e-15)


@settings(max_examples=100, deadline=None)
@given(vec3.filter(lambda s: 1e-3 < np.linalg.norm(s)))
def test_shadow_set_is_the_same_attitude(s):
    sh = _core.mrp_shadow(s)
    np.testing.assert_allclose(_core.mrp_to_dcm(sh), _core.mrp_to_dcm(s), atol=1e-10)
    short = _core.mrp_short(s)
    assert np.linalg.norm(short) <= 1.0 + 1e-15
    np.testing.assert_allclose(_core.mrp_to_dcm(short), _core.mrp_to_dcm(s), atol=1e-10)


def test_G_matches_finite_difference_of_rotation_matrix_propagation(rng):
    # sigma_dot = G(sigma) omega (1),(2): propagate the DCM exactly with
    # C(t+h) = exp(-[w x] h) C(t) and difference the MRP of the result.
    h = 1e-6
    for _ in range(50):
        s = rng.uniform(-0.6, 0.6, 3)
        w = rng.normal(size=3)
        C = ref.mrp_dcm(s)
        sp = ref.dcm_to_mrp(ref.rotation_exp(w, h) @ C)
        sm = ref.dcm_to_mrp(ref.rotation_exp(w, -h) @ C)
        fd = (sp - sm) / (2 * h)
        # central difference: error O(h^2) ~ 1e-12 plus rounding ~ eps/h ~ 1e-10
        np.testing.assert_allclose(_core.mrp_G(s) @ w, fd, atol=2e-9)


def test_G_inverse(rng):
    for _ in range(20):
        s = rng.uniform(-1, 1, 3)
        np.testing.assert_allclose(_core.mrp_G_inverse(s) @ _core.mrp_G(s), np.eye(3), atol=1e-12)


@settings(max_examples=300, deadline=None)
@given(vec3.filter(lambda s: np.linalg.norm(s) <= 1), vec3.filter(lambda s: np.linalg.norm(s) <= 1))
def test_subtraction_matches_rotation_matrices(s, sd):
    # (8): R(sigma_BD) = R(sigma_BN) R(sigma_DN)'
    e = _core.mrp_subtract(s, sd)
    assert np.all(np.isfinite(e))
    assert np.linalg.norm(e) <= 1.0 + 1e-12  # short rotation
    np.testing.assert_allclose(_core.mrp_to_dcm(e), ref.mrp_dcm(s) @ ref.mrp_dcm(sd).T, atol=1e-9)


def test_subtraction_near_the_singular_composition():
    # |s| = |sd| = 1 and antiparallel: the printed (8) divides by zero; the
    # attitude is still well defined (a 2 * 180 deg composition = identity)
    s = np.array([1.0, 0.0, 0.0])
    sd = -s
    e = _core.mrp_subtract(s, sd)
    assert np.all(np.isfinite(e))
    np.testing.assert_allclose(_core.mrp_to_dcm(e), ref.mrp_dcm(s) @ ref.mrp_dcm(sd).T, atol=1e-9)


def test_subtraction_of_equal_attitudes_is_zero(rng):
    for _ in range(10):
        s = rng.uniform(-0.5, 0.5, 3)
        np.testing.assert_allclose(_core.mrp_subtract(s, s), 0.0, atol=1e-15)
        # and with the shadow set of one side: the same attitude
        np.testing.assert_allclose(_core.mrp_subtract(_core.mrp_shadow(s), s), 0.0, atol=1e-12)
