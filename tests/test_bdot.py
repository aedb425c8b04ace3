"""B-dot detumbling (issue #43 item 5; cpp/include/sc_rt/bdot.hpp), checked against what nobody
here wrote: a rigid body integrated by scipy's solve_ivp (quaternion kinematics, Euler's
equations) in a rotating dipole-like field written here, where the continuous law's Lyapunov
function 1/2 omega' J omega must never increase; Markley & Crassidis' gain rule
k = 2 n (1 + sin xi_m) J_min; the first-order difference against the closed form of a vector
rotating at a constant rate (the chord: sin(theta/2)/(theta/2) times the tangent at the
midpoint); the filter against 1 - exp(-t/tau); the mode switch's hysteresis. All fail on the
old main (no such bindings)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from sc_rt import _core

N_ORBIT = 0.0011  # [rad/s]


def _rods(dmax: float) -> _core.MagnetorquerParams:
    r = _core.MagnetorquerParams()
    r.G_B = np.eye(3)
    r.dipole_max = np.full(3, dmax)
    return r


def _field_N(t: float) -> np.ndarray:
    """A dipole-like field seen along a circular polar orbit: the radial part B0 sin(u) * -2,
    the along-track part B0 cos(u) (u = n t), plus a small constant cross-track part [T]."""
    u = N_ORBIT * t
    return 3e-5 * np.array([math.cos(u), 0.15, -2.0 * math.sin(u)])


def test_gain_rule_against_the_formula():
    J = np.array([[12.0, 0.5, 0.0], [0.5, 9.0, 0.2], [0.0, 0.2, 15.0]])
    J_min = float(np.linalg.eigvalsh(J)[0])
    for n, xi in [(0.0011, math.radians(60.0)), (0.00106, math.radians(90.0)), (0.0012, 0.0)]:
        assert _core.bdot_gain(n, xi, J_min) == pytest.approx(2.0 * n * (1.0 + math.sin(xi)) * J_min, rel=1e-15)
    with pytest.raises(ValueError, match="J_min must be finite and > 0, got 0"):
        _core.bdot_gain(0.001, 0.0, 0.0)


@pytest.mark.parametrize("dmax", [1e6, 20.0])  # unsaturated, and saturated most of the time
def test_lyapunov_function_decreases_monotonically(dmax):
    J = np.array([[10.0, 0.3, -0.2], [0.3, 15.0, 0.1], [-0.2, 0.1, 20.0]])
    k = _core.bdot_gain(N_ORBIT, math.radians(70.0), float(np.linalg.eigvalsh(J)[0]))
    p = _core.BdotParams()
    p.gain = k
    p.derivative = _core.BdotDerivative.Analytic
    law = _core.Bdot(p, _rods(dmax))
    state = _core.BdotState()
    saturated = []

    def rhs(t, x):
        q, w = x[:4], x[4:]
        B_B = Rotation.from_quat(q).as_matrix().T @ _field_N(t)
        o = law.update(state, t, B_B, w)
        saturated.append(o.scale < 1.0)
        tau = np.cross(o.m_B, B_B)
        w_dot = np.linalg.solve(J, -np.cross(w, J @ w) + tau)
        v, s = q[:3], q[3]
        q_dot = 0.5 * np.concatenate([s * w + np.cross(v, w), [-(v @ w)]])  # q x (w, 0), scalar last
        return np.concatenate([q_dot, w_dot])

    w0 = np.radians([4.0, -3.0, 5.0])
    x0 = np.concatenate([[0.0, 0.0, 0.0, 1.0], w0])
    t = np.linspace(0.0, 2000.0, 401)
    sol = solve_ivp(rhs, (t[0], t[-1]), x0, t_eval=t, method="DOP853", rtol=1e-11, atol=1e-13)
    assert sol.success
    w = sol.y[4:]
    V = 0.5 * np.einsum("it,ij,jt->t", w, J, w)
    assert np.all(np.diff(V) <= 1e-12 * V[0]), np.max(np.diff(V))
    assert V[-1] < (0.8 if dmax < 100 else 0.5) * V[0]  # and it does detumble
    if dmax < 100:
        assert np.mean(saturated) > 0.5


def test_difference_matches_the_rotating_vector_closed_form():
    """Constant body rate, field fixed in N: B_B(t) = exp(-w^ t) B_0, whose chord over dt is
    sin(theta/2)/(theta/2) * (-w x B(t - dt/2)) / 1 per second, theta = |w| dt."""
    w = np.radians([3.0, -2.0, 6.0])
    B0 = np.array([2e-5, -1e-5, 3e-5])
    dt = 0.5

    def B_at(t):
        return Rotation.from_rotvec(-w * t).apply(B0)

    p = _core.BdotParams()
    p.gain = 0.01
    law = _core.Bdot(p, _rods(1e9))
    s = _core.BdotState()
    o = law.update(s, 0.0, B_at(0.0), np.zeros(3))
    np.testing.assert_array_equal(o.dipole, np.zeros(3))  # first sample: no difference yet
    s = o.state
    theta = np.linalg.norm(w) * dt
    sinc = math.sin(theta / 2) / (theta / 2)
    for i in range(1, 20):
        t = i * dt
        o = law.update(s, t, B_at(t), np.zeros(3))
        s = o.state
        expect = sinc * -np.cross(w, B_at(t - dt / 2))
        np.testing.assert_allclose(o.Bdot_B, expect, rtol=1e-9, atol=1e-18)
        B = B_at(t)
        np.testing.assert_allclose(o.m_B, -0.01 / (B @ B) * o.Bdot_B, rtol=1e-13)  # normalized law
    # time not advancing: the derivative is held
    held = law.update(s, s.t, B_at(s.t) * 2.0, np.zeros(3))
    np.testing.assert_array_equal(held.Bdot_B, s.Bdot_B)


def test_filter_against_the_exponential():
    c = np.array([1e-7, -2e-7, 5e-8])  # [T/s] a field changing linearly
    p = _core.BdotParams()
    p.gain = 2.0
    p.normalized = False
    p.filter_tau = 3.0
    law = _core.Bdot(p, _rods(1e9))
    s = _core.BdotState()
    dt = 0.2
    for i in range(0, 60):
        o = law.update(s, i * dt, np.array([1e-5, 2e-5, 3e-5]) + c * (i * dt), np.zeros(3))
        s = o.state
        np.testing.assert_allclose(o.Bdot_B, c * -math.expm1(-i * dt / 3.0), rtol=1e-9, atol=1e-22)
        np.testing.assert_allclose(o.m_B, -2.0 * o.Bdot_B, rtol=1e-13)  # -k dB/dt


def test_mode_switch_hysteresis():
    D, A = _core.DetumbleMode.Detumble, _core.DetumbleMode.Attitude
    on, off = 0.035, 0.0087
    assert _core.detumble_mode(A, 0.0349, on, off) == A
    assert _core.detumble_mode(A, 0.0351, on, off) == D
    assert _core.detumble_mode(D, 0.02, on, off) == D  # between: kept
    assert _core.detumble_mode(A, 0.02, on, off) == A
    assert _core.detumble_mode(D, 0.0088, on, off) == D
    assert _core.detumble_mode(D, 0.0086, on, off) == A
    assert _core.detumble_mode_name(D) == "detumble" and _core.detumble_mode_name(A) == "attitude"
    p = _core.BdotParams()
    p.gain = 1.0
    p.rate_on, p.rate_off = 0.01, 0.02
    with pytest.raises(ValueError, match="rate_off 0.02, rate_on 0.01"):
        _core.Bdot(p, _rods(1.0))
