"""A scenario as the TOML data it could have been read from, and its keys by
dotted name ("spacecraft.dJ", "faults[0].onset"): what the ``[montecarlo]``
table (dispersions.py) names, draws into, and re-reads through the file's
own checks (sc_rt.scenario.reader.scenario_from_data)."""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

import numpy as np

__all__ = ["element_names", "get_key", "is_number", "key_parts", "numeric_keys", "scenario_data", "set_key",
           "value_shape"]


def _plain(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer, np.bool_)):
        return v.item()
    return v


def _group(obj: Any) -> dict[str, Any]:
    return {f.name: _plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}


def scenario_data(scn: Any) -> dict[str, Any]:
    """The scenario as the parsed TOML of a file that reads back to the same
    numbers (the reader of sc_rt.scenario.model accepts it: no capture table,
    J0 and Cbar written out; every controller value written out)."""
    p, a, c = scn.plant, scn.actuators, scn.controller
    controller = {name: _group(getattr(c, name)) for name in ("ppc", "safety")}
    controller["pinv_damping"] = float(c.pinv_damping)
    # [laws.NAME]: every law's table as given (one number as a scalar)
    laws = {law: {k: (v[0] if len(v) == 1 else list(v)) for k, v in items} for law, items in c.laws}
    faults = []
    for f in a.faults:
        entry: dict[str, Any] = {"wheel": int(f.wheel) + 1, "onset": float(f.onset),
                                 "rate": float(f.rate), "stuck": bool(f.stuck)}  # fmt: skip
        if not f.stuck:  # the reader refuses effectiveness and bias next to stuck
            entry["effectiveness"] = float(f.effectiveness)
            entry["bias"] = float(f.bias)
            if a.wheels is not None:  # friction rise: torque-commanded wheels only
                entry["friction"] = float(f.friction)
        if f.end is not None:
            entry["end"] = float(f.end)
        faults.append(entry)
    return {
        "name": scn.name,
        "description": scn.description,
        **({"expect": scn.expect} if scn.expect else {}),
        "run": _group(scn.run),
        "spacecraft": {
            "J0": p.J0.tolist(), "dJ": p.dJ.tolist(), "Cbar": p.Cbar.tolist(), "Jw": p.Jw.tolist(),
            "umin": a.umin.tolist(), "umax": a.umax.tolist(), "w0": float(p.w0),
            "max_wheel_speed": a.max_wheel_speed.tolist(),
        },  # fmt: skip
        "disturbance": _group(p.disturbance),
        "initial": _group(scn.initial),
        "guidance": scn.guidance.data(),  # its kind's keys (sc_rt.scenario.tables.guidance)
        "controller": controller,
        **({"laws": laws} if laws else {}),
        "faults": faults,
        **_sensors(scn, controller),
        **_requirements(scn),
        **_wheels(a.wheels),
        **_orbit(p),
        **_magnetorquers(p.magnetorquers),
        **(scn.magnetic_control.data() if getattr(scn, "magnetic_control", None) is not None else {}),
    }


def _degrees(x: float) -> float:
    """x [rad] in degrees, chosen so that the reader's ``deg * pi / 180`` gives x back."""
    deg = x / (math.pi / 180.0)
    for d in (deg, math.nextafter(deg, math.inf), math.nextafter(deg, -math.inf)):
        if d * (math.pi / 180.0) == x:
            return d
    return deg


def _orbit(p: Any) -> dict[str, Any]:
    """The [orbit] and [environment] tables (the field and the residual dipole), if any."""
    o = getattr(p, "orbit", None)
    if o is None:
        return {}
    orbit = {"a": float(o.a), "e": float(o.e), "inclination": _degrees(o.i), "raan": _degrees(o.raan),
             "argp": _degrees(o.argp), "mean_anomaly": _degrees(o.M0), "jd_epoch": float(o.jd_epoch),
             "j2": bool(o.j2)}
    env = {"field": p.field_model, "residual_dipole": [float(v) for v in p.residual_dipole]}
    return {"orbit": orbit, "environment": env}


def _magnetorquers(r: Any) -> dict[str, Any]:
    """The [magnetorquers] table and its faults, if any."""
    if r is None:
        return {}
    faults = []
    for f in r.faults:
        entry: dict[str, Any] = {"rod": int(f.rod) + 1, "kind": f.kind, "onset": float(f.onset)}
        if f.kind == "stuck":
            entry["dipole"] = float(f.dipole)
        if math.isfinite(f.end):
            entry["end"] = float(f.end)
        faults.append(entry)
    return {"magnetorquers": {"G_B": r.axes.tolist(), "max_dipole": r.max_dipole.tolist(), "faults": faults}}


def _wheels(w: Any) -> dict[str, Any]:
    """The [wheels] table, every value written out per wheel, if any."""
    if w is None:
        return {}
    table: dict[str, Any] = {"command": w.command, "stribeck": bool(w.stribeck), "lag": [float(v) for v in w.lag]}
    if w.stribeck_switching:  # written only when on: a table without it reads back unchanged
        table["stribeck_switching"] = True
    for group in (w.limits, w.friction):
        for name in (f.name for f in dataclasses.fields(group[0])):
            table[name] = [float(getattr(g, name)) for g in group]
    return {"wheels": table}


def _requirements(scn: Any) -> dict[str, Any]:
    """The [[requirements]] rows, if any."""
    if not getattr(scn, "requirements", ()):
        return {}
    from sc_rt.scenario.tables.requirements import requirements_data

    return {"requirements": requirements_data(scn.requirements)}


def _sensors(scn: Any, controller: dict[str, Any]) -> dict[str, Any]:
    """The [sensors] table (and [controller] measurement, estimator), if any."""
    if getattr(scn, "sensors", None) is None:
        return {}
    from sc_rt.scenario.tables.sensors import sensors_data

    table, extra = sensors_data(scn.sensors)
    controller.update(extra)
    return {"sensors": table}


_PART_RE = re.compile(r"^([A-Za-z_][\w-]*)((?:\[\d+\])*)$")


def key_parts(key: str) -> list[str | int] | None:
    """The names and indices of dotted ``key`` ("faults[0].onset" -> ["faults", 0,
    "onset"]); None when it is not a key."""
    out: list[str | int] = []
    for part in key.split("."):
        m = _PART_RE.match(part)
        if not m:
            return None
        out.append(m.group(1))
        out.extend(int(i) for i in re.findall(r"\[(\d+)\]", m.group(2)))
    return out


def get_key(data: dict[str, Any], key: str) -> Any:
    """The value of dotted ``key`` ("faults[0].onset") in ``data``; KeyError if absent."""
    node: Any = data
    for p in key_parts(key) or [key]:
        try:
            node = node[p]
        except (KeyError, IndexError, TypeError):
            raise KeyError(key) from None
    return node


def set_key(data: dict[str, Any], key: str, value: Any) -> None:
    """Set dotted ``key`` in ``data`` (which must hold it already)."""
    parts = key_parts(key) or [key]
    node: Any = data
    for p in parts[:-1]:
        node = node[p]
    node[parts[-1]] = value


def is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def value_shape(v: Any) -> tuple[int, ...] | None:
    """Shape of a number, a list of numbers or a list of rows; None otherwise."""
    if is_number(v):
        return ()
    if isinstance(v, list) and v and all(is_number(x) for x in v):
        return (len(v),)
    if (isinstance(v, list) and v and all(isinstance(r, list) and r for r in v)
            and len({len(r) for r in v}) == 1 and all(is_number(x) for r in v for x in r)):  # fmt: skip
        return (len(v), len(v[0]))
    return None


#: Top-level tables of scenario data that are not the run's physics or
#: controller (what it is judged by): no key of theirs is dispersed.
NOT_DISPERSED = ("requirements",)


def numeric_keys(data: dict[str, Any]) -> dict[str, tuple[tuple[int, ...], bool]]:
    """Every numeric key of scenario data -> (shape, integer-valued); the
    requirements' keys are not among them (``NOT_DISPERSED``)."""
    out: dict[str, tuple[tuple[int, ...], bool]] = {}

    def walk(node: Any, key: str) -> None:
        if isinstance(node, dict):
            for k, v in node.items():
                if not key and k in NOT_DISPERSED:
                    continue
                walk(v, f"{key}.{k}" if key else k)
        elif isinstance(node, list) and node and all(isinstance(x, dict) for x in node):
            for i, v in enumerate(node):
                walk(v, f"{key}[{i}]")
        elif (shape := value_shape(node)) is not None:
            ints = all(isinstance(x, int) for x in np.asarray(node, dtype=object).flat)
            out[key] = (shape, ints)

    walk(data, "")
    return out


def element_names(key: str, shape: tuple[int, ...]) -> list[str]:
    """Column names of the elements of ``key``: key, key[i] or key[i][j]."""
    if shape == ():
        return [key]
    return [key + "".join(f"[{i}]" for i in idx) for idx in np.ndindex(*shape)]
