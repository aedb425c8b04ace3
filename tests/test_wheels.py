"""Flight-like wheel torques (issue #28, first part): the command limits and
the friction of a torque-commanded wheel, in Python (sc_rt.model.wheels) and
in C++ (sc_rt._core.wheel_applied_torque / wheel_friction_torque), checked
against what nobody here wrote: the cases of Basilisk's own RWUpdate unit
test of its reaction wheel state effector (three
wheels commanded [0.4, 0.1, -0.5] N m under torque, deadband, power and
speed limits), the closed form of a Coulomb + viscous spin-down, and the
Stribeck term's peak. The two implementations agree bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.model.wheels import WheelFriction, WheelLimits, applied_torque, friction_torque

RPM = 2.0 * math.pi / 60.0
CMD = (0.4, 0.1, -0.5)  # [N m] the test's command to the three wheels


def _cpp_torque(u: float, omega: float, lim: WheelLimits) -> float:
    return _core.wheel_applied_torque(u, omega, lim.u_max, lim.u_min, lim.p_max, lim.omega_max)


def _cpp_friction(omega: float, f: WheelFriction, stribeck: bool) -> float:
    return _core.wheel_friction_torque(omega, f.coulomb, f.static, f.beta, f.viscous, f.omega_limit_cycle, stribeck)


# Basilisk's RWUpdate cases: the limits, the wheel speeds [rad/s], the torques it applies
RWUPDATE = [
    ("torque limit 0.5, deadband 0.2", WheelLimits(u_max=0.5, u_min=0.2), (0.0, 0.0, 0.0), (0.4, 0.0, -0.5)),
    ("torque limit 0.3, deadband 0.05", WheelLimits(u_max=0.3, u_min=0.05), (0.0, 0.0, 0.0), (0.3, 0.1, -0.3)),
    ("power limit 0.7 W", WheelLimits(u_max=0.3, u_min=0.05, p_max=0.7), (7.0, -5.0, 2.0), (0.1, 0.1, -0.3)),
    ("speed limit 100 rpm", WheelLimits(u_max=0.3, u_min=0.05, omega_max=100 * RPM),
     (100 * RPM, -200 * RPM, 50 * RPM), (0.0, 0.1, -0.3)),
]


@pytest.mark.parametrize("case, lim, omega, expected", RWUPDATE, ids=[c[0] for c in RWUPDATE])
@pytest.mark.parametrize("impl", ["python", "cpp"])
def test_basilisk_rwupdate_cases(case, lim, omega, expected, impl):
    f = applied_torque if impl == "python" else _cpp_torque
    got = [f(u, w, lim) for u, w in zip(CMD, omega)]
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-8)  # Basilisk's accuracy


def test_the_speed_limit_passes_a_torque_that_slows_the_wheel():
    lim = WheelLimits(omega_max=10.0)
    for impl in (applied_torque, _cpp_torque):
        assert impl(0.2, 10.0, lim) == 0.0 and impl(-0.2, -12.0, lim) == 0.0  # further up: zeroed
        assert impl(-0.2, 10.0, lim) == -0.2 and impl(0.2, -12.0, lim) == 0.2  # slowing: passes
        assert impl(0.2, 9.99, lim) == 0.2  # below the limit: anything


def test_python_and_cpp_agree_bit_for_bit():
    rng = np.random.default_rng(28)
    for _ in range(2000):
        lim = WheelLimits(*(rng.choice([0.0, -1.0, float(rng.uniform(0.01, 0.5))]) for _ in range(4)))
        u, w = rng.uniform(-1, 1), rng.choice([0.0, float(rng.uniform(-700, 700))])
        assert applied_torque(u, w, lim) == _cpp_torque(u, w, lim), (u, w, lim)
        fr = WheelFriction(coulomb=float(rng.uniform(0, 1e-3)), static=float(rng.uniform(0, 2e-3)),
                           beta=float(rng.choice([0.0, rng.uniform(0.1, 5)])), viscous=float(rng.uniform(0, 1e-5)),
                           omega_limit_cycle=float(rng.choice([0.0, rng.uniform(1e-4, 0.1)])))
        for stribeck in (False, True):
            assert friction_torque(w, fr, stribeck) == _cpp_friction(w, fr, stribeck), (w, fr, stribeck)


def _spin_down(f: WheelFriction, J: float, omega0: float, h: float, t_end: float, friction=friction_torque):
    """A free wheel, J dOmega/dt = friction(Omega), RK4 at step h."""
    def rate(w: float) -> float:
        return friction(w, f, False) / J

    ts, ws, w = [0.0], [omega0], omega0
    for k in range(int(round(t_end / h))):
        k1 = rate(w)
        k2 = rate(w + h / 2 * k1)
        k3 = rate(w + h / 2 * k2)
        k4 = rate(w + h * k3)
        w = w + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        ts.append((k + 1) * h)
        ws.append(w)
    return np.array(ts), np.array(ws)


@pytest.mark.parametrize("impl", ["python", "cpp"])
def test_coulomb_and_viscous_spin_down_against_its_closed_form(impl):
    """Above the limit-cycle speed, J dW/dt = -(f_c + c W): W(t) = (W0 + f_c/c)
    exp(-c t / J) - f_c / c, reaching omega_lc at t1 = (J/c) ln((W0 + f_c/c) /
    (omega_lc + f_c/c)); below it the friction is linear through its value at
    omega_lc, an exponential with the time constant J omega_lc / (f_c + c omega_lc)."""
    J, fc, c, lc, w0 = 0.01, 5e-3, 1e-4, 0.5, 20.0  # a small wheel with strong friction: ~35 s
    f = WheelFriction(coulomb=fc, viscous=c, omega_limit_cycle=lc)
    fric = friction_torque if impl == "python" else _cpp_friction
    t1 = J / c * math.log((w0 + fc / c) / (lc + fc / c))
    tau = J * lc / (fc + c * lc)
    ts, ws = _spin_down(f, J, w0, 0.01, t1 + 3 * tau, fric)
    above, below = ts <= t1 - 0.01, ts >= t1 + 0.01
    closed_above = (w0 + fc / c) * np.exp(-c * ts[above] / J) - fc / c
    np.testing.assert_allclose(ws[above], closed_above, rtol=1e-9)
    closed_below = lc * np.exp(-(ts[below] - t1) / tau)
    np.testing.assert_allclose(ws[below], closed_below, rtol=2e-6)  # the step across t1 is not exact


def test_without_the_linear_band_the_wheel_stops_at_the_closed_form_time():
    """omega_lc = 0: the speed follows the closed form down to zero, reached
    at t_stop = (J/c) ln(1 + c W0 / f_c), and stays there (within the one
    step's worth of Coulomb deceleration, h f_c / J, that the sign of the
    friction leaves the integration chattering in)."""
    J, fc, c, w0, h = 0.01, 5e-3, 1e-4, 20.0, 0.01
    f = WheelFriction(coulomb=fc, viscous=c)
    t_stop = J / c * math.log(1.0 + c * w0 / fc)
    ts, ws = _spin_down(f, J, w0, h, t_stop + 2.0)
    moving = ts <= t_stop - h
    np.testing.assert_allclose(ws[moving], (w0 + fc / c) * np.exp(-c * ts[moving] / J) - fc / c, rtol=1e-9,
                               atol=1e-9)
    assert ws[moving][-1] < 2 * h * fc / J  # it is stopping within a step of t_stop
    assert np.all(np.abs(ws[ts >= t_stop]) <= h * fc / J)  # and stays stopped


@pytest.mark.parametrize("impl", ["python", "cpp"])
def test_the_stribeck_term_peaks_at_the_breakaway_torque(impl):
    """At Omega = beta the static part is (f_s - f_c) exactly: the friction is
    f_s - f_c + f_c tanh(10) + c beta; far from rest it is Coulomb + viscous."""
    fr = WheelFriction(coulomb=5e-4, static=1e-3, beta=0.2, viscous=2e-6)
    fric = friction_torque if impl == "python" else _cpp_friction
    expect = (1e-3 - 5e-4) + 5e-4 * math.tanh(10.0) + 2e-6 * 0.2
    assert fric(0.2, fr, True) == pytest.approx(-expect, rel=1e-12)
    assert fric(-0.2, fr, True) == pytest.approx(expect, rel=1e-12)
    assert fric(50.0, fr, True) == pytest.approx(-(5e-4 + 2e-6 * 50.0), rel=1e-12)
    assert fric(0.2, fr, False) == -(5e-4 + 2e-6 * 0.2)  # off: Coulomb + viscous
