"""The plant (docs/MODEL.md section 1), Python reference and C++ engine.

Independent checks: scipy's rotations for the attitude (DCM, nadir), a numpy
re-implementation of (7) integrated by scipy's DOP853, conservation laws, and
hand-computed values. The C++ engine is held to the Python one.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from sc_rt import _core
from sc_rt.model.actuators import ActuatorParams, WheelFault, actuator_params_to_cpp, wheel_accel
from sc_rt.model.plant import (
    derivative,
    disturbance,
    lumped_disturbance,
    omega_dot,
    plant_params_to_cpp,
    rk4_step,
    total_angular_momentum_N,
)
from sc_rt.model.plant_params import DisturbanceParams, PlantParams

CBAR_PAPER = np.array(
    [
        [-0.9992, -0.0300, -0.0256, -0.6086],
        [-0.0394, 0.7455, 0.6653, 0.7913],
        [0.0009, -0.6658, 0.7461, 0.0469],
    ]
)
C_SERVICE = np.c_[np.eye(3), np.ones(3) / math.sqrt(3.0)]  # columns e1, e2, e3, (1,1,1)/sqrt 3
J0_PAPER = np.diag([10.0, 15.0, 20.0])
DJ_PAPER = np.diag([2.0, -1.0, 2.0])
NO_DIST = DisturbanceParams(amp=np.zeros(3), freq=np.zeros(3), bias=np.zeros(3))
PAPER_FAULTS = (  # Section 4.2, with the errata's wheel numbering (0-based here)
    WheelFault(wheel=0, effectiveness=0.5, bias=0.3, onset=5.0),
    WheelFault(wheel=1, effectiveness=0.5, onset=10.0),
    WheelFault(wheel=2, bias=-0.3, onset=5.0, end=15.0),
)
X0_PAPER = np.r_[[0.323, -0.194, -0.388], [-0.01, 0.02, -0.03], np.zeros(4)]


def paper_plant(**kw) -> PlantParams:
    args = dict(J0=J0_PAPER, dJ=DJ_PAPER, Cbar=CBAR_PAPER, Jw=np.full(4, 0.338), w0=0.0011)
    args.update(kw)
    return PlantParams(**args)


def paper_actuators(**kw) -> ActuatorParams:
    args = dict(umin=np.full(4, -7.0), umax=np.full(4, 10.0))
    args.update(kw)
    return ActuatorParams(**args)


def random_state(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    sigma = v / np.linalg.norm(v) * rng.uniform(0.0, 0.95)
    return np.r_[sigma, rng.normal(0.0, 0.3, 3), rng.uniform(-150.0, 150.0, 4)]


# --- independent formulations used by the tests ------------------------------


def dcm_BN(sigma) -> np.ndarray:
    """[BN] from scipy: its MRP rotation is the active rotation [NB]."""
    return Rotation.from_mrp(sigma).as_matrix().T


def mrp_from_dcm_BN(BN) -> np.ndarray:
    return Rotation.from_matrix(BN.T).as_mrp()  # scipy returns the short set


def gravity_gradient_ref(J, sigma, w0) -> np.ndarray:
    """3 w0^2 n x (J n), n = nadir (orbit e3) in B, from scipy's rotation."""
    n = dcm_BN(sigma)[:, 2]
    return 3.0 * w0**2 * np.cross(n, J @ n)


def ref_rhs(p: PlantParams, act: ActuatorParams, u_cmd):
    """A numpy/scipy re-implementation of (1),(2),(7),(15),(16) for solve_ivp.

    No wheel-speed limit: the tests using it stay below any limit.
    """
    J = p.J0 + p.dJ
    CJ = p.Cbar * p.Jw
    d = p.disturbance

    def f(t, x):
        s, w, Om = x[0:3], x[3:6], x[6:10]
        # (2) in matrix form; test_kinematics_match_dcm_propagation checks (2)
        # itself against a DCM propagated by scipy
        ss = s @ s
        S = np.array([[0, -s[2], s[1]], [s[2], 0, -s[0]], [-s[1], s[0], 0]])
        sd = 0.25 * ((1 - ss) * np.eye(3) + 2 * S + 2 * np.outer(s, s)) @ w
        acc = np.clip(u_cmd, act.umin, act.umax)
        for flt in act.faults:
            if flt.onset <= t < (flt.end if flt.end is not None else np.inf):
                Y = 1.0 - math.exp(-flt.rate * (t - flt.onset))
                i = flt.wheel
                acc[i] = (
                    0.0 if flt.stuck else acc[i] + Y * ((flt.effectiveness - 1) * acc[i] + flt.bias)
                )
        tau = (
            -np.cross(w, J @ w + CJ @ Om)
            - CJ @ acc
            + gravity_gradient_ref(J, s, p.w0)
            + d.bias
            + d.amp * np.cos(d.freq * t)
        )
        return np.r_[sd, np.linalg.solve(J, tau), acc]

    return f


def cpp_step(pc, ac, t, x, h, u):
    return _core.plant_rk4_step(
        pc, ac, t, _core.PlantState.from_vector(x), h, np.asarray(u, float)
    ).to_vector()


def cpp_derivative(pc, t, x, a):
    return _core.plant_derivative(
        pc, t, _core.PlantState.from_vector(x), np.asarray(a, float)
    ).to_vector()


def assert_blocks_close(a, b, rtol, what=""):
    """Norm-wise relative agreement per block (sigma, omega, wheels)."""
    for sl in (slice(0, 3), slice(3, 6), slice(6, 10)):
        scale = max(np.linalg.norm(b[sl]), 1e-300)
        err = np.linalg.norm(a[sl] - b[sl])
        assert err <= rtol * scale, f"{what} block {sl}: |diff| = {err:.3e}, |ref| = {scale:.3e}"


# --- disturbance ---------------------------------------------------------------


def test_disturbance_is_the_papers_by_hand():
    p = paper_plant()
    for t in (0.0, 17.3, 250.0):
        expected = 1e-3 * np.array(
            [5 * math.cos(0.02 * t), -5 * math.cos(0.025 * t), 6 * math.cos(0.04 * t)]
        )
        np.testing.assert_allclose(disturbance(p, t), expected, rtol=1e-15, atol=1e-18)
        np.testing.assert_allclose(
            _core.disturbance(plant_params_to_cpp(p), t), expected, rtol=1e-15, atol=1e-18
        )
    q = paper_plant(
        disturbance=DisturbanceParams(amp=[1.0, 0, 0], freq=[0.5, 0, 0], bias=[0.1, 0.2, -0.3])
    )
    np.testing.assert_allclose(disturbance(q, 2.0), [0.1 + math.cos(1.0), 0.2, -0.3], rtol=1e-15)


# --- kinematics ------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(5))
def test_kinematics_match_dcm_propagation(seed):
    # sigma_dot of the derivative against a central difference of the
    # attitude propagated as a DCM: [BN](t + dt) = exp(-w^ dt) [BN](t).
    rng = np.random.default_rng(seed)
    p = paper_plant()
    x = random_state(rng)
    sigma, w = x[0:3], x[3:6]
    dt = 1e-5
    BN = dcm_BN(sigma)
    step = Rotation.from_rotvec(w * dt).as_matrix().T  # exp(-w^ dt)
    s_plus = mrp_from_dcm_BN(step @ BN)
    s_minus = mrp_from_dcm_BN(step.T @ BN)
    fd = (s_plus - s_minus) / (2 * dt)
    # central difference error ~ dt^2 |sigma'''| ~ 1e-10, rounding ~ 1e-16/dt = 1e-11
    np.testing.assert_allclose(derivative(0.0, x, np.zeros(4), p)[0:3], fd, rtol=0, atol=1e-8)
    np.testing.assert_allclose(
        cpp_derivative(plant_params_to_cpp(p), 0.0, x, np.zeros(4))[0:3], fd, rtol=0, atol=1e-8
    )


def test_wheel_block_of_the_derivative_is_the_acceleration():
    p = paper_plant()
    a = np.array([1.5, -2.0, 0.25, 7.0])
    np.testing.assert_array_equal(derivative(3.0, X0_PAPER, a, p)[6:10], a)


# --- gravity gradient --------------------------------------------------------------


@pytest.mark.parametrize("seed", range(5))
def test_gravity_gradient_against_scipy_nadir(seed):
    # No rate, no wheels, no d: J omega_dot = u_g exactly.
    rng = np.random.default_rng(100 + seed)
    p = paper_plant(
        dJ=np.array([[2.0, 0.3, -0.2], [0.3, -1.0, 0.4], [-0.2, 0.4, 2.0]]),
        w0=0.0011,
        disturbance=NO_DIST,
    )
    x = random_state(rng)
    x[3:10] = 0.0
    u_g = gravity_gradient_ref(p.J, x[0:3], p.w0)
    np.testing.assert_allclose(p.J @ omega_dot(0.0, x, np.zeros(4), p), u_g, rtol=1e-12, atol=1e-20)
    wd_cpp = cpp_derivative(plant_params_to_cpp(p), 0.0, x, np.zeros(4))[3:6]
    np.testing.assert_allclose(p.J @ wd_cpp, u_g, rtol=1e-12, atol=1e-20)


def test_gravity_gradient_by_hand_roll_about_x():
    # Rotation by theta about x: nadir n = (0, sin, cos) in B, so
    # u_g = 3 w0^2 (Jz - Jy) sin(theta) cos(theta) about x (J = diag(12, 14, 22)).
    p = paper_plant(w0=0.002, disturbance=NO_DIST)
    theta = 0.7
    x = np.zeros(10)
    x[0] = math.tan(theta / 4)  # MRP of a rotation about e1
    wd = omega_dot(0.0, x, np.zeros(4), p)
    expected_x = 3 * 0.002**2 * (22 - 14) * math.sin(theta) * math.cos(theta) / 12
    np.testing.assert_allclose(wd, [expected_x, 0.0, 0.0], rtol=1e-13, atol=1e-22)


# --- conservation laws and energy ------------------------------------------------------


def _spin_command(t):
    """A command that spins the wheels up and down (within the limits)."""
    return np.array(
        [
            3 * math.sin(0.05 * t),
            -2 * math.cos(0.031 * t),
            4 * math.sin(0.11 * t + 1.0),
            1.5 * math.cos(0.07 * t),
        ]
    )


def _momentum_drift(p, step, h, T=200.0):
    """Max |H_N(t) - H_N(0)| / |H_N(0)| over T seconds of steps of h."""
    # Mostly null-space motion (Cbar n = 0): the wheels swing through +-170
    # rad/s while the body keeps moderate rates (the faults and the small
    # torque part still exchange momentum with it).
    n = np.linalg.svd(p.Cbar)[2][-1]
    n /= np.abs(n).max()
    x = np.r_[[0.3, -0.2, 0.1], [0.05, -0.02, 0.03], [10.0, -5.0, 0.0, 20.0]]
    H0 = total_angular_momentum_N(x, p)
    drift, wheel_max, rate_max = 0.0, 0.0, 0.0
    for k in range(round(T / h)):
        t = k * h
        u = 3.0 * math.sin(0.04 * t) * n + 0.05 * _spin_command(t)
        x = step(t, x, h, u)
        drift = max(drift, np.linalg.norm(total_angular_momentum_N(x, p) - H0))
        wheel_max = max(wheel_max, np.abs(x[6:10]).max())
        rate_max = max(rate_max, np.abs(x[3:6]).max())
    return drift / np.linalg.norm(H0), wheel_max, rate_max


@pytest.mark.parametrize("engine", ["python", "cpp"])
def test_total_momentum_conserved_without_external_torque(engine):
    # w0 = 0 and d = 0: (7) conserves H_N = R' (J omega + Cbar Jw Omega_w)
    # exactly, faults included (a wheel's bias, loss of effectiveness or
    # sticking is an internal torque). RK4 conserves it up to its truncation
    # error. With ~57 N m s in the wheels (170 rad/s) the body nutates at
    # |h_w|/J ~ 4 rad/s, i.e. ~0.4 rad per 0.1 s step, so that error is
    # ~2e-7 of |H_N| here (bound 1e-6). Halving h must shrink it ~2^4: that
    # shows the drift is RK4 truncation, while a wrong or missing term in (7)
    # would break conservation at O(1), independent of h.
    faults = (
        WheelFault(wheel=0, effectiveness=0.8, bias=0.01, onset=20.0),
        WheelFault(wheel=2, stuck=True, onset=100.0, end=102.0),
    )
    p = paper_plant(
        w0=0.0,
        disturbance=NO_DIST,
        dJ=np.array([[2.0, 0.5, 0.0], [0.5, -1.0, 0.3], [0.0, 0.3, 2.0]]),
    )
    act = paper_actuators(faults=faults)
    if engine == "python":
        step = lambda t, x, h, u: rk4_step(p, act, t, x, h, u)  # noqa: E731
    else:
        pc, ac = plant_params_to_cpp(p), actuator_params_to_cpp(act)
        step = lambda t, x, h, u: cpp_step(pc, ac, t, x, h, u)  # noqa: E731
    rel1, wheel_max, rate_max = _momentum_drift(p, step, 0.1)
    assert wheel_max > 100.0, "the wheels must actually spin up for this test to mean anything"
    assert 0.1 < rate_max < 1.0  # and the body moves, at moderate rates
    assert rel1 < 1e-6, rel1
    rel2, _, _ = _momentum_drift(p, step, 0.05)
    assert 12.0 < rel1 / rel2 < 24.0, (rel1, rel2)  # measured ~16.4


@pytest.mark.parametrize("seed", range(5))
def test_energy_and_momentum_rates(seed):
    # d/dt (1/2 w'Jw) = -w' Cbar Jw Omega_dot + w'(u_g + d): the gyroscopic
    # term -w^ H does no work. d/dt H_N = R' (u_g + d): only external torques
    # change the total momentum (finite difference along the flow).
    rng = np.random.default_rng(200 + seed)
    p = paper_plant(
        w0=0.05,
        disturbance=DisturbanceParams(
            amp=[0.01, -0.02, 0.015], freq=[0.3, 0.2, 0.1], bias=[1e-3, 0, -2e-3]
        ),
    )
    x = random_state(rng)
    a = rng.uniform(-5, 5, 4)
    t = rng.uniform(0, 100)
    J, CJ = p.J, p.Cbar * p.Jw
    f = derivative(t, x, a, p)
    w, wd = x[3:6], f[3:6]
    ext = gravity_gradient_ref(J, x[0:3], p.w0) + disturbance(p, t)
    power_lhs = w @ J @ wd
    power_rhs = -w @ CJ @ a + w @ ext
    scale = np.abs(w) @ (np.abs(J) @ np.abs(wd)) + np.abs(w) @ np.abs(CJ) @ np.abs(a)
    assert abs(power_lhs - power_rhs) <= 1e-13 * scale
    eps = 1e-6
    dH = (total_angular_momentum_N(x + eps * f, p) - total_angular_momentum_N(x - eps * f, p)) / (
        2 * eps
    )
    expected = dcm_BN(x[0:3]).T @ ext
    # finite-difference error ~ eps^2 |H'''| plus rounding |H|/eps ~ 1e-14/1e-6
    np.testing.assert_allclose(
        dH, expected, rtol=0, atol=1e-6 * np.linalg.norm(total_angular_momentum_N(x, p))
    )


def test_torque_free_constant_wheels_keep_energy_and_momentum_norm():
    # Zero command, no external torque: the wheel speeds stay exactly
    # constant and (7) conserves the body's kinetic energy 1/2 w'Jw and |H_B|.
    # RK4 drifts by its truncation error: the wheels' 10 N m s make the body
    # nutate at ~1 rad/s (0.1 rad per step), measured 1.4e-6 (energy) and
    # 2.6e-7 (|H|) over 100 s; halving h must shrink both by >= 2^4.
    p = paper_plant(w0=0.0, disturbance=NO_DIST)
    act = paper_actuators()
    J, CJ = p.J, p.Cbar * p.Jw

    def drifts(h):
        x = np.r_[[0.1, 0.2, -0.3], [0.3, -0.2, 0.25], [30.0, -10.0, 5.0, 0.0]]
        E0, H0 = 0.5 * x[3:6] @ J @ x[3:6], np.linalg.norm(J @ x[3:6] + CJ @ x[6:10])
        dE = dH = 0.0
        for k in range(round(100.0 / h)):
            x = rk4_step(p, act, h * k, x, h, np.zeros(4))
            dE = max(dE, abs(0.5 * x[3:6] @ J @ x[3:6] - E0) / E0)
            dH = max(dH, abs(np.linalg.norm(J @ x[3:6] + CJ @ x[6:10]) - H0) / H0)
        np.testing.assert_array_equal(x[6:10], [30.0, -10.0, 5.0, 0.0])
        return dE, dH

    dE1, dH1 = drifts(0.1)
    assert dE1 < 5e-6 and dH1 < 1e-6, (dE1, dH1)
    dE2, dH2 = drifts(0.05)
    assert dE1 / dE2 > 16.0 and dH1 / dH2 > 16.0, (dE1, dE2, dH1, dH2)


def test_total_angular_momentum_by_hand():
    p = paper_plant(Cbar=C_SERVICE)
    x = np.r_[[0, 0, 0], [0.1, 0.2, 0.3], [1.0, 2.0, 3.0, math.sqrt(3.0)]]
    # sigma = 0: H_N = J w + Cbar Jw Omega = (1.2, 2.8, 6.6) + 0.338 (2, 3, 4)
    np.testing.assert_allclose(
        total_angular_momentum_N(x, p), [1.2 + 0.676, 2.8 + 1.014, 6.6 + 1.352], rtol=1e-14
    )
    # rotate the body by 90 deg about z (MRP tan(pi/8) e3): [BN] e_x = ... H_N = [NB] H_B
    x[0:3] = [0, 0, math.tan(math.pi / 8)]
    H_B = np.array([1.876, 3.814, 7.952])
    np.testing.assert_allclose(
        total_angular_momentum_N(x, p), [-H_B[1], H_B[0], H_B[2]], rtol=1e-14
    )


# --- the RK4 step --------------------------------------------------------------------------


@pytest.mark.parametrize("engine", ["python", "cpp"])
def test_rk4_against_independent_dop853(engine):
    # 10 s of the paper's faulty plant with a piecewise-constant command,
    # against a numpy re-implementation integrated by DOP853 (rtol 1e-12) with
    # the same zero-order hold. The window [20, 30] s has no fault onset/end,
    # so the right-hand side is smooth within each hold. The body turns at
    # ~0.7 rad/s with ~20 N m s in the wheels; RK4's error is then ~4e-6
    # (bound 1e-5), and two half steps per hold must cut it ~2^4, which shows
    # the two models are the same and the difference is RK4 truncation.
    p = paper_plant()
    act = paper_actuators(faults=PAPER_FAULTS)
    pc, ac = plant_params_to_cpp(p), actuator_params_to_cpp(act)
    x0 = np.r_[[0.3, -0.2, -0.35], [0.05, -0.1, 0.08], [20.0, -30.0, 10.0, 5.0]]
    h = 0.1
    holds = [(20.0 + k * h, _spin_command(20.0 + k * h) * 2.0) for k in range(100)]
    x_ref = x0
    for t, u in holds:
        sol = solve_ivp(
            ref_rhs(p, act, u), (t, t + h), x_ref, method="DOP853", rtol=1e-12, atol=1e-14
        )
        x_ref = sol.y[:, -1]

    def errors(nsub):
        x, hs = x0, h / nsub
        for t, u in holds:
            for j in range(nsub):
                ts = t + j * hs
                x = (
                    rk4_step(p, act, ts, x, hs, u)
                    if engine == "python"
                    else cpp_step(pc, ac, ts, x, hs, u)
                )
        # the attitude as a DCM: the reference keeps the long MRP set
        return (
            np.abs(dcm_BN(x[0:3]) - dcm_BN(x_ref[0:3])).max(),
            np.abs(x[3:10] - x_ref[3:10]).max() / np.abs(x_ref[3:10]).max(),
        )

    e_att1, e_rest1 = errors(1)
    assert e_att1 < 1e-5 and e_rest1 < 1e-6, (e_att1, e_rest1)
    e_att2, e_rest2 = errors(2)
    assert 12.0 < e_att1 / e_att2 < 24.0, (e_att1, e_att2)
    assert 12.0 < e_rest1 / e_rest2 < 24.0, (e_rest1, e_rest2)


@pytest.mark.parametrize("engine", ["python", "cpp"])
def test_shadow_set_switch_keeps_the_attitude(engine):
    # Start just inside |sigma| = 1 and rotate outwards: the step returns the
    # short set, and it is the same attitude as the unswitched solution.
    p = paper_plant()
    act = paper_actuators()
    sigma = np.array([0.6, -0.5, 0.6])
    sigma *= 0.995 / np.linalg.norm(sigma)
    x = np.r_[sigma, 0.5 * sigma / np.linalg.norm(sigma), np.zeros(4)]
    h = 0.1
    y = (
        rk4_step(p, act, 0.0, x, h, np.zeros(4))
        if engine == "python"
        else cpp_step(plant_params_to_cpp(p), actuator_params_to_cpp(act), 0.0, x, h, np.zeros(4))
    )
    sol = solve_ivp(
        ref_rhs(p, act, np.zeros(4)), (0.0, h), x, method="DOP853", rtol=1e-12, atol=1e-14
    )
    s_long = sol.y[0:3, -1]
    assert np.linalg.norm(s_long) > 1.0  # the test does cross the switching surface
    assert np.linalg.norm(y[0:3]) <= 1.0
    np.testing.assert_allclose(y[0:3], -s_long / (s_long @ s_long), rtol=0, atol=1e-9)
    np.testing.assert_allclose(dcm_BN(y[0:3]), dcm_BN(s_long), rtol=0, atol=1e-9)


def test_rk4_step_accepts_lists_and_rejects_bad_shapes():
    p, act = paper_plant(), paper_actuators()
    a = rk4_step(p, act, 0.0, X0_PAPER.tolist(), 0.1, [1, 2, 3, 4])
    b = rk4_step(p, act, 0.0, X0_PAPER, 0.1, np.array([1.0, 2.0, 3.0, 4.0]))
    np.testing.assert_array_equal(a, b)
    assert isinstance(a, np.ndarray) and a.shape == (10,) and a.dtype == np.float64
    with pytest.raises(ValueError, match="x must have shape"):
        rk4_step(p, act, 0.0, np.zeros(9), 0.1, np.zeros(4))
    with pytest.raises(ValueError, match="u_cmd must have shape"):
        rk4_step(p, act, 0.0, np.zeros(10), 0.1, np.zeros(3))


# --- lumped disturbance delta_2 ----------------------------------------------------


def test_lumped_disturbance_zero_when_plant_is_the_model():
    # dJ = 0, d = 0, no faults, no saturation (accel = u_sat), same w0: the
    # plant is exactly the controller's model (21).
    p = paper_plant(dJ=np.zeros((3, 3)), disturbance=NO_DIST)
    pc = plant_params_to_cpp(p)
    act = paper_actuators()
    rng = np.random.default_rng(5)
    for _ in range(20):
        x = random_state(rng)
        u_sat, accel, _ = wheel_accel(act, 1.0, rng.uniform(-7, 10, 4), x[6:10])
        scale = np.linalg.norm(omega_dot(1.0, x, accel, p))
        assert np.linalg.norm(lumped_disturbance(p, 1.0, x, u_sat, accel)) <= 1e-14 * scale
        cpp = _core.lumped_disturbance(pc, 1.0, _core.PlantState.from_vector(x), u_sat, accel)
        assert np.linalg.norm(cpp) <= 1e-14 * scale


@pytest.mark.parametrize("engine", ["python", "cpp"])
def test_lumped_disturbance_by_hand(engine):
    def ld(p, t, x, u_sat, accel):
        if engine == "python":
            return lumped_disturbance(p, t, x, u_sat, accel)
        return _core.lumped_disturbance(
            plant_params_to_cpp(p),
            t,
            _core.PlantState.from_vector(x),
            np.asarray(u_sat, float),
            np.asarray(accel, float),
        )

    x0 = np.zeros(10)
    e1 = np.array([1.0, 0, 0, 0])
    # (a) inertia error only: w = 0, Omega = 0, w0 = 0, d = 0, wheel 1 (axis e1)
    #     accelerates at 1 rad/s^2: delta_2 = (J0^-1 - J^-1) Cbar Jw u
    #     = (1/10 - 1/12) 0.338 e1 = 0.338/60 e1.
    p = paper_plant(Cbar=C_SERVICE, w0=0.0, disturbance=NO_DIST)
    np.testing.assert_allclose(ld(p, 0.0, x0, e1, e1), [0.338 / 60, 0, 0], rtol=1e-14, atol=1e-18)
    # (b) a bias fault on wheel 4 (axis (1,1,1)/sqrt 3) with J exact:
    #     delta_2 = -J0^-1 Cbar Jw (accel - u_sat) = -0.338 * 0.3 Y / sqrt 3 (1/10, 1/15, 1/20).
    p = paper_plant(Cbar=C_SERVICE, dJ=np.zeros((3, 3)), w0=0.0, disturbance=NO_DIST)
    Y = 1 - math.exp(-2.0)
    accel = np.array([0, 0, 0, 0.3 * Y])
    expected = -0.338 * 0.3 * Y / math.sqrt(3) * np.array([1 / 10, 1 / 15, 1 / 20])
    np.testing.assert_allclose(ld(p, 0.0, x0, np.zeros(4), accel), expected, rtol=1e-14)
    # (c) the disturbance only: delta_2 = J0^-1 d(t)
    p = paper_plant(dJ=np.zeros((3, 3)), w0=0.0)
    t = 40.0
    d = 1e-3 * np.array([5 * math.cos(0.8), -5 * math.cos(1.0), 6 * math.cos(1.6)])
    np.testing.assert_allclose(ld(p, t, x0, np.zeros(4), np.zeros(4)), d / [10, 15, 20], rtol=1e-13)
    # (d) gravity gradient with the inertia error, rotation theta about x:
    #     delta_2_x = 3 w0^2 sin cos [(Jz - Jy)/Jx - (J0z - J0y)/J0x] = 3 w0^2 sin cos (8/12 - 5/10)
    p = paper_plant(disturbance=NO_DIST, w0=0.0011)
    th = 1.1
    x = x0.copy()
    x[0] = math.tan(th / 4)
    expected_x = 3 * 0.0011**2 * math.sin(th) * math.cos(th) * (8 / 12 - 5 / 10)
    np.testing.assert_allclose(
        ld(p, 0.0, x, np.zeros(4), np.zeros(4)), [expected_x, 0, 0], rtol=1e-12, atol=1e-22
    )
    # (e) gyroscopic inertia error: w = (0, 0.1, 0.2), no wheels, J = diag(12, 14, 22):
    #     x: -(Jz - Jy) wy wz / Jx + (J0z - J0y) wy wz / J0x = 0.02 (-8/12 + 5/10)
    p = paper_plant(disturbance=NO_DIST, w0=0.0)
    x = x0.copy()
    x[3:6] = [0.0, 0.1, 0.2]
    np.testing.assert_allclose(
        ld(p, 0.0, x, np.zeros(4), np.zeros(4)),
        [0.02 * (-8 / 12 + 5 / 10), 0, 0],
        rtol=1e-13,
        atol=1e-18,
    )


# --- Python and C++ engines agree ------------------------------------------------------


def _random_setup(seed):
    rng = np.random.default_rng(seed)
    dJ = rng.normal(0, 0.5, (3, 3))
    p = paper_plant(
        dJ=0.5 * (dJ + dJ.T),
        w0=rng.uniform(0, 0.01),
        disturbance=DisturbanceParams(
            amp=rng.normal(0, 0.01, 3), freq=rng.uniform(0, 0.1, 3), bias=rng.normal(0, 1e-3, 3)
        ),
    )
    faults = (
        WheelFault(
            wheel=0,
            effectiveness=rng.uniform(),
            bias=rng.normal(0, 0.3),
            onset=rng.uniform(0, 50),
            rate=rng.uniform(0.1, 3),
        ),
        WheelFault(wheel=2, stuck=True, onset=rng.uniform(0, 50), end=rng.uniform(60, 100)),
        WheelFault(
            wheel=3,
            effectiveness=rng.uniform(),
            onset=rng.uniform(0, 50),
            end=rng.uniform(60, 100),
            rate=rng.uniform(0.1, 3),
        ),
    )
    act = paper_actuators(
        umin=-rng.uniform(1, 8, 4),
        umax=rng.uniform(1, 8, 4),
        max_wheel_speed=rng.uniform(50, 200, 4),
        faults=faults,
    )
    return rng, p, act


# The C++ twin repeats the Python plant's scalar operations in the same order
# (cpp/src/plant.cpp): the two are held BIT-IDENTICAL, not just close. In a
# closed loop the observer's |e|^alpha term would amplify any last-bit
# difference (tests/test_sim.py::test_python_and_cpp_engines_agree).


def assert_bits(py, cpp, what):
    py, cpp = np.asarray(py), np.asarray(cpp)
    if not np.array_equal(py, cpp, equal_nan=True):
        diff = np.flatnonzero(~((py == cpp) | (np.isnan(py) & np.isnan(cpp))))
        pytest.fail(
            f"{what}: Python and C++ differ in elements {diff.tolist()}: "
            f"{py.ravel()[diff].tolist()!r} vs {cpp.ravel()[diff].tolist()!r} "
            f"(difference {(py.ravel()[diff] - cpp.ravel()[diff]).tolist()!r})"
        )


def assert_engines_bit_identical(p, act, t, x, u, h=0.1):
    """Every public plant function, Python against C++, to the last bit.

    Returns (the Python rk4 step, the Python wheel_accel output).
    """
    pc, ac = plant_params_to_cpp(p), actuator_params_to_cpp(act)
    xs = _core.PlantState.from_vector(x)
    py = wheel_accel(act, t, u, x[6:10])
    cp = _core.wheel_accel(ac, t, u, x[6:10])
    assert_bits(py[0], cp.u_sat, f"wheel_accel u_sat at t={t!r}")
    assert_bits(py[1], cp.accel, f"wheel_accel accel at t={t!r}")
    assert_bits(py[2], cp.Y, f"wheel_accel Y at t={t!r}")
    assert_bits(disturbance(p, t), _core.disturbance(pc, t), f"disturbance at t={t!r}")
    assert_bits(
        derivative(t, x, py[1], p),
        _core.plant_derivative(pc, t, xs, cp.accel).to_vector(),
        f"derivative at t={t!r}",
    )
    assert_bits(
        lumped_disturbance(p, t, x, py[0], py[1]),
        _core.lumped_disturbance(pc, t, xs, cp.u_sat, cp.accel),
        f"lumped_disturbance at t={t!r}",
    )
    step = rk4_step(p, act, t, x, h, u)
    assert_bits(step, _core.plant_rk4_step(pc, ac, t, xs, h, u).to_vector(), f"rk4_step at t={t!r}")
    return step, py


def _fault_set(name, rng):
    """(PlantParams, ActuatorParams, wheel-speed limit or None) of a named case."""
    if name == "fault_free":
        return paper_plant(), paper_actuators(), None
    if name == "paper_faults":
        return paper_plant(), paper_actuators(faults=PAPER_FAULTS), None
    if name == "paper_faults_stuck_limit":
        faults = PAPER_FAULTS + (WheelFault(wheel=3, stuck=True, onset=5.0, end=15.0),)
        wmax = np.array([60.0, 90.0, 120.0, 75.0])
        return paper_plant(), paper_actuators(max_wheel_speed=wmax, faults=faults), wmax
    if name == "random":  # full inertia, random d(t) and w0, random faults and limits
        _, p, act = _random_setup(int(rng.integers(1 << 30)))
        return p, act, act.max_wheel_speed
    if name == "no_gravity_no_disturbance":  # the constant-d and k = 0 branches
        return (
            paper_plant(
                w0=0.0, disturbance=DisturbanceParams(amp=np.zeros(3), bias=[1e-3, 0.0, -2e-3])
            ),
            paper_actuators(faults=(WheelFault(wheel=1, stuck=True, onset=2.0),)),
            None,
        )
    raise AssertionError(name)


FAULT_SETS = (
    "fault_free",
    "paper_faults",
    "paper_faults_stuck_limit",
    "random",
    "no_gravity_no_disturbance",
)


@pytest.mark.parametrize("case", FAULT_SETS)
def test_python_and_cpp_are_bit_identical_on_random_inputs(case):
    rng = np.random.default_rng(1000 + FAULT_SETS.index(case))
    h = 0.1
    limited = shadowed = 0
    for n in range(80):
        p, act, wmax = _fault_set(case, rng)
        x = random_state(rng)
        if n % 4 == 1:
            # near |sigma| = 1, spinning outward: the step maps to the shadow set
            x[0:3] *= 0.995 / np.linalg.norm(x[0:3])
            x[3:6] = x[0:3] * rng.uniform(1.0, 3.0) + rng.normal(0, 0.05, 3)
        if wmax is not None and n % 2 == 0:
            # wheels at or beyond their limits, commanded further out
            sign = rng.choice([-1.0, 1.0], 4)
            x[6:10] = sign * np.where(np.isfinite(wmax), wmax, 100.0) * rng.uniform(0.98, 1.05, 4)
            u = sign * rng.uniform(0.5, 12.0, 4)
        else:
            u = rng.uniform(-12.0, 12.0, 4)
        # times around the fault edges (a stage lands on onset or end) and anywhere
        edges = [f.onset for f in act.faults] + [f.end for f in act.faults if f.end is not None]
        if edges and n % 3 == 0:
            t = float(rng.choice(edges)) - float(rng.choice([0.0, 0.5 * h, h, 1e-9]))
        else:
            t = float(rng.uniform(0.0, 300.0))
        step, (_, accel, _) = assert_engines_bit_identical(p, act, t, x, u, h)
        if wmax is not None:
            free = wheel_accel(paper_actuators(faults=act.faults, umin=act.umin, umax=act.umax), t,
                               u, x[6:10])[1]
            limited += int(np.any(free != accel))
        shadowed += int(np.dot(step[0:3], x[0:3]) < 0.0)
    assert shadowed >= 5, "the sample should switch to the MRP shadow set"
    if case in ("paper_faults_stuck_limit", "random"):
        assert limited >= 10, "the sample should hit the wheel-speed limit"


def test_python_and_cpp_are_bit_identical_on_special_commands():
    # NaN and infinite commands, commands exactly at the limits, zero state
    p = paper_plant()
    faults = PAPER_FAULTS + (WheelFault(wheel=3, stuck=True, onset=5.0, end=15.0),)
    act = paper_actuators(max_wheel_speed=np.full(4, 100.0), faults=faults)
    x = random_state(np.random.default_rng(5))
    for u in (
        [-7.0, 10.0, 0.0, -0.0],
        [np.inf, -np.inf, 1e300, -1e300],
        [np.nan, 1.0, 2.0, 3.0],
    ):
        for t in (0.0, 5.0, 7.25, 15.0):
            assert_engines_bit_identical(p, act, t, x, np.array(u))
            assert_engines_bit_identical(p, act, t, np.zeros(10), np.array(u))


@pytest.mark.parametrize("case", ["paper_faults_stuck_limit", "fault_free", "random"])
def test_python_and_cpp_are_bit_identical_over_300s_open_loop(case):
    # 3000 steps of 0.1 s with a time-varying command: every state identical.
    p, act, wmax = _fault_set(case, np.random.default_rng(7))
    pc, ac = plant_params_to_cpp(p), actuator_params_to_cpp(act)
    x_py = X0_PAPER.copy()
    s_cpp = _core.PlantState.from_vector(X0_PAPER)
    h = 0.1
    hit_limit = False
    for k in range(3000):
        t = k * h
        u = 6.0 * _spin_command(0.5 * t) + np.array([1.0, 0.5, -0.5, 0.2])
        x_py = rk4_step(p, act, t, x_py, h, u)
        s_cpp = _core.plant_rk4_step(pc, ac, t, s_cpp, h, u)
        assert_bits(x_py, s_cpp.to_vector(), f"state after step {k} (t = {t + h:.1f} s)")
        if wmax is not None:
            hit_limit |= bool(np.any(np.abs(x_py[6:10]) >= wmax - 1.0))
    if case == "paper_faults_stuck_limit":
        assert hit_limit, "the trajectory should reach the wheel-speed limit"


def test_plant_state_vector_round_trip():
    v = np.arange(10.0) * 0.1
    s = _core.PlantState.from_vector(v)
    np.testing.assert_array_equal(s.sigma_BN, v[0:3])
    np.testing.assert_array_equal(s.omega_BN_B, v[3:6])
    np.testing.assert_array_equal(s.wheel_speed, v[6:10])
    np.testing.assert_array_equal(s.to_vector(), v)
    with pytest.raises(TypeError):
        _core.PlantState.from_vector(np.zeros(9))


def test_plant_params_to_cpp_copies_every_field():
    d = DisturbanceParams(amp=[1e-3, 2e-3, 3e-3], freq=[0.1, 0.2, 0.3], bias=[-1e-4, 0, 1e-4])
    p = paper_plant(disturbance=d, w0=0.002)
    c = plant_params_to_cpp(p)
    np.testing.assert_array_equal(c.J0, J0_PAPER)
    np.testing.assert_array_equal(c.dJ, DJ_PAPER)
    np.testing.assert_array_equal(c.Cbar, CBAR_PAPER)
    np.testing.assert_array_equal(c.Jw, np.full(4, 0.338))
    assert c.w0 == 0.002
    np.testing.assert_array_equal(c.dist_amp, d.amp)
    np.testing.assert_array_equal(c.dist_freq, d.freq)
    np.testing.assert_array_equal(c.dist_bias, d.bias)
    # the C++ defaults are the paper's plant too
    dflt = _core.PlantParams()
    np.testing.assert_array_equal(dflt.J0, J0_PAPER)
    np.testing.assert_array_equal(dflt.Cbar, CBAR_PAPER)
    np.testing.assert_array_equal(dflt.dist_amp, [5e-3, -5e-3, 6e-3])


# --- validation ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        (dict(J0=np.diag([10.0, -15.0, 20.0])), "PlantParams.J0 is not positive definite"),
        (
            dict(J0=np.array([[10.0, 1, 0], [0, 15, 0], [0, 0, 20]])),
            "PlantParams.J0 is not symmetric",
        ),
        (dict(J0=np.eye(2)), "PlantParams.J0 must have shape (3, 3)"),
        (dict(J0=np.diag([10.0, np.nan, 20.0])), "PlantParams.J0 must be finite"),
        (
            dict(dJ=np.diag([-11.0, 0, 0])),
            "PlantParams.J0 + dJ (the true inertia J) is not positive definite",
        ),
        (dict(dJ=np.array([[0, 1.0, 0], [0, 0, 0], [0, 0, 0]])), "PlantParams.dJ is not symmetric"),
        (dict(Cbar=2 * CBAR_PAPER), "PlantParams.Cbar column 0 is not a unit vector"),
        (dict(Cbar=CBAR_PAPER[:, :3]), "PlantParams.Cbar must have shape (3, 4)"),
        (dict(Jw=[0.338, 0.338, 0.0, 0.338]), "PlantParams.Jw of wheel 2 must be > 0, got 0.0"),
        (dict(w0=-0.001), "PlantParams.w0 must be finite and >= 0, got -0.001"),
        (dict(w0=math.nan), "PlantParams.w0"),
        (dict(disturbance="none"), "PlantParams.disturbance must be a DisturbanceParams"),
    ],
)
def test_plant_params_validation(kwargs, needle):
    with pytest.raises(ValueError) as e:
        paper_plant(**kwargs)
    assert needle in str(e.value)


def test_disturbance_params_validation():
    with pytest.raises(ValueError, match=r"DisturbanceParams.amp must be finite"):
        DisturbanceParams(amp=[np.inf, 0, 0])
    with pytest.raises(ValueError, match=r"DisturbanceParams.freq must have shape \(3,\)"):
        DisturbanceParams(freq=[0.1, 0.2])


def test_plant_params_are_read_only_copies():
    J0 = np.diag([10.0, 15.0, 20.0])
    p = paper_plant(J0=J0)
    J0[0, 0] = -1.0
    assert p.J0[0, 0] == 10.0
    with pytest.raises(ValueError):
        p.J0[0, 0] = -1.0


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        (dict(J0=np.diag([10.0, -15.0, 20.0])), "J0 is not positive definite"),
        (dict(dJ=np.diag([-11.0, 0, 0])), "J0 + dJ (the true inertia J) is not positive definite"),
        (dict(dJ=np.array([[0, 1.0, 0], [0, 0, 0], [0, 0, 0]])), "dJ is not symmetric"),
        (dict(Cbar=2 * CBAR_PAPER), "Cbar column 0 is not a unit vector"),
        (dict(Jw=np.array([0.338, -1.0, 0.338, 0.338])), "Jw[1] must be > 0, got -1"),
        (dict(w0=-1.0), "w0 must be finite and >= 0"),
        (dict(dist_amp=np.array([0.0, np.nan, 0.0])), "dist_amp is not finite"),
    ],
)
def test_cpp_plant_params_validation(kwargs, needle):
    with pytest.raises(ValueError) as e:
        _core.PlantParams(**kwargs)
    assert needle in str(e.value)
    c = _core.PlantParams()
    for k, v in kwargs.items():
        setattr(c, k, v)
    assert any(needle in problem for problem in _core.validate(c))
