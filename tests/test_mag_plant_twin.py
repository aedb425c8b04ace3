"""The magnetic torque in both plants (issue 43, item 3): the Python plant and
its C++ twin bit for bit with a residual dipole and a held magnetorquer
dipole, for the paper's wheels and torque-commanded ones, and the two
engines bit for bit with a scenario's ``[environment] residual_dipole``;
a zero dipole leaves the plant bitwise as it was; the scenario keys read and
refused as docs/SCENARIOS.md says; lockstep HIL bitwise sim with a residual
dipole and a stuck rod. (All fail on the old main: no ``residual_dipole``,
``field_model`` nor ``dipole_B``.)"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.model.actuators import ActuatorParams, WheelFault, actuator_params_to_cpp
from sc_rt.model.orbit import R_EARTH, OrbitParams
from sc_rt.model.plant import derivative, lumped_disturbance, plant_params_to_cpp, rk4_step
from sc_rt.model.plant_params import PlantParams
from sc_rt.model.torque_plant import TorquePlant, TorqueWheels, torque_plant_to_cpp
from sc_rt.model.truth import new_motor
from sc_rt.model.truth import rk4_step as truth_step
from sc_rt.model.truth import row as truth_row
from sc_rt.model.wheels import WheelFriction, WheelLimits
from sc_rt.scenario.reader import scenario_from_data
from sc_rt.scenario.schema import ScenarioError
from sc_rt.scenario.shipped import resolve

ORBIT = OrbitParams(a=R_EARTH + 500e3, e=0.01, i=math.radians(51.6), raan=0.3, argp=1.1, M0=0.2, j2=True)
X0 = np.array([0.1, -0.2, 0.3, 0.01, -0.02, 0.015, 10.0, -20.0, 30.0, 5.0])
RES = np.array([0.3, -0.5, 1.2])  # [A m^2]


def _plant(field="igrf", res=RES, orbit=ORBIT, **kw) -> PlantParams:
    base = dict(J0=np.diag([10.0, 15.0, 20.0]), dJ=np.diag([2.0, -1.0, 2.0]),
                Cbar=np.c_[np.eye(3), np.ones(3) / math.sqrt(3.0)], Jw=np.full(4, 0.338), w0=0.0011)
    base.update(kw)
    return PlantParams(**base, orbit=orbit, field_model=field, residual_dipole=res)


def _dipole(t: float) -> list[float]:
    """A magnetorquer body dipole [A m^2] that changes from step to step."""
    return [20.0 * math.sin(0.01 * t), -15.0, 10.0 * math.cos(0.02 * t)]


@pytest.mark.parametrize("field", ["igrf", "dipole", "wmm2025"])
def test_paper_wheel_plant_with_dipoles_is_bit_identical_in_python_and_cpp(field):
    p = _plant(field)
    act = ActuatorParams(umin=np.full(4, -7.0), umax=np.full(4, 10.0), max_wheel_speed=np.full(4, 400.0),
                         faults=(WheelFault(wheel=1, effectiveness=0.3, onset=20.0),))
    pc, ac = plant_params_to_cpp(p), actuator_params_to_cpp(act)
    assert pc.field_nmax == {"igrf": 13, "dipole": 1, "wmm2025": 12}[field] and list(pc.residual_dipole) == list(RES)
    x_py, x_c = X0.copy(), X0.copy()
    h = 0.1
    for k in range(600):
        t = 86000.0 + k * h
        u = [math.sin(0.01 * t), 0.5, -0.3 * math.cos(0.02 * t), 0.1]
        m = _dipole(t) if k % 3 else None  # None: the residual dipole alone
        x_py = rk4_step(p, act, t, x_py, h, u, dipole_B=m)
        x_c = _core.plant_rk4_step(pc, ac, t, _core.PlantState.from_vector(x_c), h, np.asarray(u, float),
                                   dipole_B=m).to_vector()
        assert np.array_equal(x_py, x_c), f"step {k}"
    acc = np.array([0.3, -0.2, 0.1, 0.0])
    xs = _core.PlantState.from_vector(X0)
    m = _dipole(3.0)
    assert np.array_equal(derivative(12.5, X0, acc, p, dipole_B=m),
                          _core.plant_derivative(pc, 12.5, xs, acc, dipole_B=m).to_vector())
    assert np.array_equal(lumped_disturbance(p, 12.5, X0, acc, acc), _core.lumped_disturbance(pc, 12.5, xs, acc, acc))


def test_torque_wheel_plant_with_dipoles_is_bit_identical_in_python_and_cpp():
    p = _plant()
    wheels = TorqueWheels(limits=tuple(WheelLimits(u_max=0.2, omega_max=600.0) for _ in range(4)),
                          friction=tuple(WheelFriction(coulomb=5e-4, viscous=1e-6) for _ in range(4)))
    act = ActuatorParams(umin=np.full(4, -7.0), umax=np.full(4, 10.0), wheels=wheels,
                         faults=(WheelFault(wheel=2, effectiveness=0.5, onset=3010.0),))
    pc, ac = plant_params_to_cpp(p), actuator_params_to_cpp(act)
    # the residual dipole alone, through the TorquePlant classes
    py, cpp = TorquePlant(p, wheels), torque_plant_to_cpp(p, wheels)
    x_py, x_c = X0.copy(), X0.copy()
    for k in range(200):
        t = 3000.0 + 0.1 * k
        u = np.array([0.1 * math.sin(0.05 * t), -0.05, 0.02, 0.0])
        x_py = py.step(t, x_py, 0.1, u)
        x_c = cpp.step(t, x_c, 0.1, u)
        assert np.array_equal(x_py, x_c), f"step {k}"
    # with a held magnetorquer dipole, through the run's step (truth.rk4_step / plant_rk4_step_motor)
    x_py, x_c = X0.copy(), X0.copy()
    mot_py, mot_c = new_motor(act), np.zeros(4)
    for k in range(200):
        t = 3000.0 + 0.1 * k
        u = [0.5 * math.sin(0.05 * t), -0.2, 0.1, 0.0]
        m = _dipole(t)
        x_py = truth_step(p, act, t, x_py, 0.1, u, mot_py, dipole_B=m)
        xs, mot_c = _core.plant_rk4_step_motor(pc, ac, t, _core.PlantState.from_vector(x_c), 0.1,
                                               np.asarray(u, float), mot_c, dipole_B=m)
        x_c = xs.to_vector()
        assert np.array_equal(x_py, x_c), f"step {k}"
    # a row's wheel accelerations come from the dynamics, the residual dipole's torque in them
    u0 = np.array([0.5, 0.2, -0.3, 0.0])
    _, acc_py, _ = truth_row(p, act, 5.0, X0, u0, np.zeros(4))
    acc_c = _core.plant_row(pc, ac, 5.0, _core.PlantState.from_vector(X0), u0, np.zeros(4)).accel
    assert np.array_equal(np.asarray(acc_py), np.asarray(acc_c))


def test_a_zero_dipole_leaves_the_plant_bitwise_unchanged():
    # the engines pass a zero magnetorquer dipole until the controller commands one
    act = ActuatorParams(umin=np.full(4, -7.0), umax=np.full(4, 10.0))
    p0 = _plant(field="none", res=np.zeros(3))
    pf = _plant(field="igrf", res=np.zeros(3))
    pc = plant_params_to_cpp(pf)
    ac = actuator_params_to_cpp(act)
    u = [0.2, -0.1, 0.3, 0.0]
    ref = rk4_step(p0, act, 100.0, X0, 0.1, u)
    assert np.array_equal(rk4_step(pf, act, 100.0, X0, 0.1, u, dipole_B=[0.0, 0.0, 0.0]), ref)
    assert np.array_equal(_core.plant_rk4_step(pc, ac, 100.0, _core.PlantState.from_vector(X0), 0.1,
                                               np.asarray(u, float), dipole_B=np.zeros(3)).to_vector(), ref)
    # and a dipole that cancels the residual one is no torque either
    pr = _plant(field="igrf")
    assert np.array_equal(rk4_step(pr, act, 100.0, X0, 0.1, u, dipole_B=-RES), ref)


def _scenario_data(extra: str) -> dict:
    data = tomllib.loads(Path(resolve("paper_fault_free")).read_text() + "\n" + extra)
    data["run"]["duration"] = 20.0
    return data


def test_engines_bit_identical_with_a_residual_dipole():
    from sc_rt.sim.engines import simulate

    scn = scenario_from_data(_scenario_data(
        '[orbit]\naltitude = 550e3\ninclination = 97.6\nraan = 30\n'
        '[environment]\nfield = "igrf"\nresidual_dipole = [2.0, -1.0, 3.0]\n'), "res.toml")
    assert scn.plant.field_model == "igrf" and list(scn.plant.residual_dipole) == [2.0, -1.0, 3.0]
    py = simulate(scn, engine="python")
    cpp = simulate(scn, engine="cpp")
    for key in ("sigma_BN", "omega_BN_B", "wheel_speed"):
        assert np.array_equal(np.asarray(py[key]), np.asarray(cpp[key])), key
    # and the dipole changed the run
    none = dataclasses.replace(scn.plant, residual_dipole=np.zeros(3))
    plain = simulate(dataclasses.replace(scn, plant=none), engine="cpp")
    assert not np.array_equal(np.asarray(plain["omega_BN_B"]), np.asarray(cpp["omega_BN_B"]))


def test_residual_dipole_key_defaults_and_refusals():
    scn = scenario_from_data(_scenario_data('[orbit]\n[environment]\nfield = "dipole"\n'), "f.toml")
    assert list(scn.plant.residual_dipole) == [0.0, 0.0, 0.0] and scn.plant.field_model == "dipole"
    assert scenario_from_data(_scenario_data(""), "f.toml").plant.field_model == "none"
    with pytest.raises(ScenarioError, match=r"environment.residual_dipole = \[1, 2\]"):
        scenario_from_data(_scenario_data('[orbit]\n[environment]\nfield = "igrf"\nresidual_dipole = [1, 2]\n'),
                           "f.toml")
    with pytest.raises(ScenarioError, match="acts through the field"):
        scenario_from_data(_scenario_data('[orbit]\n[environment]\nresidual_dipole = [1, 2, 3]\n'), "f.toml")


@pytest.mark.lcm
def test_lockstep_hil_with_a_residual_dipole_and_a_stuck_rod_is_bitwise_sim(tmp_path):
    # the emulator process integrates the same magnetic torques as the offline engines
    from trajcmp import lockstep_equals_sim

    from sc_rt.scenario.reader import load_scenario
    from sc_rt.sim.engines import simulate

    path, duration = tmp_path / "mag.toml", 20.0
    path.write_text(Path(resolve("paper_faults")).read_text()
                    + '\n[orbit]\naltitude = 500e3\ninclination = 51.6\n'
                    + '[environment]\nfield = "igrf"\nresidual_dipole = [3.0, -2.0, 1.0]\n'
                    + "[magnetorquers]\naxes = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\nmax_dipole = 30\n"
                    + '[[magnetorquers.faults]]\nrod = 3\nkind = "stuck"\ndipole = 20.0\nonset = 4.0\n')
    _, sim = lockstep_equals_sim(path, tmp_path / "hil", duration, engine="cpp")
    scn = load_scenario(path)
    # and the dipoles are in it: the run without them differs
    plain = dataclasses.replace(scn.plant, residual_dipole=np.zeros(3), magnetorquers=None)
    other = simulate(dataclasses.replace(scn, plant=plain), engine="cpp", duration=duration)
    assert not np.array_equal(np.asarray(other["omega_BN_B"]), np.asarray(sim["omega_BN_B"]))
