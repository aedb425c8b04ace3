"""The law model's wheel conversions against closed forms, on both wheel
kinds (issue 39): ``wheel_command(a)`` is the command the wheels take for the
wheel accelerations a (a itself on acceleration-commanded wheels, Jw a on
torque-commanded ones), ``wheels_for_torque(tau)`` the accelerations whose
reaction is the body torque tau (-Cbar (Jw a) = tau). Checked through a
Python law that calls them as a user's law does, with the spacecraft's Jw
and Cbar taken from the scenario, not from the model under test."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sc_rt import _core, load_scenario
from sc_rt.pylaw import register

A = np.array([1.0, -2.0, 0.5, 3.0])  # [rad/s^2]
TAU = np.array([0.01, -0.02, 0.03])  # [N m]


class _Probe:
    """Records what the model's conversions give, commands nothing."""

    seen: dict = {}

    def __init__(self, setup):
        m = setup.model
        _Probe.seen = {"cmd": np.array(m.wheel_command(A)), "u_tau": np.array(m.wheels_for_torque(TAU)),
                       "torque": bool(m.wheel_torque_command)}

    def reset(self, inp):
        pass

    def step(self, inp):
        return np.zeros(4)


def _scenario(command: str):
    scn = load_scenario("flight_wheels")
    wheels = dataclasses.replace(scn.actuators.wheels, command=command)
    return dataclasses.replace(scn, actuators=dataclasses.replace(scn.actuators, wheels=wheels))


@pytest.mark.parametrize("command", ["acceleration", "torque"])
def test_wheel_command_and_wheels_for_torque_against_closed_forms(command):
    scn = _scenario(command)
    cfg = scn.core_config()
    cfg.law = register(_Probe)
    cfg.law_params = []
    _core.Controller(cfg)  # constructs the law with the run's model
    seen = _Probe.seen
    Jw = np.broadcast_to(np.asarray(scn.plant.Jw, float), (4,))
    Cbar = np.asarray(scn.plant.Cbar, float)
    assert seen["torque"] == (command == "torque")
    expected = Jw * A if command == "torque" else A
    np.testing.assert_allclose(seen["cmd"], expected, rtol=1e-15, atol=0)
    # the accelerations' reaction on the body is the torque asked for
    np.testing.assert_allclose(-Cbar @ (Jw * seen["u_tau"]), TAU, rtol=0, atol=1e-14)
