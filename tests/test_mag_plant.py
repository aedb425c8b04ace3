"""The magnetic torque the plant integrates (issue 43: "with everything but the
magnetorquers off, total angular momentum conserved to 1e-10; with them on,
its change equals the integral of m x B"), against what the test computes
itself: the field from the ``ppigrf`` package (IGRF-14, independent of
sc_rt.model.field), the attitude matrix from the Euler parameters of the
MRP, the angular momentum and the torque in N with numpy, the integral by
Simpson's rule. All fail on the old main (no ``field_model``,
``residual_dipole``, ``orbit_gravity_gradient`` nor ``dipole_B``)."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest

from magscn import ppigrf_field_N
from refmath import mrp_dcm
from sc_rt import _core
from sc_rt.model.actuators import ActuatorParams, actuator_params_to_cpp
from sc_rt.model.field import field_for
from sc_rt.model.orbit import R_EARTH, OrbitParams, orbit_state
from sc_rt.model.plant import derivative, plant_params_to_cpp
from sc_rt.model.plant_params import DisturbanceParams, PlantParams
from sc_rt.scenario.tables.orbit import julian_date

ppigrf = pytest.importorskip("ppigrf")

WHEN = dt.datetime(2026, 3, 20, 12, 0, 0)
JD = julian_date(WHEN)
ORBIT = OrbitParams(a=R_EARTH + 500e3, i=math.radians(51.6), raan=0.4, M0=0.3, jd_epoch=JD)
J0 = np.array([[12.0, 0.3, -0.2], [0.3, 14.0, 0.4], [-0.2, 0.4, 22.0]])
CBAR = np.c_[np.eye(3), np.ones(3) / math.sqrt(3.0)]
JW = np.full(4, 0.05)
X0 = np.array([0.1, -0.3, 0.2, 0.006, -0.004, 0.0075, 5.0, -3.0, 2.0, 1.0])  # slow enough for h = 0.5 s
ZERO_D = DisturbanceParams(amp=np.zeros(3), freq=np.zeros(3), bias=np.zeros(3))


def _plant(res=(0.0, 0.0, 0.0), field="igrf") -> PlantParams:
    # every torque but the magnetic one off: no d(t), no w0 form (w0 = 0), the orbit's
    # gravity gradient switched off by the test-only flag
    return PlantParams(J0=J0, dJ=np.zeros((3, 3)), Cbar=CBAR, Jw=JW, w0=0.0, disturbance=ZERO_D,
                       orbit=ORBIT, field_model=field, residual_dipole=np.asarray(res, float),
                       orbit_gravity_gradient=False)


ACT = ActuatorParams(umin=np.full(4, -7.0), umax=np.full(4, 10.0))


def _H_N(x) -> np.ndarray:
    """[N m s] spacecraft + wheels' angular momentum in N."""
    return mrp_dcm(x[0:3]).T @ (J0 @ x[3:6] + (CBAR * JW) @ x[6:10])


def _field_N(times) -> np.ndarray:
    """[T] IGRF-14 by ppigrf at the orbit's positions (ECI), the epoch's coefficients (n, 3)."""
    return ppigrf_field_N(ORBIT, JD, times, WHEN)


def _run(p: PlantParams, h: float, n: int, dipole=None) -> np.ndarray:
    """States at t = k h, k = 0..n, on the C++ plant (bitwise the Python one,
    tests/test_mag_plant_twin.py); ``dipole(k)``: the held dipole of step k."""
    pc, ac = plant_params_to_cpp(p), actuator_params_to_cpp(ACT)
    u = np.zeros(4)
    xs = [X0]
    x = _core.PlantState.from_vector(X0)
    for k in range(n):
        x = _core.plant_rk4_step(pc, ac, k * h, x, h, u, dipole_B=None if dipole is None else dipole(k))
        xs.append(x.to_vector())
    return np.array(xs)


def test_residual_dipole_torque_is_m_cross_the_field_in_the_body():
    m = np.array([0.8, -1.5, 2.5])  # [A m^2]
    p, p0 = _plant(m), _plant()
    acc = np.zeros(4)
    times = [0.0, 1500.0, 4000.0]
    B_N = _field_N(times)
    for t, B in zip(times, B_N):
        for sigma in ([0.0, 0.0, 0.0], [0.2, -0.4, 0.1], [-0.5, 0.3, 0.6]):
            x = X0.copy()
            x[0:3] = sigma
            tau = J0 @ (derivative(t, x, acc, p)[3:6] - derivative(t, x, acc, p0)[3:6])
            ref = np.cross(m, mrp_dcm(sigma) @ B)
            # ppigrf and the bench's IGRF-14 agree to < 1 nT (tests/test_geomag.py): 1e-9 T |m|
            np.testing.assert_allclose(tau, ref, rtol=0, atol=1e-9 * np.linalg.norm(m))
            assert np.linalg.norm(ref) > 1e-5  # [N m]: 20-50 uT times 3 A m^2 is a real torque


def test_angular_momentum_conserved_without_any_dipole_over_an_orbit():
    # the field is on, no dipole: no external torque at all (J2 off, gravity gradient off, d = 0)
    period = 2.0 * math.pi * math.sqrt(ORBIT.a**3 / ORBIT.mu)
    h = 0.5
    xs = _run(_plant(), h, int(period / h) + 1)
    H = np.array([_H_N(x) for x in xs])
    drift = np.max(np.linalg.norm(H - H[0], axis=1)) / np.linalg.norm(H[0])
    assert drift < 1e-10, drift
    # and the body did move: the attitude turned by radians, momentum moved between axes
    assert np.max(np.abs(xs[:, 3:6] - X0[3:6])) > 1e-3


def test_momentum_change_is_the_integral_of_m_cross_b_in_n():
    res = np.array([1.0, -2.0, 0.5])  # [A m^2] residual dipole
    h, block, nblocks = 0.5, 20, 100  # the magnetorquers' dipole held 10 s at a time, 1000 s
    rng = np.random.default_rng(7)
    dip = rng.uniform(-20.0, 20.0, (nblocks, 3))  # [A m^2]
    xs = _run(_plant(res), h, block * nblocks, dipole=lambda k: dip[k // block])
    t = h * np.arange(len(xs))
    B_N = _field_N(t)
    # tau_N = C_NB (m_B x C_BN B_N) = (C_NB m_B) x B_N, Simpson's rule over each block (m constant)
    integral = np.zeros(3)
    w = np.ones(block + 1)
    w[1:-1:2], w[2:-1:2] = 4.0, 2.0
    for b in range(nblocks):
        k = slice(b * block, (b + 1) * block + 1)
        m_B = res + dip[b]
        tau = np.array([np.cross(mrp_dcm(x[0:3]).T @ m_B, B) for x, B in zip(xs[k], B_N[k])])
        integral += (h / 3.0) * (w @ tau)
    dH = _H_N(xs[-1]) - _H_N(xs[0])
    # the field's difference (< 1 nT of ppigrf against the bench's IGRF-14) times |m| <= 22 A m^2
    # over 1000 s bounds the error by 2.2e-5 N m s; RK4's and Simpson's errors (h omega ~ 1e-2,
    # a step's error ~ (h omega)^5 / 120 |H|) are orders below it
    assert np.linalg.norm(integral) > 1e-2  # [N m s]: a change three orders above the tolerance
    np.testing.assert_allclose(dH, integral, rtol=0, atol=2.2e-5)


def _bench_field_error(res, h: float, n: int) -> tuple[float, float]:
    """|dH - Simpson integral of m x B| and |integral| [N m s] over n steps of h,
    the field from sc_rt.model.field (itself within 1 nT of ppigrf, tests/test_geomag.py)."""
    xs = _run(_plant(res), h, n)
    f = field_for("igrf", JD)
    t = h * np.arange(n + 1)
    B_N = np.array([f.B_eci(orbit_state(ORBIT, tk)[0], JD, tk) for tk in t]) * 1e-9
    tau = np.array([np.cross(mrp_dcm(x[0:3]).T @ res, B) for x, B in zip(xs, B_N)])
    w = np.ones(n + 1)
    w[1:-1:2], w[2:-1:2] = 4.0, 2.0
    integral = (h / 3.0) * (w @ tau)
    dH = _H_N(xs[-1]) - _H_N(xs[0])
    return float(np.linalg.norm(dH - integral)), float(np.linalg.norm(integral))


def test_momentum_change_against_the_benchs_field_to_rk4_accuracy():
    # with the same field on both sides what remains is the integration's error alone: RK4's
    # and Simpson's, both fourth order, so halving the step divides it by about 16
    res = np.array([3.0, 1.0, -2.0])
    err, integral = _bench_field_error(res, 0.5, 400)
    err2, _ = _bench_field_error(res, 0.25, 800)
    assert integral > 1e-3  # [N m s]
    assert err < 1e-10 * np.linalg.norm(_H_N(X0)), err
    assert 10.0 < err / err2 < 25.0, (err, err2)  # h^4: no missing term of lower order
