"""Reading a scenario file: TOML -> a validated ``Scenario`` (sc_rt.scenario.model),
every problem collected with file, line, key and value (sc_rt.scenario.schema),
shipped scenarios by name (sc_rt.scenario.shipped)."""

from __future__ import annotations

import dataclasses
import re
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt import _core
from sc_rt.pylaw import is_python_law, load_law
from sc_rt.isolate import PROBE_TIMEOUT_ENV, ChildDied, ChildTimedOut, call_in_child, probe_timeout
from sc_rt._core import mrp_to_dcm
from sc_rt.model.actuators import ActuatorParams, WheelFault
from sc_rt.scenario.wheels import check_wheel_fault, read_wheels
from sc_rt.scenario.orbit import read_environment, read_orbit
from sc_rt.model.combined import RigidBody, combine
from sc_rt.model.plant import DisturbanceParams, PlantParams
from sc_rt.scenario.dispersions import read_montecarlo
from sc_rt.scenario.files import MAX_NESTING, FileProblem, deep_key, nesting_problem, read_bounded
from sc_rt.scenario.schema import (
    Doc,
    ScenarioError,
    ScenarioIssue,
    Spec,
    Table,
    build,
    field_spec,
    format_value,
    key_lines,
    read_fields,
    read_only,
    read_values,
)
from sc_rt.scenario.guidance import coverage_problem, guidance_phases, read_guidance
from sc_rt.scenario.requirements import read_requirements
from sc_rt.scenario.sensors import read_sensors
from sc_rt.scenario.shipped import resolve

from sc_rt.scenario.laws import law_table_name, read_laws
from sc_rt.scenario.model import (LAWS, PAPER_DEFAULTS, ControllerParams, InitialState,
                                  PpcParams, RecordParams, RunParams, SafetyLimits, Scenario,
                                  law_problem, law_spec)

__all__ = ["load_scenario", "parse_set", "scenario_from_data", "read_run", "check_law", "with_run"]

_FAULT = WheelFault(wheel=0)  # defaults of a fault's optional keys


def check_law(doc: Doc, scn: Scenario, law_key: str, where: dict | None = None) -> None:
    """Load and construct the scenario's law once (a plugin, or any law given
    a table), probe one step at rest (in a child process, killed after
    sc_rt.isolate.probe_timeout() seconds): its problems as scenario errors on
    ``law_key`` or on the parameter's own key (``where``: (law, key) -> the
    dotted key it came from; default ``laws.<law>.<key>``). The built-in laws' tables are checked as
    the file is read (``check_tables``). A law that commands the other unit
    than the wheels take is converted by the controller (docs/LAWS.md, "What a
    law commands"), not refused."""
    where = where or {}
    run_law = scn.run.controller
    if run_law in LAWS:
        return
    if is_python_law(run_law):  # a Python law: its class loads, then it is checked as a plugin is
        try:
            load_law(run_law)
        except ValueError as e:
            doc.error(law_key, run_law, str(e).replace("--law ", "law ", 1))
            return
    try:
        name = law_table_name(run_law)
    except ValueError as e:  # a plugin that does not load
        doc.error(law_key, run_law, str(e))
        return
    table = scn.controller.table(name)
    try:
        timeout = probe_timeout()
    except ValueError as e:
        doc.error(law_key, run_law, f"the law's probe: {e}")
        return
    try:
        cfg = scn.core_config(law=run_law)
        try:  # native code: a crash in the probe is a refusal, and so is a law that does not return
            issues = call_in_child(_core.check_law, cfg, timeout=timeout)
        except ChildTimedOut:
            issues = [("law", f"law {run_law}: did not return within {timeout:g} s when constructed and "
                              f"probed at rest at t = 0 (killed; {PROBE_TIMEOUT_ENV} sets the limit)")]
        except ChildDied as e:
            issues = [("law", f"law {run_law}: crashed the process when probed at rest at t = 0 ({e.how})")]
    except ValueError as e:  # the config itself (LCM translation)
        issues = [("law", str(e))]
    _report(doc, issues, run_law, name, table, law_key, where, set())


def check_tables(doc: Doc, laws: tuple, where: dict) -> None:
    """Each built-in law's table, checked by that law (constructed once with
    the paper's spacecraft: its parameters do not depend on the rest of the
    file, so their problems are reported with the file's others)."""
    seen: set[tuple[str, str]] = set()
    for name, table in laws:
        if name not in LAWS:
            continue
        cfg = _core.ControllerConfig()
        cfg.law = name
        cfg.law_params = [(k, list(v)) for k, v in table]
        _report(doc, _core.check_law(cfg), name, name, table, f"laws.{name}", where, seen)


def _report(doc: Doc, issues, spec: str, name: str, table: tuple, law_key: str, where: dict,
            seen: set) -> None:
    """The probe's ``issues`` as errors: a parameter's on its own key."""
    values = dict(table)
    for key, message in issues:
        if key.startswith("params."):
            param = key[len("params."):]
            value = values.get(param)
            message = message.replace(f"laws.{name}.{param}: ", "")
            dotted = where.get((name, param), f"laws.{name}.{param}")
            if (dotted, message) in seen:  # an older table feeds two laws: said once
                continue
            seen.add((dotted, message))
            doc.error(dotted, None if value is None else _param_value(value), message)
        else:
            doc.error(law_key, spec, message)


def _param_value(v: tuple) -> Any:
    return v[0] if len(v) == 1 else list(v)


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


_MAT33 = Spec("matrix", shape=(3, 3))
_MAT34 = Spec("matrix", shape=(3, 4))
_WHEELS = Spec("vector", shape=(4,), scalar_ok=True)
_V3 = Spec("vector", shape=(3,))


def _inertia_problem(J: np.ndarray) -> str:
    """Why J is not a rigid body's inertia matrix ("" if it is one)."""
    if np.abs(J - J.T).max() > 1e-9 * np.abs(J).max():
        return "must be symmetric"
    moments = np.linalg.eigvalsh(J)
    if moments[0] <= 0:
        return f"must be positive definite (eigenvalues {format_value(np.round(moments, 6))})"
    if moments[0] + moments[1] < moments[2] * (1 - 1e-9):
        return (
            f"is not a rigid body's inertia: principal moments {format_value(np.round(moments, 6))} "
            "break the triangle inequality I1 + I2 >= I3"
        )
    return ""


def _wheel_axes_problem(C: np.ndarray) -> str:
    """Why C cannot be a wheel matrix ("" if it can); the checks of C++ validate()."""
    norms = np.linalg.norm(C, axis=0)
    if np.any(np.abs(norms - 1.0) > 1e-2):
        return f"columns must be unit spin axes (norms {format_value(np.round(norms, 4))})"
    sv = np.linalg.svd(C, compute_uv=False)
    if sv[2] < 1e-6 * sv[0]:
        return "is rank-deficient: the wheels cannot produce torque about every axis"
    return ""


def _read_checked(t: Table, name: str, spec: Spec, problem_of: Any, missing: str = "") -> Any:
    """A required value that must also pass ``problem_of`` (returns "" when fine)."""
    value = t.read(name, spec, missing=missing)
    if value is not None and (problem := problem_of(value)):
        t.fail(name, f"{name} {problem}")
        return None
    return value


def _read_capture(t: Table) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(J0, Cbar) of the combined spacecraft from [spacecraft.capture]."""
    frame = t.read("frame", Spec("str", choices=("service", "principal")), default="service")
    s, g = t.sub("service"), t.sub("target")
    mass = Spec("number", gt=0)
    service = (
        s.read("mass", mass),
        _read_checked(s, "inertia", _MAT33, _inertia_problem),
        _read_checked(s, "C", _MAT34, _wheel_axes_problem),
    )
    target = (
        g.read("mass", mass),
        _read_checked(g, "inertia", _MAT33, _inertia_problem),
        g.read("position", Spec("vector", shape=(3,))),
        g.read("attitude", Spec("vector", shape=(3,), mrp=True)),
    )
    for sub in (s, g, t):
        sub.finish()
    if any(v is None for v in (frame, *service, *target)):
        return None, None
    c = combine(
        RigidBody(service[0], service[1]), service[2],
        RigidBody(target[0], target[1]), target[2], mrp_to_dcm(target[3]), frame,
    )  # fmt: skip
    return read_only(c.J_C), read_only(c.Cbar)


def _read_spacecraft(t: Table, dist: Table) -> tuple[PlantParams | None, ActuatorParams | None]:
    if t.has("capture"):
        for name in ("J0", "Cbar"):
            if t.has(name):
                t.fail(name, f"give either {name} or [{t.key}.capture], not both")
            t.used.add(name)
        J0, Cbar = _read_capture(t.sub("capture"))
    else:
        either = f"required key is missing (or give a [{t.key}.capture] table)"
        J0 = _read_checked(t, "J0", _MAT33, _inertia_problem, either)
        Cbar = _read_checked(t, "Cbar", _MAT34, _wheel_axes_problem, either)
    dJ = t.read("dJ", _MAT33)
    if dJ is not None and np.abs(dJ - dJ.T).max() > 1e-9 * max(np.abs(dJ).max(), 1.0):
        t.fail("dJ", "dJ must be symmetric")
        dJ = None
    if J0 is not None and dJ is not None and (problem := _inertia_problem(J0 + dJ)):
        t.fail("dJ", f"the true inertia J0 + dJ = {format_value(J0 + dJ)} {problem}")
        dJ = None
    Jw = t.read("Jw", dataclasses.replace(_WHEELS, gt=0))
    umin, umax = t.read("umin", _WHEELS), t.read("umax", _WHEELS)
    if umin is not None and umax is not None and np.any(umin >= umax):
        bad = ", ".join(str(i + 1) for i in np.flatnonzero(umin >= umax))
        t.fail("umin", f"umin must be < umax = {format_value(t.raw('umax'))} for every wheel "
                       f"(not for wheel {bad})")  # fmt: skip
        umin = None
    w0 = t.read("w0", Spec("number", ge=0))
    max_speed = t.read(
        "max_wheel_speed",
        dataclasses.replace(_WHEELS, gt=0, allow_inf=True),
        default=read_only(np.full(4, np.inf)),
    )
    t.finish()
    amp, freq = dist.read("amp", _V3), dist.read("freq", dataclasses.replace(_V3, ge=0))
    bias = dist.read("bias", _V3, default=read_only(np.zeros(3)))
    dist.finish()
    disturbance = build(dist, DisturbanceParams, amp=amp, freq=freq, bias=bias)
    plant = build(t, PlantParams, J0=J0, dJ=dJ, Cbar=Cbar, Jw=Jw, w0=w0, disturbance=disturbance)
    actuators = build(t, ActuatorParams, umin=umin, umax=umax, max_wheel_speed=max_speed)
    return plant, actuators


def _read_faults(root: Table, plant_step: float | None) -> tuple[WheelFault, ...] | None:
    root.used.add("faults")
    raw = root.raw("faults") if root.has("faults") else []
    if not (isinstance(raw, list) and all(isinstance(f, dict) for f in raw)):
        root.fail("faults", "faults must be an array of tables ([[faults]])")
        return None
    faults, first_of_wheel = [], {}
    for i, entry in enumerate(raw):
        t = Table(root.doc, f"faults[{i}]", entry)
        wheel = t.read("wheel", Spec("int", ge=1, le=4))
        eff = t.read("effectiveness", Spec("number", ge=0, le=1), default=_FAULT.effectiveness)
        bias = t.read("bias", Spec("number"), default=_FAULT.bias)
        onset = t.read("onset", Spec("number", ge=0))
        end = t.read("end", Spec("number"), default=_FAULT.end)
        rate = t.read("rate", Spec("number", gt=0), default=_FAULT.rate)
        stuck = t.read("stuck", Spec("bool"), default=_FAULT.stuck)
        friction = t.read("friction", Spec("number", ge=0), default=_FAULT.friction)
        t.finish()
        check_wheel_fault(t, bool(stuck), rate, root.has("wheels"), plant_step)
        if wheel is not None and wheel in first_of_wheel:
            t.fail("wheel", f"wheel {wheel} already has a fault (faults[{first_of_wheel[wheel]}]): "
                   "one fault per wheel")  # fmt: skip
            wheel = None
        elif wheel is not None:
            first_of_wheel[wheel] = i
        if end is not None and onset is not None and end <= onset:
            t.fail("end", f"end must be > onset ({onset:g} s)")
            onset = None
        if stuck and (t.has("effectiveness") or t.has("bias") or t.has("friction")):
            t.fail("stuck", "a stuck wheel ignores effectiveness, bias and friction: give stuck or those")
            stuck = None
        if t.has("end") and end is None:  # end was given but is bad (reported)
            continue
        fault = build(
            t, WheelFault, ("end",), wheel=None if wheel is None else wheel - 1,
            effectiveness=eff, bias=bias, onset=onset, end=end, rate=rate, stuck=stuck, friction=friction,
        )  # fmt: skip
        if fault is not None:
            faults.append(fault)
    return tuple(faults) if len(faults) == len(raw) else None


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
    plant, actuators = _read_spacecraft(root.sub("spacecraft"), root.sub("disturbance"))
    initial_table = root.sub("initial")
    initial = read_fields(initial_table, InitialState)
    guidance = read_guidance(root.sub("guidance"), run.duration if run else None, path.parent)
    controller_table = root.sub("controller", required=False)
    sensors = read_sensors(root, controller_table, run)  # [sensors], [controller] measurement, estimator
    try:
        run_law = law_table_name(run.controller) if run is not None else None
    except ValueError:  # a plugin that does not load: check_law reports it
        run_law = None
    controller, where, deprecations = _read_controller(root, controller_table, run_law)
    if controller is not None:
        check_tables(doc, controller.laws, where)
    faults = _read_faults(root, run.plant_step if run else None)
    wheels = read_wheels(root)
    orbit = read_orbit(root)  # [orbit]: the plant's gravity gradient of the orbit
    field_model = read_environment(root, orbit is not None)  # [environment] field
    requirements = read_requirements(root, run.duration if run else None,
                                     guidance_phases(guidance) if guidance is not None else {})
    record = read_fields(root.sub("record", required=False), RecordParams)
    montecarlo = root.sub("montecarlo", required=False)  # read last: it names the others' keys
    root.finish()
    if wheels is False:
        actuators = None  # (reported)
    if plant is not None and orbit is not False:
        plant = dataclasses.replace(plant, orbit=orbit)
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
    )
    check_law(doc, scenario, "controller.law" if "law" in ctl_data else "run.controller", where)
    if doc.errors:
        return None
    return dataclasses.replace(scenario, montecarlo=read_montecarlo(montecarlo, scenario))


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
    """``--set`` pairs into the file's data, before it is validated like the file."""
    for key, value in sets:
        node = data
        parts = key.split(".")
        for i, part in enumerate(parts[:-1]):
            nxt = node.setdefault(part, {})
            if not isinstance(nxt, dict):
                where = ".".join(parts[:i + 1])
                raise ScenarioError(path, [ScenarioIssue(0, key, value, f"--set {key}: {where} is not a table")])
            node = nxt
        if isinstance(node.get(parts[-1]), dict):
            raise ScenarioError(path, [ScenarioIssue(0, key, value, f"--set {key}: a table, not a value")])
        node[parts[-1]] = value


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
    new = dataclasses.replace(scn, run=run)
    if run.controller != scn.run.controller:
        check_law(doc, new, "run.controller")
        if doc.errors:
            raise ScenarioError(doc.path, doc.errors)
    return new
