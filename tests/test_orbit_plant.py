"""The orbit's gravity gradient in both plants (issue 43, item 1): the
Python plant and its C++ twin bit for bit with an ``[orbit]``, for the
paper's wheels and for torque-commanded ones, through the engines too; the
orbit's torque is the one the plant integrates; the scenario's ``[orbit]``
keys read and refused as documented (docs/SCENARIOS.md)."""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.model.actuators import ActuatorParams, WheelFault, actuator_params_to_cpp
from sc_rt.model.orbit import MU_EARTH, R_EARTH, OrbitParams, gravity_gradient_orbit, orbit_state
from sc_rt.model.plant import derivative, lumped_disturbance, plant_params_to_cpp, rk4_step
from sc_rt.model.plant_params import PlantParams
from sc_rt.model.torque_plant import TorquePlant, TorqueWheels, torque_plant_to_cpp
from sc_rt.model.wheels import WheelFriction, WheelLimits
from sc_rt.scenario.reader import load_scenario, scenario_from_data
from sc_rt.scenario.schema import ScenarioError
from sc_rt.scenario.shipped import resolve

ORBIT = OrbitParams(a=R_EARTH + 500e3, e=0.01, i=math.radians(51.6), raan=0.3, argp=1.1, M0=0.2, j2=True)
X0 = np.array([0.1, -0.2, 0.3, 0.01, -0.02, 0.015, 10.0, -20.0, 30.0, 5.0])


def _plant(orbit=ORBIT, **kw) -> PlantParams:
    base = dict(J0=np.diag([10.0, 15.0, 20.0]), dJ=np.diag([2.0, -1.0, 2.0]),
                Cbar=np.c_[np.eye(3), np.ones(3) / math.sqrt(3.0)], Jw=np.full(4, 0.338), w0=0.0011)
    base.update(kw)
    return PlantParams(**base, orbit=orbit)


def _cpp_step(pc, ac, t, x, h, u):
    return _core.plant_rk4_step(pc, ac, t, _core.PlantState.from_vector(x), h, np.asarray(u, float)).to_vector()


def test_paper_wheel_plant_with_an_orbit_is_bit_identical_in_python_and_cpp():
    p = _plant()
    act = ActuatorParams(umin=np.full(4, -7.0), umax=np.full(4, 10.0), max_wheel_speed=np.full(4, 400.0),
                         faults=(WheelFault(wheel=1, effectiveness=0.3, onset=20.0),))
    pc, ac = plant_params_to_cpp(p), actuator_params_to_cpp(act)
    assert pc.orbit.enabled and pc.orbit.a == ORBIT.a and pc.orbit.j2
    x_py = X0.copy()
    x_c = X0.copy()
    h = 0.1
    for k in range(1500):
        t = 86000.0 + k * h  # late in a day: the orbit has turned many times
        u = [math.sin(0.01 * t), 0.5, -0.3 * math.cos(0.02 * t), 0.1]
        x_py = rk4_step(p, act, t, x_py, h, u)
        x_c = _cpp_step(pc, ac, t, x_c, h, u)
        assert np.array_equal(x_py, x_c), f"step {k}"
    acc = np.array([0.3, -0.2, 0.1, 0.0])
    assert np.array_equal(derivative(12.5, X0, acc, p),
                          _core.plant_derivative(pc, 12.5, _core.PlantState.from_vector(X0), acc).to_vector())
    assert np.array_equal(lumped_disturbance(p, 12.5, X0, acc, acc),
                          _core.lumped_disturbance(pc, 12.5, _core.PlantState.from_vector(X0), acc, acc))


def test_torque_wheel_plant_with_an_orbit_is_bit_identical_in_python_and_cpp():
    p = _plant()
    wheels = TorqueWheels(limits=tuple(WheelLimits(u_max=0.2, omega_max=600.0) for _ in range(4)),
                          friction=tuple(WheelFriction(coulomb=5e-4, viscous=1e-6) for _ in range(4)))
    py, cpp = TorquePlant(p, wheels), torque_plant_to_cpp(p, wheels)
    x_py = X0.copy()
    x_c = X0.copy()
    for k in range(500):
        t = 3000.0 + 0.1 * k
        u = np.array([0.1 * math.sin(0.05 * t), -0.05, 0.02, 0.0])
        x_py = py.step(t, x_py, 0.1, u)
        x_c = cpp.step(t, x_c, 0.1, u)
        assert np.array_equal(x_py, x_c), f"step {k}"


def test_the_plant_integrates_the_orbits_gravity_gradient():
    # the body-rate derivative of a plant with the orbit minus one without any
    # gravity gradient is J^-1 u_g of the orbit's position at t (numpy)
    p = _plant()
    p0 = _plant(orbit=None, w0=0.0)
    acc = np.zeros(4)
    for t in (0.0, 1000.0, 4000.0):
        diff = derivative(t, X0, acc, p)[3:6] - derivative(t, X0, acc, p0)[3:6]
        r, _ = orbit_state(ORBIT, t)
        ug = gravity_gradient_orbit(p.J, X0[0:3], r)
        np.testing.assert_allclose(diff, np.linalg.solve(p.J, ug), rtol=1e-9, atol=1e-20)
        assert np.linalg.norm(ug) > 1e-6  # [N m]: a real torque at this attitude


def test_orbit_plant_equals_the_constant_rate_plant_where_nadir_is_e3():
    # a polar circular orbit passing the north pole at t = 0 and w0 = sqrt(mu / a^3)
    a = R_EARTH + 600e3
    w0 = math.sqrt(MU_EARTH / a**3)
    po = _plant(orbit=OrbitParams(a=a, i=math.pi / 2, M0=math.pi / 2), w0=w0)
    pw = _plant(orbit=None, w0=w0)
    acc = np.array([0.1, 0.0, -0.1, 0.2])
    np.testing.assert_allclose(derivative(0.0, X0, acc, po), derivative(0.0, X0, acc, pw), rtol=1e-12, atol=1e-18)


def _scenario_data(extra: str) -> dict:
    data = tomllib.loads(Path(resolve("paper_fault_free")).read_text() + "\n" + extra)
    data["run"]["duration"] = 20.0
    return data


def test_engines_bit_identical_with_an_orbit_scenario():
    from sc_rt.sim.engines import simulate

    scn = scenario_from_data(_scenario_data(
        '[orbit]\naltitude = 550e3\ninclination = 97.6\nraan = 30\ntrue_anomaly = 10\n'
        'epoch = 2026-03-20T12:00:00Z\nj2 = true\n'), "orbit.toml")
    assert scn.plant.orbit is not None and scn.plant.orbit.j2
    py = simulate(scn, engine="python")
    cpp = simulate(scn, engine="cpp")
    for key in ("sigma_BN", "omega_BN_B", "wheel_speed"):
        assert np.array_equal(np.asarray(py[key]), np.asarray(cpp[key])), key
    # and the orbit changed the run: the constant-rate plant's differs
    plain = simulate(dataclasses.replace(scn, plant=dataclasses.replace(scn.plant, orbit=None)), engine="cpp")
    assert not np.array_equal(np.asarray(plain["omega_BN_B"]), np.asarray(cpp["omega_BN_B"]))


def test_orbit_keys_read_with_their_units_and_defaults():
    scn = scenario_from_data(_scenario_data("[orbit]\n"), "orbit.toml")
    o = scn.plant.orbit
    assert (o.a, o.e, o.i, o.M0, o.j2) == (R_EARTH + 400e3, 0.0, 0.0, 0.0, False)
    assert o.jd_epoch == 2461041.5  # 2026-01-01T00:00:00Z
    scn = scenario_from_data(_scenario_data(
        '[orbit]\na = 7000e3\ne = 0.01\ninclination = 90\nmean_anomaly = 180\njd_epoch = 2451545.0\n'), "o.toml")
    o = scn.plant.orbit
    assert (o.a, o.e, o.i, o.M0, o.jd_epoch) == (7000e3, 0.01, math.pi / 2, math.pi, 2451545.0)
    assert scenario_from_data(_scenario_data(""), "o.toml").plant.orbit is None


@pytest.mark.parametrize(("extra", "needle"), [
    ("[orbit]\ne = 1.5\n", "orbit.e = 1.5"),
    ("[orbit]\naltitude = -5\n", "orbit.altitude = -5"),
    ("[orbit]\na = 6000e3\n", "perigee radius"),
    ("[orbit]\na = 7000e3\naltitude = 500e3\n", "a or altitude, not both"),
    ('[orbit]\nepoch = "yesterday"\n', "orbit.epoch"),
    ("[orbit]\ninclinaton = 10\n", "did you mean 'inclination'"),
    ("[orbit]\ntrue_anomaly = 1\nmean_anomaly = 2\n", "not both"),
])
def test_bad_orbit_keys_are_refused_naming_the_key(extra, needle):
    with pytest.raises(ScenarioError, match=needle.replace("(", r"\(")):
        scenario_from_data(_scenario_data(extra), "bad.toml")


def test_bad_orbit_key_in_a_file_exits_2_with_its_line(tmp_path):
    f = tmp_path / "bad_orbit.toml"
    f.write_text(Path(resolve("paper_fault_free")).read_text() + "\n[orbit]\ne = 2.0\n")
    with pytest.raises(ScenarioError) as err:
        load_scenario(f)
    assert "orbit.e = 2.0" in str(err.value) and "bad_orbit.toml:" in str(err.value)


def test_environment_field_key_reads_and_needs_an_orbit():
    from sc_rt.model.field import field_for

    scn = scenario_from_data(_scenario_data('[orbit]\n[environment]\nfield = "igrf"\n'), "f.toml")
    assert scn.field_model == "igrf"
    f = field_for(scn.field_model, scn.plant.orbit.jd_epoch)
    r, _ = orbit_state(scn.plant.orbit, 0.0)
    assert 15e3 < np.linalg.norm(f.B_eci(r, scn.plant.orbit.jd_epoch, 0.0)) < 65e3  # [nT] at 400 km
    assert scenario_from_data(_scenario_data(""), "f.toml").field_model == "none"
    with pytest.raises(ScenarioError, match='environment.field = "wmm"'):
        scenario_from_data(_scenario_data('[orbit]\n[environment]\nfield = "wmm"\n'), "f.toml")
    with pytest.raises(ScenarioError, match=r"give an \[orbit\] table too"):
        scenario_from_data(_scenario_data('[environment]\nfield = "dipole"\n'), "f.toml")


@pytest.mark.lcm
def test_lockstep_hil_with_an_orbit_is_bitwise_sim(tmp_path):
    # the emulator process integrates the same orbit plant as the offline engines
    from trajcmp import lockstep_equals_sim

    path = tmp_path / "orbit.toml"
    path.write_text(Path(resolve("paper_faults")).read_text()
                    + "\n[orbit]\naltitude = 500e3\ne = 0.01\ninclination = 51.6\nj2 = true\n")
    lockstep_equals_sim(path, tmp_path / "hil", 20.0, engine="cpp")
