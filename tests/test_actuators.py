"""Saturation and the wheel fault model (docs/MODEL.md section 2, (15), (16)).

Expected values are written out by hand from (15),(16) in each test, not taken
from the code under test; the C++ engine is held to the Python one.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.model.actuators import (
    ActuatorParams,
    WheelFault,
    actuator_params_to_cpp,
    fault_Y,
    wheel_accel,
)

UMIN = np.array([-7.0, -1.0, -3.0, -0.5])  # asymmetric on purpose
UMAX = np.array([10.0, 2.0, 0.5, 4.0])
ZERO4 = np.zeros(4)


def _act(*faults: WheelFault, wmax=np.inf) -> ActuatorParams:
    return ActuatorParams(umin=UMIN, umax=UMAX, max_wheel_speed=np.full(4, wmax), faults=faults)


def _cpp_accel(act: ActuatorParams, t: float, u, w):
    out = _core.wheel_accel(
        actuator_params_to_cpp(act), t, np.asarray(u, float), np.asarray(w, float)
    )
    return out.u_sat, out.accel, out.Y


# --- saturation (15) -------------------------------------------------------


def test_saturation_asymmetric_limits_by_hand():
    act = _act()
    u = [12.0, -5.0, 0.2, 4.0]  # above umax, below umin, inside, exactly umax
    for engine in (wheel_accel, _cpp_accel):
        u_sat, accel, Y = engine(act, 3.0, u, ZERO4)
        np.testing.assert_array_equal(u_sat, [10.0, -1.0, 0.2, 4.0])
        np.testing.assert_array_equal(accel, u_sat)  # healthy: Omega_dot = sat(uc)
        np.testing.assert_array_equal(Y, ZERO4)
    u = [-7.5, 2.5, -3.0, -0.6]
    for engine in (wheel_accel, _cpp_accel):
        u_sat, _, _ = engine(act, 0.0, u, ZERO4)
        np.testing.assert_array_equal(u_sat, [-7.0, 2.0, -3.0, -0.5])


# --- fault schedule (16) ---------------------------------------------------


@pytest.mark.parametrize("engine", [wheel_accel, _cpp_accel], ids=["python", "cpp"])
def test_effectiveness_and_bias_at_half_activation(engine):
    # t - T = ln 2 / a  ->  Y = 1/2 exactly (to rounding).
    a = 0.7
    f = WheelFault(wheel=1, effectiveness=0.5, bias=0.3, onset=5.0, rate=a)
    t = 5.0 + math.log(2.0) / a
    u_sat, accel, Y = engine(_act(f), t, [1.0, 1.5, 0.0, 0.0], ZERO4)
    # (15): 1.5 + 0.5 * ((0.5 - 1) * 1.5 + 0.3) = 1.5 - 0.225 = 1.275
    assert Y[1] == pytest.approx(0.5, abs=1e-15)
    assert accel[1] == pytest.approx(1.275, abs=1e-15)
    assert accel[0] == 1.0 and Y[0] == 0.0  # other wheels untouched
    assert u_sat[1] == 1.5


@pytest.mark.parametrize("engine", [wheel_accel, _cpp_accel], ids=["python", "cpp"])
def test_onset_and_end_are_abrupt_at_sample_times(engine):
    f = WheelFault(wheel=2, effectiveness=1.0, bias=-0.3, onset=5.0, end=15.0, rate=1.0)
    act = _act(f)
    u = [0.0, 0.0, 0.4, 0.0]
    # t: expected Y, from (16) with a = 1, T = 5, end = 15
    cases = {
        0.0: 0.0,
        4.9: 0.0,
        5.0: 0.0,  # from T on, 1 - exp(0) = 0
        5.1: 1.0 - math.exp(-0.1),
        6.0: 1.0 - math.exp(-1.0),
        14.9: 1.0 - math.exp(-9.9),
        15.0: 0.0,  # the end is abrupt: over at t == end
        15.1: 0.0,
        100.0: 0.0,
    }
    for t, Y_expected in cases.items():
        _, accel, Y = engine(act, t, u, ZERO4)
        assert Y[2] == pytest.approx(Y_expected, rel=1e-14, abs=1e-300), t
        assert accel[2] == pytest.approx(0.4 - 0.3 * Y_expected, rel=1e-14), t
        assert fault_Y(f, t) == pytest.approx(Y_expected, rel=1e-14, abs=1e-300)


@pytest.mark.parametrize("engine", [wheel_accel, _cpp_accel], ids=["python", "cpp"])
@pytest.mark.parametrize("rate", [0.1, 1.0, 10.0])
def test_evolution_rate(engine, rate):
    f = WheelFault(wheel=0, effectiveness=0.0, onset=2.0, rate=rate)
    for tau_multiple in (0.5, 1.0, 3.0):
        t = 2.0 + tau_multiple / rate
        _, accel, Y = engine(_act(f), t, [4.0, 0, 0, 0], ZERO4)
        assert Y[0] == pytest.approx(1.0 - math.exp(-tau_multiple), rel=1e-14)
        # L = 0: Omega_dot = s + Y (-s) = (1 - Y) s
        assert accel[0] == pytest.approx(math.exp(-tau_multiple) * 4.0, rel=1e-13)


@pytest.mark.parametrize("engine", [wheel_accel, _cpp_accel], ids=["python", "cpp"])
def test_effectiveness_zero_ignores_commands_only_bias_left(engine):
    f = WheelFault(wheel=3, effectiveness=0.0, bias=0.25, onset=1.0, rate=2.0)
    t = 1.0 + 40.0  # Y = 1 - exp(-80): 1 to double precision
    outs = [engine(_act(f), t, [0, 0, 0, u], ZERO4)[1][3] for u in (-0.5, 0.0, 1.0, 4.0, 9.0)]
    np.testing.assert_allclose(outs, 0.25, rtol=0, atol=1e-15)


@pytest.mark.parametrize("engine", [wheel_accel, _cpp_accel], ids=["python", "cpp"])
def test_bias_only_fault(engine):
    f = WheelFault(wheel=0, bias=-0.3, onset=0.0, rate=1.0)  # L = 1: only the bias
    for t in (0.5, 2.0, 30.0):
        for u in (-7.0, 0.0, 3.0, 11.0):
            s = min(max(u, -7.0), 10.0)
            _, accel, _ = engine(_act(f), t, [u, 0, 0, 0], ZERO4)
            assert accel[0] == pytest.approx(s - 0.3 * (1.0 - math.exp(-t)), rel=1e-14, abs=1e-15)


@pytest.mark.parametrize("engine", [wheel_accel, _cpp_accel], ids=["python", "cpp"])
def test_stuck_wheel_zero_from_onset_to_end(engine):
    # A slow rate: Y is still tiny at onset + 0.01, the stuck wheel is already
    # at zero acceleration (abrupt, independent of Y).
    f = WheelFault(wheel=1, stuck=True, onset=3.0, end=8.0, rate=0.01, bias=0.5)
    act = _act(f)
    u = [1.0, 1.5, -2.0, 3.0]
    _, accel, _ = engine(act, 2.99, u, ZERO4)
    assert accel[1] == 1.5
    for t in (3.0, 3.01, 5.0, 7.999):
        _, accel, Y = engine(act, t, u, [0, 42.0, 0, 0])
        assert accel[1] == 0.0, t
        np.testing.assert_array_equal(accel[[0, 2, 3]], [1.0, -2.0, 3.0])
        assert Y[1] == pytest.approx(1.0 - math.exp(-0.01 * (t - 3.0)), rel=1e-13, abs=1e-300)
    _, accel, Y = engine(act, 8.0, u, ZERO4)
    assert accel[1] == 1.5 and Y[1] == 0.0


@pytest.mark.parametrize("engine", [wheel_accel, _cpp_accel], ids=["python", "cpp"])
def test_fault_acts_on_the_saturated_command(engine):
    f = WheelFault(wheel=0, effectiveness=0.5, onset=0.0)
    t = 50.0  # Y = 1 to double precision
    u_sat, accel, _ = engine(_act(f), t, [25.0, 0, 0, 0], ZERO4)
    assert u_sat[0] == 10.0
    assert accel[0] == pytest.approx(5.0, rel=1e-15)


@pytest.mark.parametrize("engine", [wheel_accel, _cpp_accel], ids=["python", "cpp"])
def test_wheel_speed_limit(engine):
    act = _act(wmax=50.0)
    u = [1.0, -1.0, 0.3, -0.4]
    # at +limit: outward (positive) acceleration stops, inward passes
    _, accel, _ = engine(act, 0.0, u, [50.0, 50.0, 49.999, 60.0])
    np.testing.assert_array_equal(accel, [0.0, -1.0, 0.3, -0.4])
    # at -limit, mirrored
    _, accel, _ = engine(act, 0.0, u, [-50.0, -50.0, -60.0, -60.0])
    np.testing.assert_array_equal(accel, [1.0, 0.0, 0.3, 0.0])
    # the limit also stops a fault's bias that pushes outward
    f = WheelFault(wheel=2, bias=0.2, onset=0.0)
    _, accel, _ = engine(_act(f, wmax=50.0), 100.0, [0, 0, 0, 0], [0, 0, 50.0, 0])
    assert accel[2] == 0.0
    _, accel, _ = engine(_act(f, wmax=50.0), 100.0, [0, 0, 0, 0], [0, 0, 49.0, 0])
    assert accel[2] == pytest.approx(0.2, rel=1e-15)


def test_fault_Y_healthy_and_none_end():
    assert fault_Y(None, 10.0) == 0.0
    f = WheelFault(wheel=0, onset=1.0, rate=0.5)  # never ends
    assert fault_Y(f, 1e6) == 1.0
    assert fault_Y(f, 0.999) == 0.0


# --- the two engines agree --------------------------------------------------


def test_python_and_cpp_wheel_accel_agree_on_random_inputs():
    rng = np.random.default_rng(11)
    faults = (
        WheelFault(wheel=0, effectiveness=0.3, bias=0.2, onset=4.0, rate=0.8),
        WheelFault(wheel=1, effectiveness=0.9, bias=-0.1, onset=2.0, end=9.0, rate=3.0),
        WheelFault(wheel=2, stuck=True, onset=6.0, end=7.5),
    )
    act = _act(*faults, wmax=30.0)
    edges = (2.0, 4.0, 6.0, 7.5, 9.0)
    for n in range(500):
        # every third sample exactly on a fault's onset or end
        t = float(rng.choice(edges)) if n % 3 == 0 else rng.uniform(0.0, 12.0)
        u = rng.uniform(-12.0, 12.0, 4)
        w = rng.uniform(-40.0, 40.0, 4)
        py = wheel_accel(act, t, u, w)
        cp = _cpp_accel(act, t, u, w)
        for name, a, b in zip(("u_sat", "accel", "Y"), py, cp, strict=True):
            # Same operations in the same order, same libm expm1: the same bits
            # (the plant's RK4 relies on it, tests/test_plant.py).
            assert np.array_equal(a, b), f"{name} at t={t!r}: {a.tolist()} vs {b.tolist()}"


# --- validation ----------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        (dict(wheel=4), "WheelFault.wheel"),
        (dict(wheel=-1), "WheelFault.wheel"),
        (dict(wheel=1.5), "WheelFault.wheel"),
        (dict(wheel=True), "WheelFault.wheel"),
        (dict(wheel=0, effectiveness=1.5), "WheelFault.effectiveness must be in [0, 1], got 1.5"),
        (dict(wheel=0, effectiveness=-0.1), "WheelFault.effectiveness"),
        (dict(wheel=0, effectiveness=math.nan), "WheelFault.effectiveness"),
        (dict(wheel=0, bias=math.inf), "WheelFault.bias"),
        (dict(wheel=0, rate=0.0), "WheelFault.rate must be finite and > 0, got 0.0"),
        (dict(wheel=0, rate=-1.0), "WheelFault.rate"),
        (dict(wheel=0, onset=math.nan), "WheelFault.onset"),
        (dict(wheel=0, onset=5.0, end=5.0), "WheelFault.end must be > onset (5.0), got 5.0"),
        (dict(wheel=0, onset=5.0, end=2.0), "WheelFault.end"),
    ],
)
def test_wheel_fault_validation(kwargs, needle):
    with pytest.raises(ValueError) as e:
        WheelFault(**kwargs)
    assert needle in str(e.value)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        (dict(umin=[-1, -1, 2, -1], umax=[1, 1, 1, 1]), "umin must be < umax for wheel 2"),
        (dict(umin=[-1, -1, 1, -1], umax=[1, 1, 1, 1]), "umin = 1.0, umax = 1.0"),
        (dict(umin=[-1, -1, -1], umax=[1, 1, 1, 1]), "ActuatorParams.umin must have shape (4,)"),
        (dict(umin=[-np.inf, -1, -1, -1], umax=[1, 1, 1, 1]), "must be finite"),
        (dict(umin=[-1] * 4, umax=[1, np.nan, 1, 1]), "ActuatorParams.umin/umax of wheel 1"),
        (
            dict(umin=[-1] * 4, umax=[1] * 4, max_wheel_speed=[1, 0, 1, 1]),
            "max_wheel_speed of wheel 1",
        ),
        (dict(umin=[-1] * 4, umax=[1] * 4, max_wheel_speed=[1, 1, np.nan, 1]), "max_wheel_speed"),
        (
            dict(umin=[-1] * 4, umax=[1] * 4, faults=(WheelFault(2), WheelFault(2, bias=0.1))),
            "wheel 2 has more than one fault",
        ),
        (
            dict(umin=[-1] * 4, umax=[1] * 4, faults=("not a fault",)),
            "faults[0] must be a WheelFault",
        ),
    ],
)
def test_actuator_params_validation(kwargs, needle):
    with pytest.raises(ValueError) as e:
        ActuatorParams(**kwargs)
    assert needle in str(e.value)


def test_actuator_params_are_read_only_copies():
    umin = np.full(4, -1.0)
    act = ActuatorParams(umin=umin, umax=[1, 2, 3, 4])
    umin[0] = 5.0  # the caller's array is not shared
    assert act.umin[0] == -1.0
    assert act.umax.dtype == np.float64
    with pytest.raises(ValueError):
        act.umax[0] = 0.0  # read-only: validated once, cannot go invalid later


def test_wheel_accel_rejects_wrong_shapes():
    with pytest.raises(ValueError, match="u_cmd must have shape"):
        wheel_accel(_act(), 0.0, [1.0, 2.0, 3.0], ZERO4)
    with pytest.raises(ValueError, match="wheel_speed must have shape"):
        wheel_accel(_act(), 0.0, ZERO4, np.zeros(5))


# --- the C++ structs through the binding ------------------------------------


def test_cpp_validation_names_the_field():
    with pytest.raises(ValueError, match=r"umin\[1\] must be < umax\[1\]"):
        _core.ActuatorParams(umin=[-1.0, 2.0, -1.0, -1.0], umax=[1.0, 1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match=r"max_wheel_speed\[3\] must be > 0"):
        _core.ActuatorParams(max_wheel_speed=[1.0, 1.0, 1.0, -1.0])
    with pytest.raises(ValueError, match=r"effectiveness must be in \[0, 1\], got 1.5"):
        _core.WheelFault(active=True, effectiveness=1.5)
    with pytest.raises(ValueError, match=r"end must be > onset"):
        _core.WheelFault(active=True, onset=3.0, end=1.0)
    with pytest.raises(ValueError, match=r"rate must be finite and > 0"):
        _core.WheelFault(active=True, rate=0.0)
    bad = _core.WheelFault()  # inactive: not checked
    bad.active, bad.effectiveness = True, -2.0
    with pytest.raises(ValueError, match=r"faults\[2\]\.effectiveness"):
        _core.ActuatorParams(
            faults=[_core.WheelFault(), _core.WheelFault(), bad, _core.WheelFault()]
        )
    with pytest.raises(ValueError, match="must hold 4 WheelFault"):
        _core.ActuatorParams(faults=[_core.WheelFault()] * 3)
    a = _core.ActuatorParams()
    a.umin = np.array([-1.0, 11.0, -1.0, -1.0])  # assigned after construction: validate() reports
    assert any("umin[1]" in e for e in _core.validate(a))
    assert _core.validate(_core.ActuatorParams()) == []


def test_actuator_params_to_cpp_round_trip():
    act = ActuatorParams(
        umin=UMIN,
        umax=UMAX,
        max_wheel_speed=[100.0, np.inf, 50.0, 75.0],
        faults=(
            WheelFault(wheel=3, effectiveness=0.4, bias=0.1, onset=2.0, end=9.0, rate=0.5),
            WheelFault(wheel=1, stuck=True, onset=1.0),
        ),
    )
    c = actuator_params_to_cpp(act)
    np.testing.assert_array_equal(c.umin, UMIN)
    np.testing.assert_array_equal(c.umax, UMAX)
    np.testing.assert_array_equal(c.max_wheel_speed, [100.0, np.inf, 50.0, 75.0])
    f0, f1, f2, f3 = c.faults
    assert not f0.active and not f2.active
    assert f1.active and f1.stuck and f1.onset == 1.0 and f1.end == math.inf
    assert (f3.effectiveness, f3.bias, f3.onset, f3.end, f3.rate) == (0.4, 0.1, 2.0, 9.0, 0.5)
    assert not f3.stuck
    # faults are references into the struct: editing one edits the params
    c.faults[0].active = True
    c.faults[0].bias = 0.7
    assert c.faults[0].active and c.faults[0].bias == 0.7
    out = _core.wheel_accel(c, 10.0, np.zeros(4), np.zeros(4))
    assert out.accel[0] == pytest.approx(0.7 * (1.0 - math.exp(-10.0)), rel=1e-14)
