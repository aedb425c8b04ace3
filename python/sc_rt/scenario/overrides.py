"""What a run of a scenario needs besides the scenario itself: CLI-style
overrides, the sampling grid, the initial state. Shared by every engine
and by the emulator (one definition, so they all step the same way)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sc_rt.scenario.model import Scenario
from sc_rt.scenario.reader import with_run

__all__ = ["Grid", "grid", "initial_state", "with_overrides"]


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
    """
    if control_rate_hz is not None and plant_step is None:
        try:
            period = 1.0 / float(control_rate_hz)
            plant_step = period / math.ceil(period / scn.run.plant_step - 1e-9)
        except (ValueError, ZeroDivisionError, OverflowError, TypeError):
            plant_step = None  # the rate itself is invalid: with_run names it
    return with_run(scn, controller=law, control_rate_hz=control_rate_hz, duration=duration,
                        plant_step=plant_step)


def grid(scn: Scenario) -> Grid:
    rate = scn.run.control_rate_hz
    n_sub = scn.run.plant_substeps
    return Grid(int(round(scn.run.duration * rate)), n_sub, 1.0 / (rate * n_sub), rate)


def initial_state(scn: Scenario) -> np.ndarray:
    """x0 = [sigma_BN, omega_BN_B, wheel_speed] (10,)."""
    i = scn.initial
    return np.concatenate([i.sigma_BN, i.omega_BN_B, i.wheel_speed]).astype(float)
