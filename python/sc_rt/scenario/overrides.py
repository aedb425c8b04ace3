"""What a run of a scenario needs besides the scenario itself: CLI-style
overrides, a Monte Carlo run's drawn values, the sampling grid, the initial state. Shared by every engine
and by the emulator (one definition, so they all step the same way)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, NamedTuple

import numpy as np

from sc_rt.scenario.keys import scenario_data, set_key
from sc_rt.scenario.model import Scenario
from sc_rt.scenario.reader import scenario_from_data, with_run

__all__ = ["DRAW", "Grid", "grid", "initial_state", "with_draws", "with_overrides"]

#: The prefix of a drawn value in ``Scenario.overrides`` ("draw spacecraft.dJ"): a
#: campaign run's values, recorded as its inputs and replayed (sc_rt.plan.run).
DRAW = "draw "


class Grid(NamedTuple):
    """The sampling of a run."""

    n_ctrl: int  # control periods (rows = n_ctrl + 1)
    n_sub: int  # plant RK4 steps per control period
    h: float  # plant step [s]
    rate: float  # control rate [Hz]


def with_overrides(scn: Scenario, *, law: str | None = None, control_rate_hz: float | None = None,
                   duration: float | None = None, plant_step: float | None = None) -> Scenario:
    """The scenario with CLI-style overrides, validated like the file.

    When only the control rate changes, the plant step becomes the largest
    step that divides the new control period and does not exceed the
    scenario's (10 Hz -> 100 Hz with a 0.1 s plant step gives 0.01 s).

    Parameters
    ----------
    scn : Scenario
        The scenario (``sc_rt.load_scenario``); it is not changed.
    law : str, optional
        The control law: "dsc-ppc", "dsc", "pd", "rft" (the core's laws) or
        "plugin:PATH_OR_NAME" (a relative plugin path is taken from the
        working directory; docs/LAWS.md). None: the scenario's.
    control_rate_hz : float, optional
        [Hz] the control rate. None: the scenario's.
    duration : float, optional
        [s] the run's duration. None: the scenario's.
    plant_step : float, optional
        [s] the plant integration step; the control period must be an
        integer multiple of it. None: the scenario's, or derived from a new
        control rate as above.

    Returns
    -------
    Scenario
        A copy of ``scn`` with its ``run`` parameters replaced.

    Raises
    ------
    ScenarioError
        An override is invalid (the message names it as ``run.<key>``), the
        guidance's reference file does not cover a longer duration, or a new
        law is a built-in one on torque-commanded wheels. A plugin's or a
        Python law's load and probe happen where the run is planned
        (sc_rt.plan.law.probe_law), not here.
    """
    given = tuple((f"run.{k}", v) for k, v in (("controller", law), ("control_rate_hz", control_rate_hz),
                                                ("duration", duration), ("plant_step", plant_step))
                  if v is not None)
    if control_rate_hz is not None and plant_step is None:
        try:
            period = 1.0 / float(control_rate_hz)
            plant_step = period / math.ceil(period / scn.run.plant_step - 1e-9)
        except (ValueError, ZeroDivisionError, OverflowError, TypeError):
            plant_step = None  # the rate itself is invalid: with_run names it
    new = with_run(scn, controller=law, control_rate_hz=control_rate_hz, duration=duration,
                   plant_step=plant_step)
    # the law as resolved (a file's path made absolute): what a replay of the record runs
    given = tuple((k, new.run.controller if k == "run.controller" else v) for k, v in given)
    return dataclasses.replace(new, overrides=scn.overrides + given) if given else new


def with_draws(scn: Scenario, draws: Any, where: str = "") -> Scenario:
    """The scenario with a Monte Carlo run's drawn values, validated like the file.

    Parameters
    ----------
    scn : Scenario
        The campaign's base scenario (its plan's); it is not changed.
    draws : iterable of (str, value)
        (dotted key, value) pairs of the scenario's data
        (sc_rt.scenario.keys.scenario_data: "spacecraft.dJ",
        "faults[0].onset", "sensors.seed"), each value as the data holds it
        (a number, or nested lists of numbers).
    where : str
        Appended to the file's name in an error (" (run 4)").

    Returns
    -------
    Scenario
        The base's data with those values, read back through the file's
        checks; its ``overrides`` are the base's followed by one
        ``("draw KEY", value)`` pair per value (what the run records).

    Raises
    ------
    ScenarioError
        The values make an invalid scenario (a draw to redraw, or a run
        without a valid draw).
    KeyError
        A key the base's data does not hold (draws of another scenario).
    """
    draws = tuple((str(k), v) for k, v in draws)
    data = scenario_data(scn)
    for key, value in draws:
        try:
            set_key(data, key, value)
        except (KeyError, IndexError, TypeError):
            raise KeyError(key) from None
    out = scenario_from_data(data, scn.path, where)
    return dataclasses.replace(out, path=scn.path,
                               overrides=scn.overrides + tuple((DRAW + k, v) for k, v in draws))


def grid(scn: Scenario) -> Grid:
    rate = scn.run.control_rate_hz
    n_sub = scn.run.plant_substeps
    return Grid(int(round(scn.run.duration * rate)), n_sub, 1.0 / (rate * n_sub), rate)


def initial_state(scn: Scenario) -> np.ndarray:
    """x0 = [sigma_BN, omega_BN_B, wheel_speed] (10,)."""
    i = scn.initial
    return np.concatenate([i.sigma_BN, i.omega_BN_B, i.wheel_speed]).astype(float)
