"""Reading a scenario file: TOML -> a validated ``Scenario`` (sc_rt.scenario.model),
every problem collected with file, line, key and value (sc_rt.scenario.schema),
shipped scenarios by name (sc_rt.scenario.shipped)."""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt import _core
from sc_rt.scenario.tables.wheels import read_wheels
from sc_rt.scenario.tables.magnetorquers import read_magnetorquers
from sc_rt.scenario.tables.momentum import read_magnetic_control
from sc_rt.scenario.tables.orbit import read_environment, read_orbit
from sc_rt.scenario.dispersions import read_montecarlo
from sc_rt.scenario.keys import key_parts
from sc_rt.scenario.files import MAX_NESTING, FileProblem, deep_key, nesting_problem, read_bounded
from sc_rt.scenario.schema import (
    Doc,
    ScenarioError,
    ScenarioIssue,
    Spec,
    Table,
    field_spec,
    format_value,
    key_lines,
    read_fields,
    read_values,
)
from sc_rt.scenario.tables.guidance import coverage_problem, guidance_phases, read_guidance
from sc_rt.scenario.tables.requirements import read_requirements
from sc_rt.scenario.tables.sensors import read_sensors
from sc_rt.scenario.shipped import resolve
from sc_rt.scenario.tables.spacecraft import read_faults, read_spacecraft

from sc_rt.scenario.tables.laws import read_laws, report_issues
from sc_rt.scenario.model import (LAWS, PAPER_DEFAULTS, ControllerParams, InitialState,
                                  PpcParams, RecordParams, RunParams, SafetyLimits, Scenario,
                                  law_problem, law_spec)

__all__ = ["load_scenario", "parse_set", "scenario_from_data", "read_run", "with_run"]



def check_tables(doc: Any, laws: tuple, where: dict) -> None:
    """Each built-in law's table, checked by that law (constructed once with
    the paper's spacecraft: its parameters do not depend on the rest of the
    file, so their problems are reported with the file's others). Only the
    core's own laws: a plugin's or Python law's table is checked by its probe
    where the run is planned (sc_rt.plan.law)."""
    seen: set[tuple[str, str]] = set()
    for name, table in laws:
        if name not in LAWS:
            continue
        cfg = _core.ControllerConfig()
        cfg.law = name
        cfg.law_params = [(k, list(v)) for k, v in table]
        report_issues(doc, _core.check_law(cfg), name, name, table, f"laws.{name}", where, seen)


def read_run(t: Table) -> RunParams | None:
    v = read_values(t, RunParams)
    if v["controller"] is not None and (problem := law_problem(v["controller"])):
        t.fail("controller", f"controller {problem}")
        v["controller"] = None
    rate, step = v["control_rate_hz"], v["plant_step"]
    if rate is not None and step is not None:
        n = 1.0 / (rate * step)  # plant steps per control period
        if abs(n - round(n)) > 1e-9 * n:  # also catches n < 1/2 (round(n) = 0)
            t.fail(
                "plant_step",
                f"the control period 1/control_rate_hz = {1.0 / rate:g} s must be an "
                f"integer multiple of plant_step (it is {n:.6g} steps)",
            )
            return None
    return None if any(x is None for x in v.values()) else RunParams(**v)


def _read_controller(root: Table, t: Table, run_law: str | None) -> tuple[ControllerParams | None, dict, list]:
    """[controller] (the common parts) and the laws' tables ([laws.NAME],
    and the older [controller.params|dsc|neso|pd|rft]): (params or None,
    (law, key) -> dotted key, deprecation notes)."""
    ppc_table = t.sub("ppc", required=False)
    ppc = read_fields(ppc_table, PpcParams)
    if ppc is not None and np.any(ppc.chi0 < ppc.chiinf):
        ppc_table.fail("chi0", f"chi0 must be >= chiinf = {format_value(ppc.chiinf)} on every axis")
        ppc = None
    safety = read_fields(t.sub("safety", required=False), SafetyLimits)
    damping = t.read("pinv_damping", field_spec(ControllerParams, "pinv_damping"),
                     default=PAPER_DEFAULTS.spacecraft.pinv_damping)  # fmt: skip
    laws = read_laws(root, t, run_law)
    t.used.add("law")  # read by _read_scenario
    t.finish()
    if damping is None or laws is None or ppc is None or safety is None:
        return None, {}, []
    tables, where, notes = laws
    return ControllerParams(ppc=ppc, safety=safety, pinv_damping=damping, laws=tables), where, notes


def _read_scenario(doc: Doc, data: dict[str, Any], path: Path) -> Scenario | None:
    root = Table(doc, "", data)
    name = root.read("name", Spec("str"), default=path.stem)
    description = root.read("description", Spec("str"), default="")
    expect = root.read("expect", Spec("str", choices=("holds", "violates")), default="")
    # The law: [controller] law, or the older [run] controller (one of them).
    ctl_data = data.get("controller") if isinstance(data.get("controller"), dict) else {}
    law = ctl_data.get("law")
    run_table = root.sub("run")
    if law is not None:
        law_table = Table(doc, "controller", ctl_data)
        if run_table.has("controller") and run_table.raw("controller") != law:
            law_table.fail("law", f'give the law once: [controller] law or [run] controller '
                                  f'(= {format_value(run_table.raw("controller"))}), not both')
            law = None
        elif problem := law_problem(law):
            law_table.fail("law", f"law {problem}")
            law = None
        else:
            law = law_spec(law, path.parent)
        if run_table.data is not None:  # read the rest of [run] with a valid placeholder
            run_table = Table(doc, "run", {**run_table.data, "controller": next(iter(LAWS))})
    run = read_run(run_table)
    if run is not None and law is not None:
        run = dataclasses.replace(run, controller=law)
    elif run is not None and "law" in ctl_data:
        run = None  # the bad [controller] law (reported)
    elif run is not None:
        run = dataclasses.replace(run, controller=law_spec(run.controller, path.parent))
    plant, actuators = read_spacecraft(root.sub("spacecraft"), root.sub("disturbance"))
    initial_table = root.sub("initial")
    initial = read_fields(initial_table, InitialState)
    guidance = read_guidance(root.sub("guidance"), run.duration if run else None, path.parent)
    controller_table = root.sub("controller", required=False)
    sensors = read_sensors(root, controller_table, run)  # [sensors], [controller] measurement, estimator
    # [controller.params]: the table of the file's law, under its spec (no law is loaded here)
    run_law = run.controller if run is not None else None
    controller, where, deprecations = _read_controller(root, controller_table, run_law)
    if controller is not None:
        check_tables(doc, controller.laws, where)
    faults = read_faults(root, run.plant_step if run else None)
    wheels = read_wheels(root)
    orbit = read_orbit(root)  # [orbit]: the plant's gravity gradient of the orbit
    environment = read_environment(root, orbit)  # [environment] field, residual_dipole
    rods = read_magnetorquers(root, environment[0] if environment else None)  # [magnetorquers]
    magnetic = read_magnetic_control(root, orbit or None, rods or None, sensors is not None,  # [momentum], [bdot]
                                     plant.J0 if plant is not None else None, _speed_limits(actuators, wheels),
                                     sensors is not None and sensors.magnetometer is not None)
    if sensors is not None and sensors.magnetometer is not None and (not environment or environment[0] == "none"):
        mt = root.sub("sensors").sub("magnetometer")  # a magnetometer measures the plant's field
        mt.fail(next(iter(mt.data or {}), "rate_hz"), "[sensors.magnetometer] measures the geomagnetic field "
                'along the orbit: give [orbit] and [environment] field = "igrf" or "dipole"')
    requirements = read_requirements(root, run.duration if run else None,
                                     guidance_phases(guidance) if guidance is not None else {})
    record = read_fields(root.sub("record", required=False), RecordParams)
    montecarlo = root.sub("montecarlo", required=False)  # read last: it names the others' keys
    root.finish()
    if wheels is False:
        actuators = None  # (reported)
    field_model, residual = environment or ("none", (0.0, 0.0, 0.0))
    if plant is not None and orbit is not False:
        plant = dataclasses.replace(plant, orbit=orbit, field_model=field_model, residual_dipole=residual,
                                    magnetorquers=rods or None)
    if initial is not None and actuators is not None:
        if np.any(np.abs(initial.wheel_speed) > actuators.max_wheel_speed):
            initial_table.fail(
                "wheel_speed",
                "|wheel_speed| must be <= spacecraft.max_wheel_speed = "
                f"{format_value(actuators.max_wheel_speed)}",
            )
    if doc.errors:
        read_montecarlo(montecarlo, None)  # its own problems, reported with the others
        return None
    scenario = Scenario(
        name=name,
        description=description,
        expect=expect or "",
        path=path,
        run=run,
        plant=plant,
        actuators=dataclasses.replace(actuators, faults=faults, wheels=wheels),
        initial=initial,
        guidance=guidance,
        controller=controller,
        sensors=sensors,
        requirements=requirements,
        record=record,
        deprecations=tuple(deprecations),
        field_model=field_model,
        magnetic_control=magnetic or None,
        law_key="controller.law" if "law" in ctl_data else "run.controller",
        law_keys=tuple(where.items()),
    )
    # a law of the other unit than the wheels take is converted by the controller (docs/LAWS.md,
    # "What a law commands"), not refused
    return dataclasses.replace(scenario, montecarlo=read_montecarlo(montecarlo, scenario))


def _speed_limits(actuators, wheels) -> np.ndarray:
    """The wheels' speed limits [rad/s] as the controller knows them (inf: none)."""
    if wheels:
        return np.array([w.omega_max if w.omega_max > 0 else math.inf for w in wheels.limits])
    return np.asarray(actuators.max_wheel_speed, float) if actuators is not None else np.full(4, math.inf)


def scenario_from_data(data: dict[str, Any], path: str | Path, where: str = "") -> Scenario:
    """A scenario from parsed TOML data (e.g. a dispersed copy), validated as a
    file is; ScenarioError (no line numbers) names ``path`` + ``where``."""
    doc = Doc(f"{path}{where}", {})
    scenario = _read_scenario(doc, data, Path(path))
    if doc.errors:
        raise ScenarioError(doc.path, doc.errors)
    return scenario


def parse_set(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` of ``--set``: a dotted key of the scenario file and a TOML
    value (``0.3``, ``[1, 2, 3]``, ``"pd"``; a bare word is a string).
    ValueError with a one-line reason."""
    key, sep, value = text.partition("=")
    key, value = key.strip(), value.strip()
    if not sep or not key or not value or not all(part.strip() for part in key.split(".")):
        raise ValueError(f"{text!r}: must be KEY=VALUE with a dotted key of the scenario file "
                         "(e.g. laws.pd.beta1=0.3, run.duration=20)")
    try:
        return key, tomllib.loads(f"v = {value}")["v"]
    except tomllib.TOMLDecodeError:
        if re.fullmatch(r"[A-Za-z_][\w.:/+-]*", value):
            return key, value  # a bare word: a string (a law's name, a file)
        raise ValueError(f"{text!r}: {value!r} is not a TOML value") from None


def _apply_sets(path: Path, data: dict[str, Any], sets: Any) -> None:
    """``--set`` pairs into the file's data, before it is validated like the file.
    A key names its tables with dots and an entry of an array (of tables, or of
    numbers) with ``[i]``, as ``[montecarlo]`` keys do: ``faults[0].onset``,
    ``magnetorquers.faults[0].dipole``, ``initial.omega_BN_B[2]``; the entry must
    be in the file (``--set`` changes a fault, it does not add one)."""
    for key, value in sets:
        def fail(why: str, key=key, value=value) -> ScenarioError:
            return ScenarioError(path, [ScenarioIssue(0, key, value, f"--set {key}: {why}")])

        parts = key_parts(key)
        if parts is None:
            raise fail("not a key of the scenario file (dotted names, [i] for an entry of an array)")
        node: Any = data
        for i, part in enumerate(parts):
            last = i == len(parts) - 1
            where = _key_text(parts[:i + 1])
            if isinstance(part, int):
                if isinstance(node, dict):
                    raise fail(f"{_key_text(parts[:i])} is a table, not an array")
                if not isinstance(node, list) or part >= len(node):
                    n = len(node) if isinstance(node, list) else 0
                    entries = f"{n} entr{'y' if n == 1 else 'ies'}"
                    raise fail(f"{where} is not in the file ({_key_text(parts[:i])} has {entries})")
            elif not isinstance(node, dict):
                raise fail(f"{_key_text(parts[:i])} is not a table")
            if last:
                if isinstance(node[part] if isinstance(part, int) else node.get(part), dict):
                    raise fail("a table, not a value")
                node[part] = value
            elif isinstance(part, str) and part not in node:
                if isinstance(parts[i + 1], int):
                    raise fail(f"{where} is not in the file")
                node = node.setdefault(part, {})
            else:
                node = node[part]


def _key_text(parts: list) -> str:
    """["faults", 0, "onset"] -> "faults[0].onset"."""
    return "".join(f"[{p}]" if isinstance(p, int) else (p if i == 0 else "." + p) for i, p in enumerate(parts))


def load_scenario(path: str | Path, sets: Any = ()) -> Scenario:
    """Read and validate a scenario file, or a shipped scenario by name
    (``paper_faults``: sc_rt.scenario.shipped); raise ScenarioError listing every problem.

    Parameters
    ----------
    path : str or Path
        A TOML scenario file, or the name of a shipped scenario
        (``paper_faults`` or ``paper_faults.toml``, when no file of that name
        exists here; ``sc_rt.shipped_scenarios()`` lists them).
    sets : iterable of (str, value)
        ``--set`` overrides: (dotted key, value) pairs put into the file's
        data before it is validated like the file (``parse_set`` reads
        ``KEY=VALUE``); recorded in ``Scenario.overrides`` as ``set KEY``.

    Returns
    -------
    Scenario
        The validated, frozen scenario; gains the file leaves out take the
        paper's values.

    Raises
    ------
    ScenarioError
        The file cannot be read, is not valid TOML, or breaks the schema; it
        lists every problem with file, line, dotted key and value. A bare name
        that is neither a file nor a shipped scenario lists the shipped names.
    """
    path = resolve(path)
    try:
        raw = read_bounded(path)
    except FileProblem as e:
        raise ScenarioError(path, [ScenarioIssue(0, "", None, f"cannot read the file: {e}")]) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        line = raw.count(b"\n", 0, e.start) + 1
        raise ScenarioError(path, [ScenarioIssue(line, "", None, f"cannot read the file: not UTF-8 text "
                                                 f"(byte {e.start}: {e.reason})")]) from None
    if deep := nesting_problem(text):
        raise ScenarioError(path, [ScenarioIssue(deep[0], "", None, f"TOML too deep: {deep[1]}")])
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        m = re.search(r"at line (\d+)", str(e))
        issue = ScenarioIssue(int(m.group(1)) if m else 0, "", None, f"TOML syntax error: {e}")
        raise ScenarioError(path, [issue]) from None
    sets = tuple(sets)
    _apply_sets(path, data, sets)
    doc = Doc(str(path), key_lines(text))
    if (deep := deep_key(data)) is not None:
        raise ScenarioError(path, [_too_deep(doc, deep)])
    scenario = _read_scenario(doc, data, path)
    if doc.errors:
        raise ScenarioError(path, doc.errors)
    if sets:
        scenario = dataclasses.replace(scenario, overrides=tuple((f"set {k}", v) for k, v in sets))
    return scenario


def _too_deep(doc: Doc, path: list) -> ScenarioIssue:
    """The problem of a value nested deeper than MAX_NESTING (dotted keys
    count), at the first line of a key under its tables."""
    tables = ".".join(str(k) for k in path[:next((i for i, k in enumerate(path) if isinstance(k, int)), len(path))])
    line = min((n for k, n in doc.lines.items() if k == tables or k.startswith(tables + ".")),
               default=doc.line_of(tables))
    shown = "".join(f"[{k}]" if isinstance(k, int) else f".{k}" for k in path[:3]).lstrip(".")
    return ScenarioIssue(line, "", None, f"TOML too deep: {shown}... nests more than {MAX_NESTING} levels deep")


def with_run(scn: Scenario, **changes: Any) -> Scenario:
    """A copy with run fields replaced (CLI overrides), validated like the file.

    ``changes`` are RunParams fields (``controller``, ``control_rate_hz``,
    ``duration``, ``plant_step``); a value of None keeps the current one.
    Raises ScenarioError naming the override.
    """
    changes = {k: v for k, v in changes.items() if v is not None}
    if isinstance(changes.get("controller"), str):  # a plugin file: relative to the working directory
        changes["controller"] = law_spec(changes["controller"], Path.cwd())
    doc = Doc(f"{scn.path} (override)", {})
    run = read_run(Table(doc, "run", {**dataclasses.asdict(scn.run), **changes}))
    if run is not None and (problem := coverage_problem(scn.guidance, run.duration)):
        doc.error("run.duration", run.duration, problem)  # a reference file too short
    if doc.errors:
        raise ScenarioError(doc.path, doc.errors)
    return dataclasses.replace(scn, run=run)  # the law itself is probed where the run is planned
