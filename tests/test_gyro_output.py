"""Integrating gyros (issue #30, item 1): ``[sensors.gyro] output =
"increment"`` delivers the delta angle over the interval since the previous
sample as a mean rate tagged at the interval's end, and the MEKF propagates
with it as such. Checked against closed forms: a rotation about a fixed axis
with a linearly growing rate (its mean rate over an interval, and the
attitude deficit of treating those means as rate samples), and an arbitrary
tumbling attitude history, which the filter must follow exactly from
noise-free increments."""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.scenario.model import ScenarioError
from sc_rt.scenario.reader import load_scenario, scenario_from_data

ROOT = Path(__file__).resolve().parent.parent

DT = 0.01  # [s] plant step
TICKS = 50  # plant steps per gyro sample: 2 Hz
A, B = 0.02, 0.004  # [rad/s], [rad/s^2]: the rate a + b t about a fixed axis
AXIS = np.array([1.0, 2.0, -2.0]) / 3.0
SIGMA0 = np.array([0.1, -0.2, 0.05])


def _suite(output: int):
    p = _core.SensorParams()
    p.dt = DT
    p.gyro.enabled = True
    p.gyro.period_ticks = TICKS
    p.gyro.output = output
    s = _core.SensorSuite(p)
    s.reset()
    return s


def _fixed_axis_state(t: float) -> np.ndarray:
    """R(t) = exp(-theta(t) n^) R0, theta = a t + b t^2 / 2: the attitude and rate at t."""
    theta = A * t + B * t * t / 2.0
    return np.concatenate([_core.mrp_rotate_body(SIGMA0, theta * AXIS), (A + B * t) * AXIS, np.zeros(4)])


def _samples(suite, state, n_ticks: int) -> list[tuple[float, np.ndarray, int]]:
    out = []
    for i in range(n_ticks + 1):
        t = i * DT
        suite.tick(i, t, state(t))
        if suite.gyro_new:
            tg, w, kind = suite.gyro
            out.append((tg, np.asarray(w), kind))
    return out


def test_an_integrating_gyro_delivers_the_mean_rate_of_its_interval():
    inc = _samples(_suite(_core.GYRO_MEAN_RATE), _fixed_axis_state, 20 * TICKS)
    rate = _samples(_suite(_core.GYRO_RATE), _fixed_axis_state, 20 * TICKS)
    assert len(inc) == len(rate) == 21
    h = TICKS * DT
    for k, ((t, w, kind), (t2, r, kind2)) in enumerate(zip(inc, rate)):
        assert t == t2 and (kind, kind2) == (_core.GYRO_MEAN_RATE, _core.GYRO_RATE)
        # the rate sample: a + b t; the increment: (theta(t) - theta(t - h)) / h = a + b (t - h / 2)
        np.testing.assert_allclose(r, (A + B * t) * AXIS, rtol=0, atol=1e-15)
        mean = A + B * (t - h / 2.0) if k > 0 else A  # the first sample has no interval: the rate
        np.testing.assert_allclose(w, mean * AXIS, rtol=0, atol=1e-14)


def _mekf():
    p = _core.MekfParams()
    p.history = 8
    return _core.Mekf(p)


def _angle(s1: np.ndarray, s2: np.ndarray) -> float:
    return float(np.linalg.norm(_core.mrp_error_vector(s1, s2)))


def test_the_filter_propagates_increments_without_the_half_sample_lag():
    """Noise-free increments of the accelerating rotation: propagated as mean
    rates the filter stays on the truth; propagated as rate samples (the two
    bounding samples averaged, what sc-rt's filter did with any gyro) it
    falls behind by b h^2 / 4 over the first interval and b h^2 / 2 over
    each later one, about the axis."""
    samples = _samples(_suite(_core.GYRO_MEAN_RATE), _fixed_axis_state, 40 * TICKS)
    h = TICKS * DT
    right, wrong = _mekf(), _mekf()
    for f in (right, wrong):
        f.reset(0.0, SIGMA0, np.zeros(3))
    for n, (t, w, kind) in enumerate(samples):
        right.gyro(t, w, kind)
        wrong.gyro(t, w, _core.GYRO_RATE)
        truth = _fixed_axis_state(t)[:3]
        assert _angle(truth, right.state.sigma) < 1e-12, (t, _angle(truth, right.state.sigma))
        if n >= 1:
            deficit = B * h * h / 4.0 + (n - 1) * B * h * h / 2.0
            assert _angle(truth, wrong.state.sigma) == pytest.approx(deficit, rel=1e-6)


def _tumbling_state(t: float) -> np.ndarray:
    """A body that cones and nutates: a composition of rotations about moving
    axes (its rate is not along a fixed axis: the second-order, coning, part
    of the attitude change is not small at 2 Hz)."""
    s = _core.mrp_rotate_body(SIGMA0, np.array([0.0, 0.0, 0.6 * t]))
    s = _core.mrp_rotate_body(s, np.array([0.3 * math.sin(1.3 * t), 0.2 * math.cos(0.7 * t), 0.0]))
    return np.concatenate([s, np.full(3, np.nan), np.zeros(4)])  # the rate: unused by increments after t = 0


def test_noise_free_increments_carry_the_filter_through_a_tumble_exactly():
    """Increments are the rotation vectors of the attitude change
    (coning-compensated, docs/MODEL.md): from noise-free ones the filter
    reproduces the sampled attitudes whatever the motion between them."""
    s = _suite(_core.GYRO_MEAN_RATE)
    s.tick(0, 0.0, np.concatenate([_tumbling_state(0.0)[:3], np.zeros(7)]))  # the first sample: a rate
    f = _mekf()
    f.reset(0.0, _tumbling_state(0.0)[:3], np.zeros(3))
    for i in range(1, 60 * TICKS + 1):
        t = i * DT
        x = _tumbling_state(t)
        s.tick(i, t, x)
        if s.gyro_new:
            tg, w, kind = s.gyro
            f.gyro(tg, np.asarray(w), kind)
            assert _angle(x[:3], f.state.sigma) < 1e-11, t


def test_the_scenario_key_selects_the_output_and_bad_values_exit_with_the_key():
    from sc_rt.scenario.tables.sensors import nav_config

    path = ROOT / "scenarios" / "ppc_feasible_10hz_sensors.toml"
    base = tomllib.loads(path.read_text())
    assert load_scenario(path).sensors.gyro.output == "rate"  # the default: bitwise the runs before
    for value, code in (("rate", _core.GYRO_RATE), ("increment", _core.GYRO_MEAN_RATE)):
        data = copy.deepcopy(base)
        data["sensors"]["gyro"]["output"] = value
        scn = scenario_from_data(data, str(path))
        assert scn.sensors.gyro.output == value
        assert nav_config(scn.sensors, scn.run.plant_step, str(path)).sensors.gyro.output == code
    data = copy.deepcopy(base)
    data["sensors"]["gyro"]["output"] = "delta"
    with pytest.raises(ScenarioError, match=r"sensors\.gyro\.output.*\"rate\", \"increment\""):
        scenario_from_data(data, str(path))
