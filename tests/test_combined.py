"""The combined-spacecraft builder (docs/MODEL.md section 9) against hand computations."""

from __future__ import annotations

import doctest
import warnings

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.model import combined
from sc_rt.model.combined import (
    CbarWarning,
    RigidBody,
    check_cbar_is_rotation,
    combine,
    fit_rotation,
    parallel_axis,
    principal_axes,
)

S3 = 1.0 / np.sqrt(3.0)
# Service-frame wheel matrix of paper section 4: columns e1, e2, e3, (1,1,1)/sqrt(3).
C_PAPER = np.array([[1.0, 0.0, 0.0, S3], [0.0, 1.0, 0.0, S3], [0.0, 0.0, 1.0, S3]])
# Cbar as printed in paper section 4 (docs/MODEL.md section 8).
CBAR_PAPER = np.array(
    [
        [-0.9992, -0.0300, -0.0256, -0.6086],
        [-0.0394, 0.7455, 0.6653, 0.7913],
        [0.0009, -0.6658, 0.7461, 0.0469],
    ]
)
ZERO = np.zeros((3, 3))
# Rounding only: every inertia below is built from exact small numbers.
TIGHT = 1e-12


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_docstring_examples_run():
    result = doctest.testmod(combined)
    assert result.attempted >= 2 and result.failed == 0


def test_two_bodies_on_an_axis():
    # 3 kg at O_s, 1 kg 4 m away on x: the mass centre is 1 m from O_s; about
    # it, y and z see 3 * 1^2 + 1 * 3^2 = 12 kg m^2 (reduced mass 3/4 * 4^2).
    # Their own small inertias add unchanged.
    own_s, own_t = np.diag([0.1, 0.2, 0.3]), np.diag([0.01, 0.02, 0.03])
    c = combine(RigidBody(3.0, own_s), C_PAPER, RigidBody(1.0, own_t), [4.0, 0.0, 0.0], np.eye(3))
    assert c.mass == 4.0
    np.testing.assert_allclose(c.r_c_S, [1.0, 0.0, 0.0], rtol=0, atol=TIGHT)
    np.testing.assert_allclose(c.J_C, np.diag([0.11, 12.22, 12.33]), rtol=0, atol=TIGHT)


def test_products_of_inertia_off_axis():
    # Two 1 kg points at O_s and at (2, 2, 0): each sits d = +-(1, 1, 0) from
    # the mass centre; m (|d|^2 I - d d') = [[1, -1, 0], [-1, 1, 0], [0, 0, 2]] each.
    c = combine(RigidBody(1.0, ZERO), C_PAPER, RigidBody(1.0, ZERO), [2.0, 2.0, 0.0], np.eye(3))
    np.testing.assert_allclose(c.r_c_S, [1.0, 1.0, 0.0], rtol=0, atol=TIGHT)
    np.testing.assert_allclose(c.J_C, [[2, -2, 0], [-2, 2, 0], [0, 0, 4]], rtol=0, atol=TIGHT)


def test_rotated_target():
    # Target turned +90 deg about x relative to S: R_TS maps S components to
    # T components, so T's y axis is S's z axis and T's z axis is -S's y.
    R_TS = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    np.testing.assert_allclose(_core.mrp_to_dcm([np.tan(np.pi / 8), 0, 0]), R_TS, atol=TIGHT)
    service = RigidBody(2.0, np.diag([1.0, 2.0, 3.0]))
    target = RigidBody(2.0, np.diag([4.0, 5.0, 6.0]))  # in T: in S it is diag(4, 6, 5)
    c = combine(service, C_PAPER, target, [0.0, 0.0, 2.0], R_TS)
    # Mass centre (0, 0, 1): both bodies 1 m from it along z, + 2 kg * 1 m^2 on x and y each.
    np.testing.assert_allclose(c.r_c_S, [0.0, 0.0, 1.0], rtol=0, atol=TIGHT)
    expected = np.diag([1 + 4 + 2 + 2, 2 + 6 + 2 + 2, 3 + 5]).astype(float)
    np.testing.assert_allclose(c.J_C, expected, rtol=0, atol=TIGHT)
    # The target's attitude does not turn the wheels (they are the service's).
    np.testing.assert_array_equal(c.Cbar, C_PAPER)


def test_identity_pose_gives_cbar_equal_to_c():
    service = RigidBody(500.0, np.diag([80.0, 90.0, 100.0]))
    target = RigidBody(200.0, np.diag([20.0, 30.0, 40.0]))
    c = combine(service, C_PAPER, target, [1.0, -0.5, 0.3], np.eye(3))
    np.testing.assert_array_equal(c.Cbar, C_PAPER)
    np.testing.assert_array_equal(c.R_CS, np.eye(3))


@pytest.mark.parametrize("seed", range(20))
def test_random_bodies_give_a_symmetric_positive_definite_inertia(seed):
    rng = np.random.default_rng(seed)

    def body() -> RigidBody:
        moments = rng.uniform(1.0, 50.0, 3)
        moments[2] = rng.uniform(abs(moments[0] - moments[1]), moments[0] + moments[1])
        R = random_rotation(rng)  # a general (non-diagonal) physical inertia
        return RigidBody(rng.uniform(10.0, 1000.0), R.T @ np.diag(moments) @ R)

    service, target = body(), body()
    R_TS = random_rotation(rng)
    r_T_S = rng.normal(size=3) * 3.0
    c = combine(service, C_PAPER, target, r_T_S, R_TS)
    np.testing.assert_array_equal(c.J_C, c.J_C.T)
    moments = np.linalg.eigvalsh(c.J_C)
    assert moments[0] > 0 and moments[0] + moments[1] >= moments[2]
    # Independent check: sum of the parallel-axis terms about the mass centre.
    r_c = target.mass * r_T_S / (service.mass + target.mass)
    J = parallel_axis(service.inertia, service.mass, r_c) + parallel_axis(
        R_TS.T @ target.inertia @ R_TS, target.mass, r_T_S - r_c
    )
    np.testing.assert_allclose(c.J_C, J, rtol=1e-12)
    # Principal frame: diagonal, ascending, same moments, a proper rotation of S.
    p = combine(service, C_PAPER, target, r_T_S, R_TS, frame="principal")
    np.testing.assert_allclose(p.J_C, np.diag(moments), atol=1e-9 * moments[-1])
    np.testing.assert_allclose(p.R_CS @ p.R_CS.T, np.eye(3), atol=TIGHT)
    assert np.linalg.det(p.R_CS) > 0
    np.testing.assert_allclose(p.Cbar, p.R_CS @ C_PAPER, atol=TIGHT)
    np.testing.assert_allclose(p.R_CS.T @ p.J_C @ p.R_CS, c.J_C, rtol=1e-12, atol=1e-12)


def test_principal_axes_orders_and_signs():
    R = principal_axes(np.diag([5.0, 1.0, 3.0]))
    np.testing.assert_array_equal(R, [[0, 1, 0], [0, 0, 1], [1, 0, 0]])


def test_given_frame_rotates_inertia_and_wheels():
    R_CS = _core.mrp_to_dcm([0.1, -0.2, 0.3])
    service, target = RigidBody(2.0, np.diag([1.0, 2.0, 2.5])), RigidBody(1.0, np.diag([1, 1, 1.5]))
    base = combine(service, C_PAPER, target, [0.0, 1.0, 0.0], np.eye(3))
    c = combine(service, C_PAPER, target, [0.0, 1.0, 0.0], np.eye(3), R_CS)
    np.testing.assert_allclose(c.J_C, R_CS @ base.J_C @ R_CS.T, atol=TIGHT)
    np.testing.assert_allclose(c.Cbar, R_CS @ C_PAPER, atol=TIGHT)


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        ({"R_TS": np.diag([1.0, 1.0, -1.0])}, "proper rotation"),  # a reflection
        ({"R_TS": 2.0 * np.eye(3)}, "proper rotation"),
        ({"frame": "body"}, "frame must be"),
        ({"r_T_S": [0.0, np.nan, 0.0]}, "finite 3-vector"),
        ({"target": RigidBody(0.0, ZERO)}, "target.mass must be > 0"),
        ({"C_S": np.eye(3)}, "C_S must be 3x4"),
    ],
)
def test_combine_rejects_bad_input(kwargs, fragment):
    args = {"service": RigidBody(1.0, np.eye(3)), "C_S": C_PAPER,
            "target": RigidBody(1.0, np.eye(3)), "r_T_S": [1.0, 0.0, 0.0],
            "R_TS": np.eye(3)}  # fmt: skip
    with pytest.raises(ValueError, match=fragment):
        combine(**{**args, **kwargs})


def test_paper_cbar_is_not_a_proper_rotation_of_c():
    # Its first three columns, the images of e1, e2, e3, have determinant -1:
    # a mirror image, which no rotation produces (docs/MODEL.md section 9).
    assert np.linalg.det(CBAR_PAPER[:, :3]) == pytest.approx(-0.99993, abs=1e-5)
    with pytest.warns(CbarWarning, match=r"not R C for any proper rotation.*a reflection"):
        ok, R_best, residual = check_cbar_is_rotation(CBAR_PAPER, C_PAPER)
    assert not ok
    assert residual > 1.0  # the best rotation misses some wheel axis by more than 1 (unit axes)
    assert np.linalg.det(R_best) == pytest.approx(1.0, abs=1e-12)
    # A reflection fits to the printed precision: the 4th column is consistent.
    R_mirror, residual_mirror = fit_rotation(CBAR_PAPER, C_PAPER, proper=False)
    assert np.linalg.det(R_mirror) == pytest.approx(-1.0, abs=1e-12)
    assert residual_mirror < 1e-3


def test_check_without_warning_returns_the_same_verdict():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit = check_cbar_is_rotation(CBAR_PAPER, C_PAPER, warn=False)
    assert not fit.is_rotation and fit.residual > 1.0


@pytest.mark.parametrize("seed", range(10))
def test_cbar_from_a_random_rotation_is_accepted(seed):
    R = random_rotation(np.random.default_rng(seed))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no CbarWarning
        ok, R_best, residual = check_cbar_is_rotation(R @ C_PAPER, C_PAPER)
        # Printed to 4 decimals, as the paper prints Cbar: still within the tolerance.
        ok_printed, _, residual_printed = check_cbar_is_rotation(np.round(R @ C_PAPER, 4), C_PAPER)
    assert ok and residual < 1e-12
    np.testing.assert_allclose(R_best, R, atol=1e-12)
    assert ok_printed and residual_printed < 2e-4
