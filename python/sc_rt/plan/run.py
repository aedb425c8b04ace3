"""The plan of one run (issue 38 item 1): everything a run needs, resolved
once where the run is asked for (the command line, or the Python API's
:func:`plan_run`), as one frozen value that the engines (sc_rt.sim), the
bench (``sc_rt.hil.runner.run_hil``) and the studies take. Nothing below the
plan parses a law spec or reads the command line's arguments.

A plan is what its run records as its inputs (``RunPlan.inputs()``, kept
in ``RunMeta.inputs``, sc_rt.results.record.inputs) and what replays it
(:func:`plan_from_inputs`: the same scenario file, overrides, law, engine
and set-up).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sc_rt.plan.law import ExternalLaw, LawRef, PythonLaw, law_from_dict, resolve_law
from sc_rt.results.record.inputs import run_inputs
from sc_rt.plan.timing import RealtimeLimits, Timing, TimingSetup
from sc_rt.scenario.tables.laws import stray_tables
from sc_rt.scenario.model import Scenario, ScenarioError
from sc_rt.scenario.overrides import DRAW, with_draws, with_overrides
from sc_rt.scenario.reader import load_scenario

__all__ = ["ENGINES", "Outputs", "Bus", "RunPlan", "PlanConflict", "plan_run", "plan_from_inputs"]


class PlanConflict(ValueError):
    """Two choices of a plan that cannot go together (one line, naming the first)."""


#: the offline engines (sc_rt.sim) and the bench (sc_rt.hil)
ENGINES = ("python", "cpp", "unsampled", "bench")


@dataclass(frozen=True)
class Outputs:
    """Where a run writes.

    Parameters
    ----------
    out : Path, optional
        The run's directory; None: nowhere (an in-memory run).
    plots : bool
        Write the figures.
    mcap : Path, optional
        The log as MCAP (a bench run); None: none.
    """

    out: Path | None = None
    plots: bool = True
    mcap: Path | None = None


@dataclass(frozen=True)
class Bus:
    """The bench's bus.

    Parameters
    ----------
    lcm_url : str, optional
        The LCM URL; None: a udpm URL on a free port, ttl=0.
    prefix : str
        The channel-name prefix ("": none).
    accept_fault_commands : bool
        The emulator applies fault_cmd_t messages (``sc-rt fault``).
    auth_key : Path, optional
        A key file: the bus is authenticated with HMAC-SHA256; None: not.
    live : int, optional
        The live view's port beside the run (0: a free one); None: no live view.
    """

    lcm_url: str | None = None
    prefix: str = ""
    accept_fault_commands: bool = False
    auth_key: Path | None = None
    live: int | None = None


@dataclass(frozen=True)
class RunPlan:
    """One run, resolved once (build it with :func:`plan_run`).

    Parameters
    ----------
    scenario : Scenario
        The scenario, its overrides applied and its law's spec as resolved.
    law : LawRef
        The law (sc_rt.plan.law): BuiltinLaw, PluginLaw (file, SHA-256),
        PythonLaw (module or file, SHA-256) or ExternalLaw (a command, or
        one started by hand); loaded and probed at rest when planned.
    engine : {"python", "cpp", "unsampled", "bench"}
        An offline engine (sc_rt.sim), or the bench (sc_rt.hil).
    timing : Timing
        The mode and the bench's timing set-up.
    outputs : Outputs
        Where the run writes.
    bus : Bus
        The bench's bus and live view.
    notes : tuple of str
        What the resolution had to say (a table of a law this run does not
        run), one line each.
    """

    scenario: Scenario
    law: LawRef
    engine: str = "python"
    timing: Timing = field(default_factory=Timing)
    outputs: Outputs = field(default_factory=Outputs)
    bus: Bus = field(default_factory=Bus)
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.engine not in ENGINES:
            raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {self.engine!r}")
        if (self.engine == "bench") != (self.timing.mode != "offline"):
            raise ValueError(f"engine {self.engine!r} with mode {self.timing.mode!r}: the bench runs "
                             "lockstep or realtime, an offline engine offline")

    @property
    def mode(self) -> str:
        return self.timing.mode

    def inputs(self) -> dict[str, Any]:
        """The plan as its run records it (JSON-ready): the scenario file, its
        SHA-256 and its overrides, the law (its reference, its parameters
        as run), the engine, the timing, the outputs, the bus, and which
        sc-rt made it (sc_rt.results.record.inputs.run_inputs)."""
        rec = run_inputs(self.scenario, self.law.name)
        rec["plan"] = {"law": dataclasses.asdict(self.law), "engine": self.engine,
                       "timing": _plain(dataclasses.asdict(self.timing)),
                       "outputs": _plain(dataclasses.asdict(self.outputs)),
                       "bus": _plain(dataclasses.asdict(self.bus))}
        return rec


def _plain(d: dict[str, Any]) -> dict[str, Any]:
    return {k: (str(v) if isinstance(v, Path) else _plain(v) if isinstance(v, dict) else v) for k, v in d.items()}


def plan_run(scenario: str | Path | Scenario, *, sets: Any = (), law: str | None = None,
             engine: str = "python", control_rate_hz: float | None = None, duration: float | None = None,
             plant_step: float | None = None, external: str | None = None, external_wait: bool = False,
             timing: Timing | None = None, outputs: Outputs | None = None, bus: Bus | None = None,
             strays: bool = True) -> RunPlan:
    """The plan of a run: the Python API's entry (``sc-rt sim`` and ``hil``
    build theirs with it).

    Parameters
    ----------
    scenario : str, Path or Scenario
        A scenario file or shipped name (read with ``sets``), or a Scenario.
    sets : iterable of (str, value)
        ``--set`` overrides of the file (sc_rt.scenario.reader.load_scenario).
    law : str, optional
        The law spec (a built-in name, ``plugin:PATH``, ``[python:]module:Class``
        or ``file.py:Class``); None: the scenario's. Parsed here, once: the
        plan holds its typed reference.
    engine : {"python", "cpp", "unsampled", "bench"}
        An offline engine, or the bench (``timing.mode`` lockstep or realtime).
    control_rate_hz, duration, plant_step : float, optional
        [Hz], [s], [s] overrides of the scenario's run.
    external : str, optional
        The bench: a command line started as the controller (hil/external.py).
    external_wait : bool
        The bench: start no controller, wait for one started by hand.
    timing, outputs, bus : optional
        The run's timing set-up, outputs and bus (defaults: an offline run,
        no directory, a free LCM port).
    strays : bool
        Refuse a ``[laws.NAME]`` table that no law of the run reads but is
        near its law's name (a misspelling; sc_rt.scenario.tables.laws.stray_tables),
        and note the others (``RunPlan.notes``). False: checked by the caller
        (``sc-rt compare``, against every law it compares).

    Returns
    -------
    RunPlan
        The run, resolved: what ``sc_rt.run_hil`` and
        ``sc_rt.sim.isolated.simulate_plan`` take, and what the run records.

    Raises
    ------
    ScenarioError
        The file, an override, or the law (its load, its probe at rest, a
        parameter of its table) is refused: every problem with its key.
    PlanConflict
        A Python law with an external controller.
    ValueError
        An engine, mode or floor policy that does not exist.
    """
    timing = timing or (Timing(mode="lockstep") if engine == "bench" else Timing())
    scn = scenario if isinstance(scenario, Scenario) else load_scenario(scenario, sets)
    scn = with_overrides(scn, law=law, control_rate_hz=control_rate_hz, duration=duration, plant_step=plant_step)
    # a Python law given to the bench runs in sc-rt controller, which checks it itself (as before the plan)
    scn, ref = resolve_law(scn, overridden=law is not None, probe_python=not (engine == "bench" and law is not None))
    table_name = ref.name  # the table the run reads (an external controller is given the scenario's law's)
    if external is not None or external_wait:
        if law is not None and isinstance(ref, PythonLaw):
            raise PlanConflict(f"law {law}: a Python law runs in sc-rt controller; it cannot be combined with "
                               f"{'--external' if external is not None else '--external-wait'}")
        ref = ExternalLaw(command=external)
    errors, notes = stray_tables(scn, (), names=(table_name,)) if strays else ([], [])  # a misspelt [laws.NAME]
    if errors:
        raise ScenarioError(scn.path, errors)
    return RunPlan(scenario=scn, law=ref, engine=engine, timing=timing, outputs=outputs or Outputs(),
                   bus=bus or Bus(), notes=tuple(notes))


def plan_from_inputs(inputs: dict[str, Any], out: Path | None = None) -> RunPlan:
    """The plan a run recorded (``RunPlan.inputs()``) made again: its scenario
    file read with its ``--set`` overrides, its run overrides, its law, engine
    and set-up, and a Monte Carlo run's drawn values (``draw KEY``,
    sc_rt.scenario.overrides.with_draws) as recorded, not drawn again
    (``out``: another directory to write to). ValueError when the record
    holds no plan, or its scenario file changed since (SHA-256)."""
    if "plan" not in inputs or not inputs.get("scenario_file"):
        raise ValueError("the run's inputs hold no plan (written before sc-rt recorded its plan)")
    p = inputs["plan"]
    sets = [(k[len("set "):], v) for k, v in inputs.get("overrides", {}).items() if k.startswith("set ")]
    run = {k[len("run."):]: v for k, v in inputs.get("overrides", {}).items() if k.startswith("run.")}
    recorded = law_from_dict(p["law"])
    scn = load_scenario(inputs["scenario_file"], sets)
    if inputs.get("scenario_sha256") != plan_sha256(scn):
        raise ValueError(f"{inputs['scenario_file']}: the scenario file changed since the run (SHA-256 "
                         f"{inputs.get('scenario_sha256')}): it cannot be replayed as it ran")
    t = dict(p["timing"])
    timing = Timing(**{**t, "setup": TimingSetup(**t["setup"]), "rt_limits": RealtimeLimits(**t["rt_limits"])})
    o = p["outputs"]
    outputs = Outputs(out=Path(out or o["out"]) if (out or o["out"]) else None, plots=o["plots"],
                      mcap=Path(o["mcap"]) if o["mcap"] else None)
    b = dict(p["bus"])
    bus = Bus(**{**b, "auth_key": Path(b["auth_key"]) if b["auth_key"] else None})
    external = recorded if isinstance(recorded, ExternalLaw) else None
    plan = plan_run(scn, law=run.get("controller"), engine=p["engine"], control_rate_hz=run.get("control_rate_hz"),
                    duration=run.get("duration"), plant_step=run.get("plant_step"),
                    external=external.command if external else None,
                    external_wait=external is not None and external.command is None,
                    timing=timing, outputs=outputs, bus=bus)
    if isinstance(recorded, PythonLaw) and isinstance(plan.law, PythonLaw) and recorded.sha256 != plan.law.sha256:
        raise ValueError(f"{recorded.module}: the law's file changed since the run (SHA-256 {recorded.sha256})")
    if plan.law != recorded and not isinstance(recorded, ExternalLaw):
        raise ValueError(f"the law resolves to {plan.law} now, not to the recorded {recorded}")
    draws = [(k[len(DRAW):], v) for k, v in inputs.get("overrides", {}).items() if k.startswith(DRAW)]
    if draws:  # a campaign's run: the base plan with the values it drew
        try:
            plan = dataclasses.replace(plan, scenario=with_draws(plan.scenario, draws))
        except KeyError as e:
            raise ValueError(f"the run's drawn value {e} is not a key of the scenario") from None
    return plan


def plan_sha256(scn: Scenario) -> str | None:
    """The SHA-256 of a scenario's file now (None when it cannot be read)."""
    import hashlib

    try:
        return hashlib.sha256(Path(scn.path).read_bytes()).hexdigest()
    except OSError:
        return None

