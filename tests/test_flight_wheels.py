"""Flight-like wheels in the runs (issue #28): the ``[wheels]`` table, the
faults in torque terms, both plants, every engine and the bench.

The faults are checked against closed forms on a spacecraft whose wheels 1
and 4 share the x axis of a diagonal inertia, with no external torque: the
motion stays about x, and with M = J_xx - 2 Jw (the inertia without the two
wheels' spin), a net torque u on wheel 1 gives

    omega_dot_x = -u / M,   Omega_dot_1 = u / Jw - omega_dot_x = u (1/Jw + 1/M)

so a constant torque changes Omega_1 linearly, and a seizure brake
u = -Jw rate Omega_1 makes it decay as exp(-rate (1 + Jw/M) t).
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.model import truth
from sc_rt.model.actuators import ActuatorParams, WheelFault, actuator_params_to_cpp
from sc_rt.model.plant import plant_params_to_cpp
from sc_rt.model.plant_params import DisturbanceParams, PlantParams
from sc_rt.model.wheels import TorqueWheels, WheelFriction, WheelLimits
from sc_rt.scenario.keys import scenario_data
from sc_rt.scenario.reader import load_scenario, scenario_from_data
from sc_rt.scenario.schema import ScenarioError
from sc_rt.sim.engines import simulate

from trajcmp import lockstep_equals_sim

ROOT = Path(__file__).resolve().parent.parent
FLIGHT = ROOT / "scenarios" / "flight_wheels.toml"

JW, JXX = 0.1, 10.0
M = JXX - 2 * JW
PLANT = PlantParams(J0=np.diag([JXX, 12.0, 14.0]), dJ=np.zeros((3, 3)),
                    Cbar=np.c_[np.eye(3), [1.0, 0.0, 0.0]], Jw=np.full(4, JW), w0=0.0,
                    disturbance=DisturbanceParams(amp=np.zeros(3), freq=np.zeros(3)))


def _act(fault: WheelFault | None = None, *, coulomb: float = 0.0, command: str = "acceleration",
         lag: float = 0.0):
    friction = (WheelFriction(coulomb=coulomb),) + (WheelFriction(),) * 3
    return ActuatorParams(umin=np.full(4, -1e3), umax=np.full(4, 1e3), faults=(fault,) if fault else (),
                          wheels=TorqueWheels(friction=friction, command=command, lag=(lag,) * 4))


def _both(act, x0, u, h, n):
    """The state after each of n steps on the Python plant and on the C++ twin
    (bitwise equal), the motor state carried by both."""
    pp, ap = plant_params_to_cpp(PLANT), actuator_params_to_cpp(act)
    x, xs, out = np.array(x0, float), _core.PlantState.from_vector(np.array(x0, float)), []
    motor, motor_c = truth.new_motor(act), np.zeros(4)
    for k in range(n):
        x = truth.rk4_step(PLANT, act, k * h, x, h, u, motor)
        xs, motor_c = _core.plant_rk4_step_motor(pp, ap, k * h, xs, h, np.asarray(u, float), motor_c)
        assert np.array_equal(x, xs.to_vector()) and motor == motor_c.tolist(), k
        out.append(x.copy())
    return np.array(out)


def test_the_spin_stays_about_x():
    # the premise of the closed forms: a torque on wheel 1 moves nothing but x
    X = _both(_act(), [0, 0, 0, 0, 0, 0, 5.0, 0, 0, 0], [0.2, 0, 0, 0], 0.1, 50)
    assert np.all(X[:, [1, 2, 4, 5, 7, 8]] == 0.0)


@pytest.mark.parametrize("command, u, torque", [("acceleration", 0.5, 0.5 * JW), ("torque", 0.03, 0.03)])
def test_torque_loss_scales_the_spin_up(command, u, torque):
    # effectiveness L from long before: Y = 1 exactly, the torque is L u
    L, h, n = 0.4, 0.1, 100
    act = _act(WheelFault(wheel=0, effectiveness=L, onset=-1e3), command=command)
    X = _both(act, [0] * 10, [u, 0, 0, 0], h, n)
    t = h * np.arange(1, n + 1)
    np.testing.assert_allclose(X[:, 6], L * torque * (1 / JW + 1 / M) * t, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(X[:, 3], -L * torque / M * t, rtol=1e-12, atol=1e-16)


def test_friction_rise_multiplies_the_coulomb_spin_down():
    fc, k, h, n, O0 = 2e-3, 3.0, 0.1, 200, 50.0
    act = _act(WheelFault(wheel=0, friction=k, onset=-1e3), coulomb=fc)
    X = _both(act, [0, 0, 0, 0, 0, 0, O0, 0, 0, 0], [0, 0, 0, 0], h, n)
    t = h * np.arange(1, n + 1)
    expect = O0 - k * fc * (1 / JW + 1 / M) * t
    assert expect[-1] > 0  # still spinning: the Coulomb torque stays -k fc
    np.testing.assert_allclose(X[:, 6], expect, rtol=1e-12)


def test_a_seized_wheel_stops_with_its_time_constant():
    rate, h, n, O0 = 0.5, 0.01, 1000, 80.0
    act = _act(WheelFault(wheel=0, stuck=True, rate=rate, onset=0.0))
    X = _both(act, [0, 0, 0, 0, 0, 0, O0, 0, 0, 0], [1.0, 0, 0, 0], h, n)  # its command is ignored
    t = h * np.arange(1, n + 1)
    np.testing.assert_allclose(X[:, 6], O0 * np.exp(-rate * (1 + JW / M) * t), rtol=1e-9)
    # the momentum about x stays: the hub takes what the wheel loses
    H = (JXX - 2 * JW) * X[:, 3] + JW * (X[:, 3] + X[:, 6]) + JW * (X[:, 3] + X[:, 9])
    np.testing.assert_allclose(H, JW * O0, rtol=1e-12)


def test_a_motor_lag_delays_the_torque_by_its_time_constant():
    # a torque step c through the lag tau: m(t) = c (1 - exp(-t/tau)); the step
    # average gives the wheel the exact impulse c (t - tau (1 - exp(-t/tau)))
    c, tau, h, n = 0.04, 0.7, 0.1, 60
    act = _act(command="torque", lag=tau)
    X = _both(act, [0] * 10, [c, 0, 0, 0], h, n)
    t = h * np.arange(1, n + 1)
    impulse = c * (t - tau * -np.expm1(-t / tau))
    np.testing.assert_allclose(X[:, 6], impulse * (1 / JW + 1 / M), rtol=1e-12)
    # the row sees the motor's torque at its instant, not the command
    motor = truth.new_motor(act)
    x = np.zeros(10)
    for k in range(10):
        x = truth.rk4_step(PLANT, act, k * h, x, h, [c, 0, 0, 0], motor)
    u_sat, _, _ = truth.row(PLANT, act, 1.0, x, [c, 0, 0, 0], motor)
    assert u_sat[0] * JW == pytest.approx(c * -math.expm1(-1.0 / tau), rel=1e-12)
    # a lag without its state is refused, not ignored
    with pytest.raises(ValueError, match="motor"):
        truth.rk4_step(PLANT, act, 0.0, np.zeros(10), h, [c, 0, 0, 0])
    with pytest.raises(ValueError, match="motor"):
        _core.plant_rk4_step(plant_params_to_cpp(PLANT), actuator_params_to_cpp(act), 0.0,
                             _core.PlantState.from_vector(np.zeros(10)), h, np.array([c, 0, 0, 0]))


def _flight_text(extra: str = "", wheels_extra: str = "") -> str:
    """flight_wheels.toml with keys added to its [wheels] table (the last) and tables after it."""
    text = FLIGHT.read_text()
    assert text.rstrip().endswith("smoothly"), "[wheels] must stay the file's last table"
    return text + wheels_extra + extra


_FAULTS = """
[[faults]]
wheel = 1
stuck = true      # seized from 20 s, time constant 2 s
onset = 20.0
rate = 0.5

[[faults]]
wheel = 2
friction = 40.0   # friction rise
onset = 5.0
rate = 0.2

[[faults]]
wheel = 3
effectiveness = 0.6  # torque loss with a bias
bias = 0.05
onset = 10.0
end = 30.0
"""
# the power limit, the Stribeck term, motor lags and a start near the speed limit, so that every branch runs
_WHEELS_EXTRA = "p_max = 120.0\nstatic = 1e-3\nbeta = 2.0\nstribeck = true\nlag = [0.0, 0.3, 0.05, 1.0]\n"


def _flight_file(tmp_path: Path) -> Path:
    text = _flight_text(_FAULTS, _WHEELS_EXTRA).replace(
        "wheel_speed = [0.0, 0.0, 0.0, 0.0]", "wheel_speed = [0.0, 600.0, -620.0, 300.0]")
    path = tmp_path / "flight_faults.toml"
    path.write_text(text)
    return path


def test_engines_agree_bitwise_with_every_wheel_feature_on(tmp_path):
    scn = load_scenario(_flight_file(tmp_path))
    w = scn.actuators.wheels
    assert w.stribeck and w.limits[0].p_max == 120.0 and w.limits[0].u_max == 0.2
    assert [f.wheel for f in scn.actuators.faults] == [0, 1, 2]
    py = simulate(scn, engine="python", duration=60.0)
    cpp = simulate(scn, engine="cpp", duration=60.0)
    for name in ("sigma_BN", "omega_BN_B", "wheel_speed", "u_cmd", "u_sat", "wheel_accel", "delta2", "z1", "z2"):
        assert np.array_equal(py[name], cpp[name]), name
    # the wheel driven to its speed limit stays there: its torque command is
    # zeroed at a step's start, so it overshoots by at most a step of torque
    # (u_max h / Jw = 0.25 rad/s) and what its 0.05 s lag still gives after
    # (u_max tau / Jw = 0.13 rad/s)
    omega_max = w.limits[2].omega_max
    top = np.abs(py["wheel_speed"][:, 2]).max()
    assert omega_max - 1.0 < top < omega_max + 0.25 + 0.13, top
    # the seized wheel ends near rest
    assert abs(py["wheel_speed"][-1, 0]) < 1.0


def test_the_shipped_flight_wheels_scenario_reaches_the_speed_limit():
    scn = load_scenario(FLIGHT)
    run = simulate(scn, engine="cpp", law="dsc")
    omega_max = scn.actuators.wheels.limits[0].omega_max
    assert omega_max == pytest.approx(2 * math.pi * 100.0)  # 6000 rpm
    top = np.abs(run["wheel_speed"]).max()
    assert omega_max <= top < omega_max + 0.3
    assert run.meta.max_wheel_speed == (omega_max,) * 4  # drawn as the limit in the wheel figure


def test_the_unsampled_engine_refuses_flight_wheels():
    with pytest.raises(ValueError, match=r"\[wheels\]"):
        simulate(load_scenario(FLIGHT), engine="unsampled", duration=1.0)


def test_wheels_round_trip_through_scenario_data(tmp_path):
    scn = load_scenario(_flight_file(tmp_path))
    again = scenario_from_data(scenario_data(scn), scn.path)
    assert again.actuators.wheels == scn.actuators.wheels
    assert again.actuators.faults == scn.actuators.faults


_FAULT_TOO_FAST = "[[faults]]\nwheel = 1\nstuck = true\nonset = 1.0\nrate = 30.0\n"


@pytest.mark.parametrize("edit, key, message", [
    (('preset = "HR16"', 'preset = "HR99"'), "wheels.preset", "preset"),
    ("u_max = -0.1\n", "wheels.u_max", ">= 0"),
    (('command = "acceleration"', 'command = "speed"'), "wheels.command", "command"),
    ("coulomb = [1e-3, 1e-3]\n", "wheels.coulomb", "4 numbers"),
    ("stribeck = true\n", "wheels.stribeck", "beta > 0"),
    ("u_min = 0.5\n", "wheels.u_min", "u_max"),
    ("lag = -1.0\n", "wheels.lag", ">= 0"),
    (("", _FAULT_TOO_FAST), "faults[0].rate", "unstable"),
])
def test_bad_wheel_values_exit_2_naming_key_and_line(tmp_path, edit, key, message):
    """``edit``: keys added to [wheels], or (old, new) a line replaced ("", new: a table appended)."""
    path = tmp_path / "bad.toml"
    if isinstance(edit, str):
        path.write_text(_flight_text(wheels_extra=edit))
    elif edit[0]:
        assert edit[0] in _flight_text()
        path.write_text(_flight_text().replace(edit[0], edit[1], 1))
    else:
        path.write_text(_flight_text(extra=edit[1]))
    with pytest.raises(ScenarioError) as e:
        load_scenario(path)
    (hit,) = [x for x in e.value.errors if x.key == key]
    assert message in hit.message and hit.line is not None
    lines = path.read_text().splitlines()
    assert key.split(".")[-1].split("[")[0] in lines[hit.line - 1] or key.startswith("faults")
    if key == "wheels.u_max":  # the command line says the same (one spawn: the others only load)
        r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", str(path), "--out", str(tmp_path / "o")],
                           capture_output=True, text=True, cwd=tmp_path)
        assert r.returncode == 2 and f"{path}:{hit.line}" in r.stderr and key in r.stderr
        assert not (tmp_path / "o").exists()


def test_a_built_in_law_on_torque_wheels_is_converted_not_refused(tmp_path):
    # the built-in laws command accelerations: on wheels taking a torque the controller converts
    # (torque = Jw a; tests/test_law_command.py checks it row by row), where it used to refuse them
    path = tmp_path / "torque.toml"
    path.write_text(_flight_text().replace('command = "acceleration"', 'command = "torque"', 1))
    scn = load_scenario(path)
    assert scn.actuators.wheels.command == "torque"
    from sc_rt.scenario.overrides import with_overrides

    assert with_overrides(scn, law="pd").run.controller == "pd"  # sim --law pd
    ctl = _core.Controller(scn.core_config())
    assert ctl.law_command == "acceleration" and ctl.command_converted


def test_a_friction_rise_needs_flight_wheels(tmp_path):
    path = tmp_path / "paper.toml"
    path.write_text((ROOT / "scenarios" / "paper_fault_free.toml").read_text()
                    + "\n[[faults]]\nwheel = 2\nfriction = 2.0\nonset = 1.0\n")
    with pytest.raises(ScenarioError) as e:
        load_scenario(path)
    assert any(x.key == "faults[0].friction" and "[wheels]" in x.message for x in e.value.errors)


@pytest.mark.lcm
def test_lockstep_hil_is_bitwise_sim_with_flight_wheels_and_their_faults(tmp_path):
    lockstep_equals_sim(_flight_file(tmp_path), tmp_path / "hil", 40.0)


def test_a_flight_wheels_campaign_disperses_a_wheel_key(tmp_path):
    from sc_rt.studies.campaign import plan_campaign, Dispersion, draw_run, run_one

    path = tmp_path / "mc.toml"
    path.write_text(_flight_text(extra=(
        "\n[montecarlo]\n\n[[montecarlo.disperse]]\nkey = \"wheels.coulomb\"\ndist = \"uniform\"\n"
        "low = 1e-4\nhigh = 1e-2\napply = \"set\"\n")).replace("duration = 4000.0", "duration = 200.0"))
    scn = load_scenario(path)
    campaign = plan_campaign(scn, Dispersion(), seed=5)
    drawn = [draw_run(scn, Dispersion(), 5, i)[0].actuators.wheels.friction for i in range(3)]
    coulombs = {f.coulomb for run in drawn for f in run}
    assert len(coulombs) == 12 and all(1e-4 <= c <= 1e-2 for c in coulombs)
    rows = [run_one(campaign, i) for i in range(2)]
    assert [r["steps"] for r in rows] == [2001, 2001]
    drawn_c = [r[f"wheels.coulomb[{i}]"] for r in rows for i in range(4)]
    assert len(set(drawn_c)) == 8 and all(1e-4 <= c <= 1e-2 for c in drawn_c)
    assert all(r["finite"] for r in rows)


def test_torque_wheels_validate():
    with pytest.raises(ValueError, match="command"):
        TorqueWheels(command="speed")
    with pytest.raises(ValueError, match="u_max"):
        TorqueWheels(limits=(WheelLimits(u_max=-1.0),) + (WheelLimits(),) * 3)
    with pytest.raises(ValueError, match="friction"):
        ActuatorParams(umin=np.full(4, -1.0), umax=np.full(4, 1.0), faults=(WheelFault(wheel=0, friction=2.0),))
    with pytest.raises(ValueError, match="friction"):
        _core.ActuatorParams(faults=[_core.WheelFault(active=True, friction=2.0)] + [_core.WheelFault()] * 3)
