"""What a run is: ``RunMeta``, the scenario, law, engine and the
parameters its figures and checks need (so that no consumer needs the
scenario file). Re-exported by sc_rt.results.record.run beside the Run."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sc_rt.results.record.jsonsafe import json_safe

__all__ = ["RunMeta", "command_fields", "command_meta", "magnetic_meta"]


@dataclass(frozen=True)
class RunMeta:
    """What a run is: its scenario, law, engine and the parameters its
    figures and checks need (so no consumer needs the scenario file).

    Usually built by :meth:`of_scenario`; saved in trajectory.arrow's schema
    metadata (``sc-rt:meta``) as JSON (:meth:`to_json`, :meth:`from_json`).

    Attributes
    ----------
    scenario : str
        The scenario's name.
    law : str
        The law that ran, by its name ("dsc-ppc", "pd", a plugin's
        registered name, a Python law's label, ...).
    engine : str
        What produced the run: "python", "cpp", "unsampled", "hil-lockstep",
        "hil-realtime" or "report" (a log's rebuild).
    control_rate_hz : float
        [Hz] the control rate.
    duration_s : float
        [s] the scenario's duration (after overrides).
    ppc : dict of str to tuple of float
        The prescribed envelope (29): "chi0" [-], "chiinf" [-], "gamma"
        [1/s], "dmin" [-], "dmax" [-], 3 values each.
    umin, umax : tuple of float
        The wheel command limits, one per wheel, in the unit the wheels take
        (``wheel_command``: [rad/s^2] or [N m]).
    faults : tuple of dict
        The scenario's scheduled faults: "wheel" (1-based), "onset" [s],
        "end" [s] (None: never), "effectiveness" [-], "bias" [rad/s^2],
        "rate" [1/s], "stuck" (bool).
    rod_faults : tuple of dict
        The scenario's scheduled magnetorquer-rod faults
        (``[[magnetorquers.faults]]``): "rod" (1-based), "kind" ("dead",
        "stuck", "reversed"), "dipole" [A m^2] (a stuck rod's), "onset" [s],
        "end" [s] (None: never); ``()``: none (or an older record).
    wall_s : float
        [s] wall-clock time of the run (NaN: not measured).
    mode : str
        How the loop was clocked: "offline", "lockstep" or "realtime".
    measurement : str
        What the law was fed: "truth" (no ``[sensors]``, or measurement =
        "truth") or "estimate".
    sensors : bool
        The run had sensors (a ``[sensors]`` table): the estimator fields are
        filled and the bound is judged on ``sigma_BD_true``.
    law_identity : dict or None
        Who the law is (``sc_rt.scenario.lawspec.law_identity``): name, spec,
        source and, for a plugin, its file and the file's SHA-256.
    requirements : tuple of dict
        The scenario's ``[[requirements]]`` rows (every field of
        ``sc_rt.scenario.tables.requirements.Requirement``), what the run is judged
        by (sc_rt.results.judge.requirements); ``()``: none stated.
    Cbar : tuple of tuple of float
        [-] the wheels' spin axes in B (3 rows of 4), the plant's; ``()``:
        not recorded (older runs).
    Jw : tuple of float
        [kg m^2] the wheels' spin inertias (4); ``()``: not recorded.
    max_wheel_speed : tuple of float
        [rad/s] the actuator model's wheel speed limits (4, inf: none);
        ``()``: not recorded.
    record_every : int
        The scenario's ``[record] every``: the saved rows keep every this
        many control instants and the last (1: every row); the metrics were
        computed on every row.
    inputs : dict
        What the run was made from (``sc_rt.results.record.inputs``): the
        scenario file and its SHA-256, the overrides, the law's parameters
        as run (defaults filled in), sc-rt's version and commit.
    expect : str
        The scenario's ``expect`` ("holds", "violates"; "" unstated): the
        verdict the file says its run has, checked against the run's
        (sc_rt.results.judge.gate, metrics.json ``expect``).
    wheel_command : str
        What the wheels take, the run's command interface (the scenario's
        ``[wheels] command``): "acceleration" (wheel accelerations [rad/s^2],
        the default and every record older than this key) or "torque" (motor
        torques [N m]); the unit of u_cmd, u_sat, umin and umax.
    law_command : str
        What the law commanded (its declaration, sc_rt.pylaw.LAW_COMMANDS):
        "acceleration" or "torque"; the controller converted it to
        ``wheel_command`` when they differ; "" unknown (an external controller).
    units : dict of str to str
        Every field's unit on this run (``Field.resolved_unit`` of
        sc_rt.results.record.fields: a "command" field's is the wheels'):
        what outputs label the run's numbers with (``unit``).
    magnetic : dict
        The controller's magnetic part (docs/MODEL.md section 17), what the
        magnetic figure draws its bands and limits from: "rod_max_dipole"
        [A m^2] (per rod), "momentum" (None, or "on_fraction",
        "off_fraction" [-] and "capacity" [N m s], resolved: 0 takes
        min_i Jw_i omega_max_i as the core does) and "bdot" (bool);
        ``{}``: none (or an older record).
    telemetry_names : tuple of str
        The law's telemetry names (its ``telemetry_names()``): the columns
        of the run's ``telemetry`` field, ``"name [unit]"`` where the law
        gives a unit (``Run.named_telemetry``); () for none or unknown (an
        external controller's).
    """

    scenario: str
    law: str
    engine: str  # python | cpp | unsampled | hil-lockstep | hil-realtime | report
    control_rate_hz: float
    duration_s: float
    #: the prescribed envelope (29): chi0, chiinf, gamma, dmin, dmax (3 each)
    ppc: dict[str, tuple[float, ...]]
    umin: tuple[float, ...]
    umax: tuple[float, ...]
    #: the scenario's scheduled faults: dicts wheel (1-based), onset, end, effectiveness, bias, rate, stuck
    faults: tuple[dict[str, Any], ...] = ()
    #: the scenario's scheduled rod faults: dicts rod (1-based), kind, dipole [A m^2], onset [s], end [s] (None: never)
    rod_faults: tuple[dict[str, Any], ...] = ()
    wall_s: float = math.nan
    #: how the loop was clocked: offline, lockstep or realtime
    mode: str = "offline"
    #: what the law was fed: "truth" (no [sensors], or measurement = "truth") or "estimate"
    measurement: str = "truth"
    #: the run had sensors (a [sensors] table): estimator fields filled, bound judged on sigma_BD_true
    sensors: bool = False
    #: who the law is: name, spec, source (and a plugin's file and its sha256)
    law_identity: dict[str, Any] | None = None
    #: the scenario's [[requirements]] rows as dicts (sc_rt.scenario.tables.requirements.Requirement's fields)
    requirements: tuple[dict[str, Any], ...] = ()
    #: [-] the wheels' spin axes in B (3 x 4), [kg m^2] their inertias, [rad/s] their speed limits; () unknown
    Cbar: tuple[tuple[float, ...], ...] = ()
    Jw: tuple[float, ...] = ()
    max_wheel_speed: tuple[float, ...] = ()
    #: the scenario's [record] every: the saved rows keep every this many control instants
    #: (and the last); the metrics were computed on every row
    record_every: int = 1
    #: the law's telemetry names (its telemetry_names(): the columns of the run's telemetry field;
    #: "name [unit]" where the law gives a unit); () for none or unknown
    telemetry_names: tuple[str, ...] = ()
    #: what the wheels take: "acceleration" [rad/s^2] or "torque" [N m] (u_cmd's unit)
    wheel_command: str = "acceleration"
    #: what the law commanded ("acceleration" or "torque"; "" unknown), converted when it differs
    law_command: str = ""
    #: every field's unit on this run (name -> unit, the "command" rule resolved); {}: the fields' own
    units: dict[str, str] = dataclasses.field(default_factory=dict)
    #: the scenario's expect: "holds", "violates" or "" (unstated)
    expect: str = ""
    #: the controller's magnetic part: rod limits [A m^2], the manager's band and capacity [N m s],
    #: B-dot on; {} none (magnetic_meta)
    magnetic: dict[str, Any] = dataclasses.field(default_factory=dict)
    #: what the run was made from (results/record/inputs.py): the scenario file and its sha256,
    #: the overrides, the law's parameters as run, sc-rt's version and commit; {} unknown (older runs)
    inputs: dict[str, Any] = dataclasses.field(default_factory=dict)

    @property
    def torque_wheels(self) -> bool:
        """The wheels take motor torques [N m] (else wheel accelerations [rad/s^2])."""
        return self.wheel_command == "torque"

    def unit(self, name: str) -> str:
        """The unit of the field ``name`` on this run: ``units``, else the
        field's rule resolved by ``wheel_command`` (an older record)."""
        if name in self.units:
            return self.units[name]
        from sc_rt.results.record.fields import FIELD

        return FIELD[name].resolved_unit(self.torque_wheels, self.law_command == "torque" if self.law_command else None)

    def wheel_torque(self, u: Any) -> np.ndarray:
        """Wheel commands ``u`` (N, 4) of this run as motor torques [N m]:
        ``u`` itself on torque wheels, ``Jw u`` on acceleration wheels (the
        drive's arithmetic, types.hpp wheel_torque_command)."""
        u = np.asarray(u, float)
        return u if self.torque_wheels else u * np.asarray(self.Jw, float)

    def to_json(self) -> dict[str, Any]:
        return json_safe(dataclasses.asdict(self))

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RunMeta:
        d = dict(d)
        d["ppc"] = {k: tuple(float(x) for x in v) for k, v in d["ppc"].items()}
        d["umin"], d["umax"] = tuple(d["umin"]), tuple(d["umax"])
        d["faults"] = tuple(d.get("faults", ()))
        d["rod_faults"] = tuple(d.get("rod_faults", ()))
        d["requirements"] = tuple(d.get("requirements", ()))
        d["telemetry_names"] = tuple(d.get("telemetry_names", ()))
        d["units"] = dict(d.get("units", {}))
        d["magnetic"] = dict(d.get("magnetic") or {})
        d["Cbar"] = tuple(tuple(float(x) for x in row) for row in d.get("Cbar", ()))
        for k in ("Jw", "max_wheel_speed"):
            d[k] = tuple(math.inf if x is None else float(x) for x in d.get(k, ()))
        d["wall_s"] = math.nan if d.get("wall_s") is None else float(d["wall_s"])
        return cls(**d)

    @classmethod
    def of_scenario(cls, scn, engine: str, **over: Any) -> RunMeta:
        """The meta of a run of ``scn`` (a sc_rt.scenario Scenario)."""
        p, a, plant = scn.controller.ppc, scn.actuators, scn.plant
        faults = tuple({"wheel": f.wheel + 1, "onset": f.onset, "end": f.end,
                        "effectiveness": f.effectiveness, "bias": f.bias, "rate": f.rate,
                        "stuck": bool(f.stuck)} for f in a.faults)
        rods = getattr(plant, "magnetorquers", None)
        rod_faults = tuple({"rod": f.rod + 1, "kind": f.kind, "dipole": float(f.dipole), "onset": float(f.onset),
                            "end": None if math.isinf(f.end) else float(f.end)}
                           for f in (rods.faults if rods is not None else ()))
        from sc_rt.scenario.model import law_identity

        ident = law_identity(scn.run.controller)
        kw = dict(scenario=scn.name, law=ident["name"], law_identity=ident, engine=engine,
                  control_rate_hz=float(scn.run.control_rate_hz), duration_s=float(scn.run.duration),
                  ppc={k: tuple(float(x) for x in np.asarray(getattr(p, k), float))
                       for k in ("chi0", "chiinf", "gamma", "dmin", "dmax")},
                  umin=tuple(float(x) for x in np.asarray(a.umin, float)),
                  umax=tuple(float(x) for x in np.asarray(a.umax, float)), faults=faults, rod_faults=rod_faults,
                  requirements=tuple(dataclasses.asdict(r) for r in getattr(scn, "requirements", ())),
                  Cbar=tuple(tuple(float(x) for x in row) for row in np.asarray(plant.Cbar, float)),
                  Jw=tuple(float(x) for x in np.asarray(plant.Jw, float)),
                  max_wheel_speed=_speed_limits(a), magnetic=magnetic_meta(scn),
                  record_every=int(getattr(getattr(scn, "record", None), "every", 1)),
                  expect=str(getattr(scn, "expect", "") or ""))
        from sc_rt.results.record.inputs import run_inputs

        kw["inputs"] = run_inputs(scn, ident["name"])
        kw.update(command_meta(scn))
        sensors = getattr(scn, "sensors", None)
        if sensors is not None:
            kw.update(sensors=True, measurement=sensors.measurement)
        kw.update(over)
        return cls(**kw)


def command_meta(scn) -> dict[str, Any]:
    """The run's command interface of the scenario ``scn``: ``command_fields``
    of what its wheels take and of its law."""
    from sc_rt.scenario.tables.laws import wheels_command

    return command_fields(wheels_command(scn), scn.run.controller)


def command_fields(wheel_command: str, law_spec: str | None) -> dict[str, Any]:
    """``wheel_command`` (what the wheels take: "acceleration" or "torque"),
    ``law_command`` (what the law ``law_spec`` commands; "" when it is not
    known or does not load here) and every field's resolved ``units`` (the
    "command" rule: the wheels' unit; the "law" rule: the law's)."""
    from sc_rt.results.record.fields import FIELDS
    from sc_rt.scenario.tables.laws import command_of

    law = ""
    if law_spec:
        try:
            law = command_of(law_spec)
        except ValueError:
            law = ""
    units = {f.name: f.resolved_unit(wheel_command == "torque", law == "torque" if law else None) for f in FIELDS}
    return {"wheel_command": wheel_command, "law_command": law, "units": units}


def _speed_limits(a) -> tuple[float, ...]:
    """The wheels' speed limits [rad/s] (inf: none): the [wheels]' omega_max
    on flight-like wheels, else [spacecraft] max_wheel_speed."""
    if getattr(a, "wheels", None) is not None:
        return tuple(float(w.omega_max) if w.omega_max > 0.0 else math.inf for w in a.wheels.limits)
    return tuple(float(x) for x in np.asarray(a.max_wheel_speed, float))


def magnetic_meta(scn) -> dict[str, Any]:
    """``RunMeta.magnetic`` of the scenario ``scn``: {} without magnetic
    control, else the rods' limits [A m^2], the momentum manager's on/off
    fractions [-] and capacity [N m s] (0 resolved to min_i Jw_i
    omega_max_i, the core's MomentumParams rule) or None, and B-dot on."""
    mc = getattr(scn, "magnetic_control", None)
    rods = getattr(scn.plant, "magnetorquers", None)
    if mc is None or rods is None:
        return {}
    mom = None
    if mc.momentum is not None:
        cap = float(mc.momentum.capacity)
        if cap == 0.0:
            cap = min(j * w for j, w in zip(np.asarray(scn.plant.Jw, float), _speed_limits(scn.actuators)))
        mom = {"on_fraction": float(mc.momentum.on_fraction), "off_fraction": float(mc.momentum.off_fraction),
               "capacity": float(cap)}
    return {"rod_max_dipole": [float(v) for v in np.asarray(rods.max_dipole, float)], "momentum": mom,
            "bdot": mc.bdot is not None}
