"""The ``[montecarlo]`` table of a scenario file: which keys a Monte Carlo
campaign disperses, and how (docs/SCENARIOS.md, "[montecarlo]").

    [montecarlo]
    on_invalid = "redraw"      # or "fail"; what a draw that breaks the scenario does
    max_redraws = 100          # attempts per run before the run counts as failed

    [[montecarlo.disperse]]
    key = "spacecraft.dJ"      # any numeric key of the scenario, as written in the file
    dist = "uniform"           # "uniform", "normal", "truncnormal" or "choice"
    low = -0.5                 # parameters: one number, or one per element
    high = 0.5
    apply = "add"              # value = nominal + draw; "scale": nominal * draw; "set": draw

Every element of a vector or matrix key is drawn independently; a 3x3 key
is drawn symmetric (the upper triangle, mirrored) unless ``symmetric =
false``. The keys name the scenario as resolved (``scenario_data``): a
capture scenario's ``spacecraft.J0`` and ``spacecraft.Cbar``, every
controller gain (given or default), ``faults[i].*`` of the faults present.

This module parses and validates the table (``read_montecarlo``, called by
the scenario reader) and draws values (``draw``); applying a draw and
validating the dispersed scenario is the campaign's (sc_rt.studies.campaign).
It is pure: no simulation, no file access.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sc_rt.scenario.keys import (element_names, get_key, numeric_keys, scenario_data,  # noqa: F401
                                 set_key, value_shape)

__all__ = [
    "DISTRIBUTIONS",
    "DispersionEntry",
    "MonteCarloTable",
    "draw",
    "read_montecarlo",
    # re-exported from keys.py, the names a table's keys refer to
    "element_names",
    "get_key",
    "numeric_keys",
    "scenario_data",
    "set_key",
]

#: distribution -> (required parameters, optional parameters with defaults)
DISTRIBUTIONS: dict[str, tuple[tuple[str, ...], dict[str, Any]]] = {
    "uniform": (("low", "high"), {}),
    "normal": (("std",), {"mean": 0.0}),
    "truncnormal": (("std", "low", "high"), {"mean": 0.0}),
    "choice": (("values",), {"weights": None}),
}
APPLY = ("add", "scale", "set")
ON_INVALID = ("redraw", "fail")
_TOP_KEYS = ("disperse", "on_invalid", "max_redraws")
_ENTRY_KEYS = ("key", "dist", "apply", "symmetric")


@dataclass(frozen=True)
class DispersionEntry:
    """One ``[[montecarlo.disperse]]`` entry, validated."""

    key: str  # dotted scenario key, e.g. "spacecraft.dJ", "faults[0].onset"
    dist: str  # one of DISTRIBUTIONS
    apply: str  # "add", "scale" or "set"
    params: dict[str, Any]  # plain numbers or nested lists (TOML values)
    symmetric: bool = True  # 3x3 keys: draw the upper triangle and mirror it


@dataclass(frozen=True)
class MonteCarloTable:
    """The ``[montecarlo]`` table, validated."""

    disperse: tuple[DispersionEntry, ...] = ()
    on_invalid: str = "redraw"  # "redraw": draw again (up to max_redraws); "fail": count as failed
    max_redraws: int = 100
    lines: dict[str, int] = field(default_factory=dict, compare=False)  # key -> line, for messages


# --------------------------------------------------------------------------- #
# Reading the table (called by the scenario reader with its Table objects).


def _fmt_shape(shape: tuple[int, ...]) -> str:
    return {0: "one number", 1: f"a list of {shape[0] if shape else 0} numbers"}.get(
        len(shape), f"a {shape[0]}x{shape[1]} array" if len(shape) == 2 else "")


def read_montecarlo(table: Any, scenario: Any | None) -> MonteCarloTable | None:
    """The validated ``[montecarlo]`` table (None when absent or invalid).

    ``table`` is the reader's table object of ``montecarlo`` (errors go to its
    document with file, line, key and value); ``scenario`` is the scenario
    read so far, or None when it has errors of its own (then the keys' names
    and shapes cannot be checked, everything else is).
    """
    if table.data is None or not table.data:
        table.used.update(table.data or ())
        return None
    doc = table.doc
    errors_before = len(doc.errors)
    on_invalid = table.raw("on_invalid") if table.has("on_invalid") else "redraw"
    if on_invalid not in ON_INVALID:
        table.fail("on_invalid", "on_invalid must be " + " or ".join(f'"{c}"' for c in ON_INVALID))
    max_redraws = table.raw("max_redraws") if table.has("max_redraws") else 100
    if not (isinstance(max_redraws, int) and not isinstance(max_redraws, bool)
            and 1 <= max_redraws <= 10000):  # fmt: skip
        table.fail("max_redraws", "max_redraws must be an integer in [1, 10000]")
    raw = table.raw("disperse") if table.has("disperse") else []
    table.used.update(_TOP_KEYS)
    table.finish()
    if not (isinstance(raw, list) and all(isinstance(e, dict) for e in raw)):
        table.fail("disperse", "disperse must be an array of tables ([[montecarlo.disperse]])")
        return None
    keys = numeric_keys(scenario_data(scenario)) if scenario is not None else None
    entries, seen = [], {}
    for i, e in enumerate(raw):
        t = type(table)(doc, f"{table.key}.disperse[{i}]", e)
        entry = _read_entry(t, keys)
        if entry is not None and entry.key in seen:
            t.fail("key", f"key {entry.key!r} is dispersed already by montecarlo.disperse"
                          f"[{seen[entry.key]}]: one entry per key")  # fmt: skip
            entry = None
        if entry is not None:
            seen[entry.key] = i
            entries.append(entry)
    if len(doc.errors) > errors_before:
        return None
    lines = {k: v for k, v in doc.lines.items() if k.startswith(table.key)}
    return MonteCarloTable(tuple(entries), on_invalid, max_redraws, lines)


def _read_entry(t: Any, keys: dict[str, tuple[tuple[int, ...], bool]] | None
                ) -> DispersionEntry | None:  # fmt: skip
    ok = True

    def bad(name: str, message: str) -> None:
        nonlocal ok
        t.fail(name, message)
        ok = False

    key, dist = t.raw("key"), t.raw("dist")
    for name in ("key", "dist"):
        if not t.has(name):
            t.doc.error(t.dotted(name), None, "required key is missing")
            ok = False
    if t.has("key") and not isinstance(key, str):
        bad("key", "key must be a string naming a numeric scenario key, e.g. \"spacecraft.dJ\"")
    if t.has("dist") and dist not in DISTRIBUTIONS:
        bad("dist", "dist must be one of " + ", ".join(f'"{d}"' for d in DISTRIBUTIONS))
        dist = None
    shape, ints = None, False
    key_ok = ok
    if ok and keys is not None:
        if key not in keys:
            close = difflib.get_close_matches(key, keys, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            t.fail("key", f"{key!r} is not a numeric key of this scenario{hint}")
            key_ok = False  # the parameters are still checked (their shapes cannot be)
        else:
            shape, ints = keys[key]
    apply = t.raw("apply") if t.has("apply") else ("set" if dist == "choice" else "add")
    if apply not in APPLY:
        bad("apply", "apply must be one of " + ", ".join(f'"{a}"' for a in APPLY))
    symmetric = t.raw("symmetric") if t.has("symmetric") else True
    if not isinstance(symmetric, bool):
        bad("symmetric", "symmetric must be true or false")
    elif t.has("symmetric") and shape is not None and not (len(shape) == 2 and shape[0] == shape[1]):
        bad("symmetric", f"symmetric applies to square matrices only ({key} has shape {shape})")
    if dist is None:
        t.used.update(_ENTRY_KEYS)
        t.used.update(k for spec in DISTRIBUTIONS.values() for k in (*spec[0], *spec[1]))
        t.finish()
        return None
    required, optional = DISTRIBUTIONS[dist]
    t.used.update(_ENTRY_KEYS + required + tuple(optional))
    params: dict[str, Any] = {}
    for name in required:
        if not t.has(name):
            t.doc.error(t.dotted(name), None, f"required key is missing (dist = \"{dist}\")")
            ok = False
    for name in (*required, *optional):
        if t.has(name):
            params[name] = t.raw(name)
        elif name in optional:
            params[name] = optional[name]
    t.finish()  # a parameter of another distribution is "unknown"
    if not ok:
        return None
    if dist == "choice":
        ok = _check_choice(t, params, shape, ints, apply, bad)
    else:
        ok = _check_numeric(t, dist, params, shape, bad)
        if ok and ints:
            bad("dist", f"{key} takes integers: disperse it with dist = \"choice\" of integers")
    if not ok or not key_ok:
        return None
    return DispersionEntry(key, dist, apply, params, symmetric)


def _check_numeric(t: Any, dist: str, params: dict[str, Any], shape, bad) -> bool:
    arrays = {}
    for name, v in params.items():
        s = value_shape(v)
        if s is None or (shape is not None and s not in ((), shape)):
            want = "one number" + (f" or {_fmt_shape(shape)} (one per element)" if shape else "")
            bad(name, f"{name} must be {want}")
            return False
        a = np.asarray(v, float)
        if not np.all(np.isfinite(a)):
            bad(name, f"{name} must be finite")
            return False
        arrays[name] = a
    if "std" in arrays and np.any(arrays["std"] < 0) or dist == "truncnormal" and np.any(arrays["std"] <= 0):
        bad("std", "std must be " + ("> 0" if dist == "truncnormal" else ">= 0"))
        return False
    if "low" in arrays and np.any(np.broadcast_arrays(arrays["low"], arrays["high"])[0]
                                  > np.broadcast_arrays(arrays["low"], arrays["high"])[1]):  # fmt: skip
        bad("low", "low must be <= high (for every element)")
        return False
    if dist == "truncnormal":
        from scipy.special import ndtr

        lo, hi, mu, sd = np.broadcast_arrays(arrays["low"], arrays["high"], arrays["mean"], arrays["std"])
        if np.any(lo >= hi):
            bad("low", "low must be < high for a truncated normal")
            return False
        mass = ndtr((hi - mu) / sd) - ndtr((lo - mu) / sd)
        if np.any(mass < 1e-12):
            bad("low", f"[low, high] holds a probability of {float(mass.min()):.3g} of the normal "
                       "(mean, std): the truncated normal cannot be drawn")  # fmt: skip
            return False
    return True


def _check_choice(t: Any, params: dict[str, Any], shape, ints: bool, apply: str, bad) -> bool:
    values, weights = params["values"], params["weights"]
    if not (isinstance(values, list) and values):
        bad("values", "values must be a non-empty list")
        return False
    shapes = {value_shape(v) for v in values}
    if len(shapes) != 1 or None in shapes or (shape is not None and shapes.pop() not in ((), shape)):
        want = "numbers" + (f", or of values of the key's shape {list(shape)}" if shape else "")
        bad("values", f"values must be a list of {want}")
        return False
    if not np.all(np.isfinite(np.asarray(values, float))):
        bad("values", "values must be finite")
        return False
    if ints and not (apply == "set" and all(isinstance(x, int) for x in np.asarray(values, dtype=object).flat)):
        bad("values", "values must be integers (the key takes integers) with apply = \"set\"")
        return False
    if weights is not None:
        w = np.asarray(weights, float) if value_shape(weights) == (len(values),) else None
        if w is None or not np.all(np.isfinite(w)) or np.any(w < 0) or not w.sum() > 0:
            bad("weights", f"weights must be {len(values)} numbers >= 0 (one per value), not all 0")
            return False
    return True


# --------------------------------------------------------------------------- #
# Drawing.


def draw(entry: DispersionEntry, nominal: Any, rng: np.random.Generator) -> Any:
    """The dispersed value of ``entry.key`` (same shape and kind as ``nominal``,
    plain Python numbers or nested lists, ready for the scenario reader)."""
    nom = np.asarray(nominal, float)
    shape = nom.shape
    p = entry.params
    sym = entry.symmetric and len(shape) == 2 and shape[0] == shape[1]

    def arr(name: str) -> np.ndarray:
        return np.broadcast_to(np.asarray(p[name], float), shape)

    if entry.dist == "uniform":
        x = rng.uniform(arr("low"), arr("high"))
    elif entry.dist == "normal":
        x = rng.normal(arr("mean"), arr("std"))
    elif entry.dist == "truncnormal":
        from scipy.stats import truncnorm

        mu, sd = arr("mean"), arr("std")
        u = rng.uniform(size=shape)
        x = truncnorm.ppf(u, (arr("low") - mu) / sd, (arr("high") - mu) / sd, loc=mu, scale=sd)
    else:  # choice
        values = np.asarray(p["values"], float)
        w = None if p["weights"] is None else np.asarray(p["weights"], float)
        w = None if w is None else w / w.sum()
        if values.shape[1:] == shape:  # whole values (or numbers for a scalar key)
            x = values[rng.choice(len(values), p=w)]
        else:  # numbers, chosen per element
            x = values[rng.choice(len(values), size=shape, p=w)]
    x = np.asarray(x, float).reshape(shape)
    if sym:
        x = np.triu(x) + np.triu(x, 1).T
    out = nom + x if entry.apply == "add" else nom * x if entry.apply == "scale" else x
    if all(isinstance(v, int) and not isinstance(v, bool) for v in np.asarray(nominal, dtype=object).flat):
        if entry.dist == "choice" and entry.apply == "set":
            return np.asarray(out).astype(int).tolist()
    return out.tolist()

