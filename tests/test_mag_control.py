"""The controller's magnetic part in the loop (issue 43, items 4 and 5):
the momentum manager and B-dot beside the attitude law, in both offline
engines (docs/MODEL.md section 17).

Each test checks against something the code under test does not compute:
the other engine (bitwise), the integral of a constant torque (a closed
form), numpy's own m x B from the record. All fail on the old main, which
has no [momentum] / [bdot] tables (ScenarioError: unknown table).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from magscn import BIAS, H0, MOMENTUM, STUCK, mag_scenario
from sc_rt import simulate

def _same(a, b) -> list[str]:
    """The fields where two runs differ (NaN equal to NaN: fields no producer fills)."""
    return [k for k in a.trajectory if not np.array_equal(np.asarray(a[k]), np.asarray(b[k]),
                                                          equal_nan=np.asarray(a[k]).dtype.kind == "f")]




@pytest.mark.parametrize("extra, kw", [
    (MOMENTUM + STUCK, {"wheel_speed": tuple(10 * v for v in H0)}),
    (MOMENTUM.replace('"cross_product"', '"continuous"'), {"wheel_speed": tuple(10 * v for v in H0)}),
    ('[bdot]\nderivative = "difference"\nfilter_tau = 0.3\nrate_on = 0.0466\nrate_off = 0.0464\n' + STUCK,
     {"omega": (0.03, -0.03, 0.02)}),
])
def test_cpp_and_python_engines_are_bitwise_equal(extra, kw):
    """Every field of the two engines' runs equal with ``==``, with the
    manager unloading (either law) and with B-dot detumbling and switching,
    a stuck rod included."""
    scn = mag_scenario(extra, duration=40.0, **kw)
    py, cpp = simulate(scn, engine="python"), simulate(scn, engine="cpp")
    assert len(py.t) == len(cpp.t) == 401
    assert _same(py, cpp) == []
    assert np.any(cpp["m_B_cmd"] != 0.0)  # the rods were driven
    if "[bdot]" in extra:
        modes = cpp["detumble_mode"]
        assert modes[0] == 0 and modes[-1] == 1  # detumbled, then the law took over
    else:
        assert cpp["unloading"][0] == 1


def test_every_run_without_magnetic_control_keeps_its_rows():
    """A scenario with rods but no [momentum]/[bdot]: the magnetic fields at
    their fill (NaN, -1), the controller's rows those of a run without them."""
    run = simulate(mag_scenario("", duration=5.0), engine="cpp")
    assert np.all(np.isnan(run["rod_dipole_cmd"])) and np.all(np.isnan(run["B_B"]))
    assert np.all(run["unloading"] == -1) and np.all(run["detumble_mode"] == -1)


def _unloading_runs(duration):
    on = mag_scenario(MOMENTUM, duration=duration, gravity_gradient=False)
    off = dataclasses.replace(on, magnetic_control=None)
    return simulate(off, engine="cpp"), simulate(on, engine="cpp")


def test_the_manager_keeps_the_wheels_unloaded_over_orbits():
    """Three orbits (17 000 s) of a 1e-4 N m secular torque held inertially:
    without the manager the wheels take the torque's integral (their
    momentum in N is -(bias) t, a closed form, to 2 %), with it their
    momentum stays below the on band (0.5 N m s + what one period adds);
    the pointing holds either way, and the unloading switches are in the
    record."""
    duration = 17_000.0
    off, on = _unloading_runs(duration)
    t = off.t
    # without: the wheels' momentum in B (the body held: B fixed in N) against the integral of the
    # torque, bias t (no manager: h_wheels_B is not recorded, so Cbar Jw Omega from the state)
    assert np.all(np.isnan(off["h_wheels_B"]))
    scn = mag_scenario(MOMENTUM, duration=duration)
    CJ = scn.plant.Cbar * scn.plant.Jw
    h_wheels = off["wheel_speed"] @ CJ.T
    late = t > 2000.0
    assert np.allclose(h_wheels[late], np.outer(t[late], BIAS), rtol=0.02, atol=0.01)
    assert np.linalg.norm(h_wheels[-1]) > 1.6  # 1.7 N m s: far above the on band of 0.5
    # with: bounded by the on band, unloading switched on and off
    fill = on["wheel_fill"]
    assert np.nanmax(fill) < 0.55
    u = on["unloading"]
    switches = np.flatnonzero(np.diff(u) != 0)
    assert len(switches) >= 2 and u[switches[0] + 1] == 1 and u[switches[1] + 1] == 0
    for run in (off, on):
        err = 4 * np.degrees(np.arctan(np.linalg.norm(run["sigma_BD"][late], axis=1)))
        assert err.max() < 0.05  # [deg] the feed-forward keeps the magnetic torque off the attitude


def test_the_commanded_magnetic_torque_goes_into_the_wheels():
    """Pointing held and unloading from the start: row by row, the change of
    the wheels' momentum in B over a period equals the integral of the
    secular torque and the commanded m x B (numpy from the record: m_B_cmd,
    B_B), to the field's rotation over the period."""
    scn = mag_scenario(MOMENTUM, duration=60.0, wheel_speed=tuple(10 * v for v in H0), gravity_gradient=False)
    run = simulate(scn, engine="cpp")
    dt = 0.1
    CJ = scn.plant.Cbar * scn.plant.Jw
    h = run["wheel_speed"] @ CJ.T
    tau_mag = np.cross(run["m_B_cmd"], run["B_B"])
    assert np.all(run["unloading"] == 1)
    assert np.linalg.norm(tau_mag, axis=1).min() > 1e-4  # the unloading torque is of the secular's size
    dh = np.diff(h, axis=0) / dt
    # the body barely moves: the wheels take the external torque, dh/dt = tau_mag + bias
    want = tau_mag[:-1] + np.array(BIAS)
    rows = slice(20, None)  # after the first 2 s (the law settles the feed-forward's start)
    assert np.allclose(dh[rows], want[rows], atol=0.05 * np.abs(want).max())


class _Constant:
    """A Python law: a constant wheel acceleration, and what it was handed back."""

    name = "constant"
    seen: list = []

    def __init__(self, setup):
        pass

    def reset(self, inp) -> None:
        pass

    def step(self, inp):
        _Constant.seen.append(np.array(inp.u_sat_prev))
        return np.array([0.01, -0.02, 0.015, 0.005]), {}


def test_a_python_law_sees_none_of_the_manager():
    """Any law (here a Python one, through the core's registry) is summed
    with the manager's feed-forward before saturation, and gets its own
    command back as u_sat_prev; the sum's body torque cancels m x B
    (numpy: -Cbar Jw (u_cmd - u_law) + m_B_cmd x B_B = 0)."""
    from sc_rt import _core
    from sc_rt.pylaw import register

    scn = mag_scenario(MOMENTUM.replace("null_gain = 0.01", "null_gain = 0.0"), duration=1.0,
                       wheel_speed=tuple(10 * v for v in H0), paper_wheels=True)
    cfg = scn.core_config()
    cfg.law, cfg.law_params = register(_Constant), []
    ctl = _core.Controller(cfg)
    x = np.array([0.1, 0.2, -0.3, 0.0, 0.0, 0.0, *(10 * v for v in H0)])
    ctl.reset(_core.Measurement(0.0, x[0:3], x[3:6], x[6:10]))
    B_B = np.array([2e-5, -1e-5, 3e-5])
    _Constant.seen.clear()
    law = np.array([0.01, -0.02, 0.015, 0.005])
    for t in (0.0, 0.1, 0.2):
        c = ctl.step(_core.Measurement(t, x[0:3], x[3:6], x[6:10]), B_B)
        assert c.unloading == 1 and c.flags & 0b1111000 == 0  # unloading, no wheel saturated
        extra = np.asarray(c.u_cmd) - law
        body = -(scn.plant.Cbar * scn.plant.Jw) @ extra + np.cross(c.m_B_cmd, B_B)
        assert np.linalg.norm(body) < 1e-12 * np.linalg.norm(np.cross(c.m_B_cmd, B_B))
        assert np.linalg.norm(np.cross(c.m_B_cmd, B_B)) > 1e-5
    assert all(np.array_equal(s, law) for s in _Constant.seen[1:])  # its own command, not the sum
