"""Scenario files: the one source of truth for a run (docs/SCENARIOS.md).

A scenario is a TOML file that states the physical model explicitly (inertia,
wheels, limits, disturbance, initial state, desired trajectory, faults, run
timing); controller gains may be left out and then take the paper's values
(MODEL.md section 8), which come from the C++ config structs
(``sc_rt._core.ControllerConfig()``), so no second copy of them exists.

``load_scenario`` parses and validates a file once and returns a frozen
:class:`Scenario`. Every problem of a file is reported together in one
:class:`ScenarioError` naming the file, line, dotted key and bad value.
The controller receives its part as an LCM ``controller_config_t``
(:meth:`Scenario.controller_config_msg`); :meth:`Scenario.core_config`
decodes those bytes with the same C++ translator as the real-time process
(both in sc_rt.scenario.config_msg). The law table and the law spec's
helpers (``LAWS``, ``law_spec``, ``law_identity``, ...) live in
sc_rt.scenario.lawspec and are importable from here too.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from sc_rt_lcm import controller_config_t

from sc_rt import _core
from sc_rt.model.actuators import ActuatorParams
from sc_rt.model.plant_params import PlantParams
from sc_rt.scenario.schema import (  # noqa: F401  (ScenarioError and ScenarioIssue are public here)
    Doc,
    ScenarioError,
    ScenarioIssue,
    Spec,
    Table,
    convert,
    field_spec,
    read_only,
    spec,
    vector_spec,
)
from sc_rt.scenario.config_msg import controller_config_msg, core_config
from sc_rt.scenario.tables.laws import items_of, resolved
from sc_rt.scenario.lawspec import (  # noqa: F401  (the law table and spec helpers are public here too)
    LAW_NAMES,
    LAWS,
    PLUGIN_PREFIX,
    law_identity,
    law_problem,
    law_spec,
)
from sc_rt.scenario.tables.guidance import (
    FileGuidance,
    Guidance,
    GuidanceParams,
    HoldGuidance,
    SlewGuidance,
)

__all__ = [
    "LAWS",
    "LAW_NAMES",
    "PLUGIN_PREFIX",
    "PAPER_DEFAULTS",
    "law_problem",
    "law_spec",
    "ControllerParams",
    "FileGuidance",
    "Guidance",
    "GuidanceParams",
    "HoldGuidance",
    "InitialState",
    "PpcParams",
    "RunParams",
    "SafetyLimits",
    "Scenario",
    "ScenarioError",
    "SlewGuidance",
    "ScenarioIssue",
]

#: The paper's controller values (the C++ defaults): the defaults of every gain.
PAPER_DEFAULTS = _core.ControllerConfig()


def _paper(get: Any, metadata: dict[str, Spec]) -> Any:
    """A vector field whose default comes from the C++ config structs (the paper's values)."""
    return field(default_factory=lambda: read_only(get(PAPER_DEFAULTS)), metadata=metadata)


# --------------------------------------------------------------------------- #
# The typed scenario.


@dataclass(frozen=True)
class RunParams:
    """Run timing and the control law."""

    duration: float = field(metadata=spec("number", gt=0))  # [s]
    control_rate_hz: float = field(metadata=spec("number", gt=0))  # [Hz]
    # [s] plant integration step; the control period is an integer multiple
    plant_step: float = field(metadata=spec("number", gt=0))
    # law spec: a name of LAWS or "plugin:PATH_OR_NAME" (a plugin file's path made absolute)
    controller: str = field(metadata=spec("str"))

    @property
    def control_period(self) -> float:
        """[s] 1 / control_rate_hz."""
        return 1.0 / self.control_rate_hz

    @property
    def plant_substeps(self) -> int:
        """Plant steps per control period."""
        return round(self.control_period / self.plant_step)


@dataclass(frozen=True)
class RecordParams:
    """``[record]``: what a run keeps of its rows (docs/SCENARIOS.md)."""

    # keep every this many control instants in trajectory.npz / .arrow (and the last);
    # the metrics and the verdict are computed on every row first. 1: every row.
    every: int = field(default=1, metadata=spec("int", ge=1))


@dataclass(frozen=True)
class InitialState:
    """Plant state at t = 0."""

    sigma_BN: np.ndarray = field(metadata=vector_spec(3, mrp=True))  # [-] MRP, |sigma| <= 1
    omega_BN_B: np.ndarray = field(metadata=vector_spec(3))  # [rad/s]
    wheel_speed: np.ndarray = field(metadata=vector_spec(4))  # [rad/s] relative to the body


@dataclass(frozen=True)
class PpcParams:
    """Prescribed performance (29)-(35), per axis; defaults: Table 1."""

    chi0: np.ndarray = _paper(lambda c: c.ppc.chi0, vector_spec(3, gt=0))  # [-] chi(0) >= chiinf
    chiinf: np.ndarray = _paper(lambda c: c.ppc.chiinf, vector_spec(3, gt=0))  # [-] chi(inf)
    gamma: np.ndarray = _paper(lambda c: c.ppc.gamma, vector_spec(3, ge=0))  # [1/s] decay rate
    dmin: np.ndarray = _paper(lambda c: c.ppc.dmin, vector_spec(3, gt=0))  # [-] lower bound factor
    dmax: np.ndarray = _paper(lambda c: c.ppc.dmax, vector_spec(3, gt=0))  # [-] upper bound factor


@dataclass(frozen=True)
class SafetyLimits:
    """The controller's safe-mode limits; not from the paper."""

    # [rad/s] a measured |omega| beyond this is rejected
    max_rate: float = field(default=PAPER_DEFAULTS.safety.max_rate, metadata=spec("number", gt=0))
    # [rad/s] a measured |wheel speed| beyond this is rejected
    max_wheel_speed: float = field(
        default=PAPER_DEFAULTS.safety.max_wheel_speed, metadata=spec("number", gt=0)
    )
    # control periods without a fresh state before SAFE
    stale_periods: float = field(
        default=PAPER_DEFAULTS.safety.stale_periods, metadata=spec("number", gt=0)
    )


@dataclass(frozen=True)
class ControllerParams:
    """The controller's common parts (the envelope, the safe-mode limits, B+)
    and every law's own parameters; ControllerParams() is the paper's controller."""

    ppc: PpcParams = field(default_factory=PpcParams)
    safety: SafetyLimits = field(default_factory=SafetyLimits)
    # [-] damping of B+ = B'(BB' + damping^2 I)^-1; 0: exact pseudo-inverse
    pinv_damping: float = field(
        default=PAPER_DEFAULTS.spacecraft.pinv_damping, metadata=spec("number", ge=0)
    )
    # [laws.NAME]: each law's own parameters, ((law name, ((key, (numbers...)), ...)), ...),
    # handed to that law's constructor, which validates them (docs/LAWS.md); a law
    # without a table runs its defaults (sc_rt.scenario.tables.laws)
    laws: tuple = field(default=(), metadata=spec("params"))

    def table(self, law: str) -> tuple:
        """The items of law ``law``'s table (a registry name; () without one)."""
        return items_of(self.laws, law)

    def resolved(self, law: str) -> dict[str, Any]:
        """Law ``law``'s parameters as it runs them: its defaults overlaid with its table."""
        return resolved(self.laws, law)


@dataclass(frozen=True)
class Scenario:
    """One run, validated. Build it with :func:`load_scenario`.

    Frozen: make a changed copy with ``dataclasses.replace`` or
    ``sc_rt.with_overrides``.

    Attributes
    ----------
    name : str
        The file's ``name`` key (default: the file name without ``.toml``).
    description : str
        The file's ``description`` key ("" without one).
    expect : str
        The file's ``expect`` key: what its run's verdict is, "holds" (every
        requirement of ``requirements`` is met) or "violates" (one is not);
        "" unstated. Every shipped scenario states it and
        tests/test_library.py checks it by running the file.
    path : Path
        The file the scenario was read from (relative plugin paths are
        resolved against its folder).
    run : RunParams
        ``[run]``: duration [s], control rate [Hz], plant step [s] and the law.
    plant : PlantParams
        ``[spacecraft]`` and ``[disturbance]``: the true plant (inertia, wheel
        axes and inertias, orbit rate, disturbance).
    actuators : ActuatorParams
        The wheel limits ([rad/s^2], [rad/s]) and the ``[[faults]]`` schedule.
    initial : InitialState
        ``[initial]``: the plant state at t = 0.
    guidance : Guidance
        The ``[guidance]`` table's kind: GuidanceParams (the paper's),
        HoldGuidance, SlewGuidance or FileGuidance.
    controller : ControllerParams
        ``[controller]``: the controller's common parts (the envelope, the
        safe-mode limits, the pseudo-inverse's damping), and every law's own
        parameter table (``[laws.NAME]``; ``controller.table(name)``,
        ``controller.resolved(name)``).
    montecarlo : MonteCarloTable or None
        The ``[montecarlo]`` table (sc_rt.scenario.dispersions), None without one.
    sensors : Sensors or None
        The ``[sensors]`` tables and ``[controller] measurement``
        (sc_rt.scenario.tables.sensors), None without ``[sensors]``.
    requirements : tuple of Requirement
        The ``[[requirements]]`` rows (sc_rt.scenario.tables.requirements), what a
        run is judged by (sc_rt.results.judge.requirements); ``()`` without any.
    record : RecordParams
        ``[record]``: what a run keeps of its rows (``every``: the saved rows
        keep every this many control instants; 1 without the table).
    deprecations : tuple of str
        One line per older table the file gave (``[controller.dsc]``, ...),
        read as its new form; the command line prints them
        (sc_rt.scenario.tables.laws).
    overrides : tuple of (str, value)
        The overrides applied to the file's values, in order, as (dotted
        key, value) pairs (``sc_rt.with_overrides``); a run records them
        (sc_rt.results.record.inputs).
    field_model : str
        ``[environment] field``: "igrf", "dipole", "wmm2025" or "none" (the default),
        the geomagnetic field along the orbit (``plant.orbit``);
        ``sc_rt.model.field.field_for(model, jd)`` builds it.
    magnetic_control : MagneticControl or None
        The ``[momentum]`` and ``[bdot]`` tables (sc_rt.scenario.tables.momentum): the
        controller's momentum manager and B-dot; None without either.
    law_key, law_keys : str, tuple
        Where the file names its law and each law parameter (dotted keys),
        for the errors of the law's probe (sc_rt.plan.law).
    """

    name: str
    description: str
    path: Path
    run: RunParams
    plant: PlantParams
    actuators: ActuatorParams
    initial: InitialState
    # the [guidance] table's kind: GuidanceParams (the paper's), HoldGuidance,
    # SlewGuidance or FileGuidance (sc_rt.scenario.tables.guidance)
    guidance: Guidance
    controller: ControllerParams
    # the [montecarlo] table (sc_rt.scenario.dispersions.MonteCarloTable), None without one
    montecarlo: Any = None
    # the [sensors] tables and [controller] measurement (sc_rt.scenario.tables.sensors.Sensors), None without [sensors]
    sensors: Any = None
    # the expect key: "holds", "violates" or "" (unstated)
    expect: str = ""
    # the [[requirements]] rows (sc_rt.scenario.tables.requirements.Requirement), () without any
    requirements: tuple = ()
    # [record]: what a run keeps of its rows
    record: RecordParams = RecordParams()
    # one line per older table the file gave, read as its new form (sc_rt.scenario.tables.laws)
    deprecations: tuple = ()
    # the overrides applied to the file's values, in order: (dotted key, value) pairs
    # (sc_rt.scenario.overrides.with_overrides); a run records them (results/record/inputs.py)
    overrides: tuple = ()
    # [environment] field: the geomagnetic field model along the orbit, "igrf", "dipole",
    # "wmm2025" or "none" (sc_rt.model.field.field_for); the plant's too (plant.field_model), where the
    # residual dipole and the magnetorquers' dipole act
    field_model: str = "none"
    # [momentum] and [bdot]: the controller's magnetic part (sc_rt.scenario.tables.momentum.MagneticControl), None: none
    magnetic_control: Any = None
    # the dotted key the file names its law by ("controller.law" or "run.controller"), and the
    # dotted key of each law parameter ((law, key), dotted key) pairs: where a law's probe
    # reports a problem (sc_rt.plan.law)
    law_key: str = "run.controller"
    law_keys: tuple = ()

    def controller_config_msg(
        self, law: str | None = None, control_rate_hz: float | None = None, *, nav: bool = True
    ) -> controller_config_t:
        """The controller's part of the scenario as an LCM message, every field
        filled (sc_rt.scenario.config_msg.controller_config_msg)."""
        return controller_config_msg(self, law, control_rate_hz, nav=nav)

    def core_config(
        self, law: str | None = None, control_rate_hz: float | None = None
    ) -> _core.ControllerConfig:
        """The C++ config, decoded from the LCM bytes as the real-time process
        does (sc_rt.scenario.config_msg.core_config)."""
        return core_config(self, law, control_rate_hz)
