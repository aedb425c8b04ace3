"""The plant's magnetorquer rods (issue 43, item 3): the body dipole of rod
commands through the limits and timed faults, by hand and against the core's
own ``Magnetorquers`` component; the Python and C++ rods bitwise; a stuck rod
acting in both engines bit for bit; the ``[magnetorquers]`` keys read and
refused naming the key (docs/SCENARIOS.md). All fail on the old main (no
``sc_rt.model.rods``, ``PlantRods`` nor ``[magnetorquers]``)."""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.model.rods import Magnetorquers, RodFault, rods_dipole_B, rods_to_cpp
from sc_rt.scenario.reader import scenario_from_data
from sc_rt.scenario.schema import ScenarioError
from sc_rt.scenario.shipped import resolve

S = 1.0 / math.sqrt(2.0)
AXES = np.array([[1.0, 0.0, S, 0.0], [0.0, 1.0, S, 0.0], [0.0, 0.0, 0.0, 1.0]])  # 4 rods, one at 45 deg
LIM = np.array([10.0, 20.0, 5.0, 15.0])


def test_rod_dipoles_clip_then_fault_by_hand():
    r = Magnetorquers(axes=AXES, max_dipole=LIM, faults=(
        RodFault(rod=0, kind="dead", onset=10.0),
        RodFault(rod=1, kind="stuck", dipole=7.5, onset=10.0, end=20.0),
        RodFault(rod=3, kind="reversed", onset=5.0)))
    d = [12.0, -3.0, 8.0, 4.0]
    # t = 0: no fault yet; rod 0 clipped to 10, rod 2 to 5
    assert rods_dipole_B(r, 0.0, d) == (10.0 + S * 5.0, -3.0 + S * 5.0, 4.0)
    # t = 10: rod 0 dead, rod 1 stuck at 7.5, rod 3 reversed
    assert rods_dipole_B(r, 10.0, d) == (0.0 + S * 5.0, 7.5 + S * 5.0, -4.0)
    # t = 20: rod 1's fault has ended
    assert rods_dipole_B(r, 20.0, d) == (0.0 + S * 5.0, -3.0 + S * 5.0, -4.0)
    # no command: only the stuck rod gives a dipole
    assert rods_dipole_B(r, 15.0) == (0.0, 7.5, 0.0)


def test_rod_dipoles_match_the_cores_magnetorquers_component():
    # the core's Magnetorquers (its own tests: tests/test_magnetorquer.py) with the same faults set
    faults = {0: ("dead", 0.0), 1: ("stuck", -4.0), 3: ("reversed", 0.0)}
    r = Magnetorquers(axes=AXES, max_dipole=LIM,
                      faults=tuple(RodFault(rod=i, kind=k, dipole=v) for i, (k, v) in faults.items()))
    mp = _core.MagnetorquerParams()
    mp.G_B = AXES
    mp.dipole_max = LIM
    core = _core.Magnetorquers(mp)
    kinds = {"dead": _core.RodFault.Dead, "stuck": _core.RodFault.Stuck, "reversed": _core.RodFault.Reversed}
    for i, (k, v) in faults.items():
        core.set_fault(i, kinds[k], v)
    rng = np.random.default_rng(3)
    for _ in range(50):
        d = rng.uniform(-30.0, 30.0, 4)
        out = core.update(d, np.array([1e-5, 2e-5, -3e-5]))
        np.testing.assert_allclose(rods_dipole_B(r, 1.0, d), out.m_B, rtol=1e-15, atol=1e-14)
        # and the C++ plant's rods: bitwise the Python ones
        assert np.array_equal(_core.rods_dipole_B(rods_to_cpp(r), 1.0, d), rods_dipole_B(r, 1.0, d))


def _scenario_data(extra: str) -> dict:
    data = tomllib.loads(Path(resolve("paper_fault_free")).read_text() + "\n" + extra)
    data["run"]["duration"] = 20.0
    return data


ENV = '[orbit]\naltitude = 550e3\ninclination = 97.6\n[environment]\nfield = "igrf"\n'


def test_a_stuck_rod_acts_in_both_engines_bit_for_bit():
    from sc_rt.sim.engines import simulate

    scn = scenario_from_data(_scenario_data(ENV + (
        "[magnetorquers]\naxes = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\nmax_dipole = 30\n"
        '[[magnetorquers.faults]]\nrod = 2\nkind = "stuck"\ndipole = 25.0\nonset = 5.0\n')), "rods.toml")
    r = scn.plant.magnetorquers
    assert r.n_rods == 3 and r.faults == (RodFault(rod=1, kind="stuck", dipole=25.0, onset=5.0),)
    py = simulate(scn, engine="python")
    cpp = simulate(scn, engine="cpp")
    for key in ("sigma_BN", "omega_BN_B", "wheel_speed"):
        assert np.array_equal(np.asarray(py[key]), np.asarray(cpp[key])), key
    # the stuck rod changed the run from its onset on, not before
    healthy = dataclasses.replace(scn.plant, magnetorquers=dataclasses.replace(r, faults=()))
    plain = simulate(dataclasses.replace(scn, plant=healthy), engine="cpp")
    t = np.asarray(cpp["t"])
    w, w0 = np.asarray(cpp["omega_BN_B"]), np.asarray(plain["omega_BN_B"])
    assert np.array_equal(w[t <= 5.0], w0[t <= 5.0])
    assert not np.array_equal(w[t > 5.0], w0[t > 5.0])
    # healthy rods without a command are bitwise no rods at all
    none = simulate(dataclasses.replace(scn, plant=dataclasses.replace(scn.plant, magnetorquers=None)), engine="cpp")
    assert np.array_equal(np.asarray(none["omega_BN_B"]), w0)


def test_magnetorquer_keys_read_with_their_defaults():
    scn = scenario_from_data(_scenario_data(ENV + "[magnetorquers]\nG_B = [[1, 0], [0, 0.6], [0, 0.8]]\n"
                                            "max_dipole = [5, 8]\n"), "rods.toml")
    r = scn.plant.magnetorquers
    assert r.axes.tolist() == [[1.0, 0.0], [0.0, 0.6], [0.0, 0.8]] and r.max_dipole.tolist() == [5.0, 8.0]
    assert r.faults == ()
    assert scenario_from_data(_scenario_data(ENV), "f.toml").plant.magnetorquers is None


@pytest.mark.parametrize(("extra", "needle"), [
    ("[magnetorquers]\nmax_dipole = 5\n", "the rod axes are required"),
    ("[magnetorquers]\naxes = [[1, 0, 0]]\nG_B = [[1], [0], [0]]\nmax_dipole = 5\n", "not both"),
    ("[magnetorquers]\naxes = [[1, 1, 0]]\nmax_dipole = 5\n", "rod 1 is not a unit vector"),
    ("[magnetorquers]\naxes = [[1, 0, 0], [0, 1]]\nmax_dipole = 5\n", "magnetorquers.axes"),
    ("[magnetorquers]\naxes = [[1, 0, 0]]\nmax_dipole = -5\n", "magnetorquers.max_dipole = -5"),
    ("[magnetorquers]\naxes = [[1, 0, 0], [0, 1, 0]]\nmax_dipole = [1, 2, 3]\n", "magnetorquers.max_dipole"),
    ('[magnetorquers]\naxes = [[1, 0, 0]]\nmax_dipole = 5\n[[magnetorquers.faults]]\nrod = 2\nkind = "dead"\n',
     "rod must be 1 to 1"),
    ('[magnetorquers]\naxes = [[1, 0, 0]]\nmax_dipole = 5\n[[magnetorquers.faults]]\nrod = 1\nkind = "melted"\n',
     "magnetorquers.faults\\[0\\].kind"),
    ('[magnetorquers]\naxes = [[1, 0, 0]]\nmax_dipole = 5\n[[magnetorquers.faults]]\nrod = 1\nkind = "dead"\n'
     "dipole = 3\n", "a stuck rod's value"),
    ('[magnetorquers]\naxes = [[1, 0, 0]]\nmax_dipole = 5\n[[magnetorquers.faults]]\nrod = 1\nkind = "dead"\n'
     "onset = 5\nend = 2\n", "end must be > onset"),
    ("[magnetorquers]\naxes = [[1, 0, 0]]\nmax_dipol = 5\n", "did you mean 'max_dipole'"),
    # a rod saturates: it cannot stick beyond its own limit (rod 2's is 8, rod 1's 5)
    ('[magnetorquers]\naxes = [[1, 0, 0], [0, 1, 0]]\nmax_dipole = [5, 8]\n[[magnetorquers.faults]]\nrod = 1\n'
     'kind = "stuck"\ndipole = -6\n', r"magnetorquers.faults\[0\].dipole = -6.*max_dipole = 5 A m\^2"),
])
def test_bad_magnetorquer_keys_are_refused_naming_the_key(extra, needle):
    with pytest.raises(ScenarioError, match=needle):
        scenario_from_data(_scenario_data(ENV + extra), "bad.toml")


def test_a_rod_stuck_within_its_limit_is_read_and_beyond_it_refused_by_the_model_too():
    rods_toml = ("[magnetorquers]\naxes = [[1, 0, 0], [0, 1, 0]]\nmax_dipole = [5, 8]\n"
                 '[[magnetorquers.faults]]\nrod = 2\nkind = "stuck"\ndipole = -8\n')
    scn = scenario_from_data(_scenario_data(ENV + rods_toml), "rods.toml")
    rods = scn.plant.magnetorquers
    assert [(f.rod, f.dipole) for f in rods.faults] == [(1, -8.0)]
    # what a live rod fault command builds (emulator/receiver.py) is checked by the model itself
    with pytest.raises(ValueError, match="rod 2 stuck at 8.5 A m\\^2, beyond its limit 8.0"):
        dataclasses.replace(rods, faults=(RodFault(rod=1, kind="stuck", dipole=8.5),))


def test_magnetorquers_need_a_field():
    with pytest.raises(ScenarioError, match="act through the field"):
        scenario_from_data(_scenario_data("[magnetorquers]\naxes = [[1, 0, 0]]\nmax_dipole = 5\n"), "f.toml")


def test_torque_wheel_plant_with_a_stuck_rod_is_bit_identical_in_python_and_cpp():
    from sc_rt.model.actuators import ActuatorParams, actuator_params_to_cpp
    from sc_rt.model.orbit import R_EARTH, OrbitParams
    from sc_rt.model.plant import plant_params_to_cpp
    from sc_rt.model.plant_params import PlantParams
    from sc_rt.model.truth import new_motor, rk4_step, row
    from sc_rt.model.wheels import TorqueWheels, WheelLimits

    rods = Magnetorquers(axes=AXES, max_dipole=LIM, faults=(RodFault(rod=3, kind="stuck", dipole=12.0, onset=2.0),))
    p = PlantParams(J0=np.diag([10.0, 15.0, 20.0]), dJ=np.zeros((3, 3)), Cbar=np.c_[np.eye(3), np.ones(3) / 3**0.5],
                    Jw=np.full(4, 0.1), w0=0.0, orbit=OrbitParams(a=R_EARTH + 600e3, i=1.0), field_model="dipole",
                    magnetorquers=rods)
    act = ActuatorParams(umin=np.full(4, -7.0), umax=np.full(4, 10.0),
                         wheels=TorqueWheels(limits=tuple(WheelLimits(u_max=0.1) for _ in range(4))))
    pc, ac = plant_params_to_cpp(p), actuator_params_to_cpp(act)
    x_py = x_c = np.array([0.1, 0.2, -0.1, 0.01, 0.0, -0.02, 5.0, 0.0, -5.0, 1.0])
    mot_py, mot_c = new_motor(act), np.zeros(4)
    for k in range(60):
        t = 0.1 * k
        u = [0.05, -0.02, 0.01, 0.0]
        x_py = rk4_step(p, act, t, x_py, 0.1, u, mot_py)
        xs, mot_c = _core.plant_rk4_step_motor(pc, ac, t, _core.PlantState.from_vector(x_c), 0.1,
                                               np.asarray(u, float), mot_c)
        x_c = xs.to_vector()
        assert np.array_equal(x_py, x_c), k
    _, acc, _ = row(p, act, 5.0, x_py, u, np.zeros(4))
    assert np.array_equal(np.asarray(acc), _core.plant_row(pc, ac, 5.0, xs, np.asarray(u, float), np.zeros(4)).accel)
    # the stuck rod's torque is in the row's wheel accelerations (through omega_dot)
    _, acc0, _ = row(dataclasses.replace(p, magnetorquers=None), act, 5.0, x_py, u, np.zeros(4))
    assert not np.array_equal(np.asarray(acc), np.asarray(acc0))


def test_a_scenario_with_orbit_field_and_rods_round_trips_through_its_data():
    # what Monte Carlo draws into and a campaign's workers rebuild from (sc_rt.scenario.keys):
    # the orbit, the field, the residual dipole and the rods with their faults come back bit for bit
    from sc_rt.scenario.keys import get_key, scenario_data, set_key

    scn = scenario_from_data(_scenario_data(
        "[orbit]\naltitude = 550e3\ne = 0.001\ninclination = 97.6\nraan = 33.3\nargp = 12.0\n"
        "true_anomaly = 41.0\nepoch = 2026-03-20T12:00:00Z\nj2 = true\n"
        '[environment]\nfield = "dipole"\nresidual_dipole = [0.1, -0.2, 0.3]\n'
        "[magnetorquers]\naxes = [[0.6, 0.8, 0], [0, 0, 1], [0.70710678, 0.70710678, 0]]\nmax_dipole = [5, 6, 7]\n"
        '[[magnetorquers.faults]]\nrod = 1\nkind = "stuck"\ndipole = -2.5\nonset = 3.0\nend = 9.0\n'
        '[[magnetorquers.faults]]\nrod = 3\nkind = "reversed"\n'), "rt.toml")
    data = scenario_data(scn)
    back = scenario_from_data(data, "rt.toml")
    p, q = scn.plant, back.plant
    assert q.orbit == p.orbit and q.field_model == p.field_model == "dipole"
    assert np.array_equal(q.residual_dipole, p.residual_dipole)
    assert np.array_equal(q.magnetorquers.axes, p.magnetorquers.axes)
    assert np.array_equal(q.magnetorquers.max_dipole, p.magnetorquers.max_dipole)
    assert q.magnetorquers.faults == p.magnetorquers.faults
    # and a Monte Carlo key can disperse the residual dipole
    set_key(data, "environment.residual_dipole", [1.0, 2.0, 3.0])
    assert get_key(data, "environment.residual_dipole") == [1.0, 2.0, 3.0]
    assert scenario_from_data(data, "rt.toml").plant.residual_dipole.tolist() == [1.0, 2.0, 3.0]
