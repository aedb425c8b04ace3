"""Torque-commanded wheels in the plant (sc_rt.model.torque_plant; issue #28),
checked against what nobody here wrote: the closed form of Basilisk's "BOE"
case (its integrated reaction wheel unit test: a hub and one wheel, a
motor torque step at 5 s), the conservation of angular momentum and energy
of spacecraft and wheels once the torques end (their tolerance, 1e-10
relative), and the closed form of a Coulomb + viscous spin-down."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sc_rt.model.plant_params import DisturbanceParams, PlantParams
from sc_rt.model.torque_plant import TorquePlant, TorqueWheels, torque_plant_to_cpp
from sc_rt.model.wheels import WheelFriction, WheelLimits

RPM = 2.0 * math.pi / 60.0
QUIET = DisturbanceParams(amp=np.zeros(3), freq=np.zeros(3), bias=np.zeros(3))


def _one_wheel_about_z(I1: float, Js: float) -> PlantParams:
    """Basilisk's BOE spacecraft: a hub of inertia diag(2, 2, I1 + Js) (the
    wheel's spin inertia in it) and an HR16 wheel on z; our three other
    wheels sit on x and y at rest, untouched by a motion about z."""
    J = np.diag([2.0, 2.0, I1 + Js])
    Cbar = np.array([[0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 0.0], [1.0, 0.0, 0.0, 0.0]])
    return PlantParams(J0=J, dJ=np.zeros((3, 3)), Cbar=Cbar, Jw=np.array([Js, 1e-3, 1e-3, 1e-3]), w0=0.0,
                       disturbance=QUIET)


def test_basilisk_boe_hub_and_wheel_torque_step():
    I1, Js = 2.0, 100.0 / (6000.0 * RPM)  # HR16: 100 N m s at 6000 rpm
    plant = TorquePlant(_one_wheel_about_z(I1, Js))
    w0, W0, u, t_on, h = 0.35, 100.0 * RPM, 0.2, 5.0, 0.1  # their values and their 0.1 s step
    x = np.array([0, 0, 0, 0, 0, w0, W0, 0, 0, 0], float)
    got = {}
    for k in range(100):
        t = k * h
        x = plant.step(t, x, h, [u if t >= t_on - 1e-12 else 0.0, 0, 0, 0])
        got[round((k + 1) * h, 9)] = x
    for t in (2.0, 4.0, 6.0, 8.0, 10.0):
        dt = max(0.0, t - t_on)
        omega = w0 - u / I1 * dt
        theta = w0 * t - 0.5 * u / I1 * dt * dt
        wheel = W0 + (I1 + Js) * u / (I1 * Js) * dt
        x = got[t]
        assert x[5] == pytest.approx(omega, rel=1e-8), t
        assert 4.0 * math.atan(x[2]) == pytest.approx(theta, rel=1e-8), t
        assert x[6] == pytest.approx(wheel, rel=1e-8), t
        assert np.all(x[[0, 1, 3, 4, 7, 8, 9]] == 0.0)  # nothing moves off z


def test_momentum_and_energy_conserved_once_the_torques_end():
    J = np.array([[30.0, 1.0, -0.5], [1.0, 25.0, 0.8], [-0.5, 0.8, 20.0]])
    b = 1.0 / math.sqrt(3.0)
    Cbar = np.array([[b, -b, -b, b], [b, b, -b, -b], [b, b, b, b]])  # a pyramid
    p = PlantParams(J0=J, dJ=np.zeros((3, 3)), Cbar=Cbar, Jw=np.array([0.05, 0.06, 0.05, 0.04]), w0=0.0,
                    disturbance=QUIET)
    plant = TorquePlant(p)
    x = np.array([0.1, -0.2, 0.05, 0.02, -0.03, 0.01, 50.0, -20.0, 10.0, 0.0])
    h = 0.01
    H0 = E0 = None
    dH = dE = 0.0
    for k in range(1000):
        t = k * h
        torque = [0.02, -0.01, 0.005, 0.01] if t < 2.0 else [0.0] * 4
        x = plant.step(t, x, h, torque)
        if t + h >= 2.0 - 1e-12:
            H, E = plant.momentum_N(x), plant.energy(x)
            if H0 is None:
                H0, E0 = H, E
            dH = max(dH, float(np.linalg.norm(H - H0) / np.linalg.norm(H0)))
            dE = max(dE, abs(E - E0) / E0)
    assert dH <= 1e-10 and dE <= 1e-10, (dH, dE)
    # and while the motors worked, they changed the energy (the check can fail)
    assert abs(plant.energy(np.array([0.1, -0.2, 0.05, 0.02, -0.03, 0.01, 50.0, -20.0, 10.0, 0.0])) - E0) > 1e-3


def test_coulomb_and_viscous_spin_down_follows_its_closed_form():
    # the wheel's friction is internal: with the hub free, the relative speed
    # obeys J_eff Omega_dot = -(f_c + c Omega), J_eff = Js I1 / (Js + I1)
    I1, Js, fc, c, lc = 2.0, 0.159, 0.03, 0.001, 0.05
    plant = TorquePlant(_one_wheel_about_z(I1, Js),
                        TorqueWheels(friction=(WheelFriction(coulomb=fc, viscous=c, omega_limit_cycle=lc),)
                                     + (WheelFriction(),) * 3))
    W0, h = 15.0, 0.01
    Jeff = Js * I1 / (Js + I1)

    def closed(t: float) -> float:
        return (W0 + fc / c) * math.exp(-c * t / Jeff) - fc / c

    t_band = Jeff / c * math.log((W0 + fc / c) / (lc + fc / c))  # closed form reaches the linear band
    t_stop = Jeff / c * math.log(1.0 + c * W0 / fc)  # and would stop (Coulomb + viscous alone)
    assert t_band < t_stop
    x = np.array([0, 0, 0, 0, 0, 0, W0, 0, 0, 0], float)
    hub0 = 0.0
    crossed = None
    for k in range(int(t_stop / h) + 200):
        t = k * h
        x = plant.step(t, x, h, [0.0] * 4)
        if crossed is None and x[6] < lc:
            crossed = t + h
        if (k + 1) % 100 == 0 and t + h < t_band:
            assert x[6] == pytest.approx(closed(t + h), rel=1e-9), t + h
            # the momentum the wheel loses, the hub gets: (I1 + Js) omega + Js Omega stays Js W0
            assert (I1 + Js) * x[5] + Js * x[6] == pytest.approx(Js * W0 + (I1 + Js) * hub0, rel=1e-12)
    assert crossed == pytest.approx(t_band, abs=h)
    assert 0.0 < x[6] < lc  # inside the band it decays towards rest, never past it


def test_a_wheel_inertia_larger_than_the_spacecraft_is_refused():
    p = PlantParams(J0=np.eye(3) * 0.1, dJ=np.zeros((3, 3)), Cbar=np.array([[1.0, 0, 0, 1], [0, 1, 0, 0],
                                                                          [0, 0, 1, 0]]),
                    Jw=np.array([0.06, 0.05, 0.05, 0.06]), w0=0.0, disturbance=QUIET)
    with pytest.raises(ValueError, match="not positive definite"):
        TorquePlant(p)


@pytest.mark.parametrize("stribeck", [False, True])
def test_the_cpp_twin_gives_the_same_bits(stribeck, rng):
    """Every feature on at once: the paper's spacecraft with gravity gradient
    and disturbance, limits that bite (torque, deadband, power, speed) and
    friction of every kind; random commands, 300 steps."""
    J = np.array([[10.0, 0.3, -0.2], [0.3, 15.0, 0.1], [-0.2, 0.1, 20.0]])
    b = 1.0 / math.sqrt(3.0)
    Cbar = np.array([[b, -b, -b, b], [b, b, -b, -b], [b, b, b, b]])
    p = PlantParams(J0=J, dJ=np.diag([0.5, -0.3, 0.2]), Cbar=Cbar, Jw=np.array([0.05, 0.06, 0.05, 0.04]),
                    w0=0.0011)
    wheels = TorqueWheels(
        limits=(WheelLimits(u_max=0.2), WheelLimits(u_max=0.2, u_min=0.01), WheelLimits(p_max=2.0),
                WheelLimits(u_max=0.2, omega_max=60.0)),
        friction=tuple(WheelFriction(coulomb=5e-4, static=1e-3, beta=0.5, viscous=2e-5, omega_limit_cycle=0.01)
                       for _ in range(4)),
        stribeck=stribeck)
    py, cpp = TorquePlant(p, wheels), torque_plant_to_cpp(p, wheels)
    assert np.array_equal(py.M, cpp.M)
    x = np.array([0.1, -0.2, 0.3, 0.01, -0.02, 0.015, 55.0, -3.0, 0.2, 0.0])
    h = 0.01
    for k in range(300):
        u = rng.uniform(-0.3, 0.3, 4)
        a, c = py.step(k * h, x, h, u), cpp.step(k * h, x, h, u)
        assert np.array_equal(a, c), (k, a - c)
        x = a
    assert not np.allclose(x[6:], [55.0, -3.0, 0.2, 0.0], atol=0.5)  # the wheels did move
