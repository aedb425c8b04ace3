"""The declared per-row fields of a run (``FIELDS``): name, shape of one
row, unit, where the value comes from, and what it means; the table every
producer fills and every reader reads (results/record/run.py ``Run``).

The core's fields are not written here: they are read at import from
``_core.FIELD_TABLE`` (cpp/include/sc_rt/fields.hpp, the one table); only
the fields Python alone produces are declared below."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sc_rt import _core

__all__ = ["Field", "FIELDS", "FIELD", "CORE_FIELDS", "COLUMNS", "SOURCES", "empty_arrays", "packed_layout",
           "core_fields", "merge_fields"]

SOURCES = ("plant", "controller", "truth", "timing", "derived", "estimator")


@dataclass(frozen=True)
class Field:
    """One per-row array of a run.

    ``FIELDS`` (public as ``sc_rt.FIELDS``) is the tuple of every one, in the
    order trajectory.arrow's columns list them; ``FIELD`` maps name -> Field.

    Attributes
    ----------
    name : str
        The array's name (``run[name]``).
    shape : tuple of int
        The shape of one row (``()``: a scalar per row).
    unit : str
        Its unit ("s", "rad/s", "rad/s^2", "us", "-" for none).
    source : str
        Where the value comes from: one of ``SOURCES``.
    doc : str
        What it means (the equation numbers are docs/MODEL.md's).
    dtype : str
        Its numpy dtype ("f8", "i8", "?").
    fill : Any
        The value of a row the producer did not fill (NaN; -1, 0 or False
        for the integer and boolean fields).
    core : bool
        Part of the trajectory every producer fills (checked for finiteness
        by the metrics).
    """

    name: str
    shape: tuple[int, ...]  # of one row
    unit: str
    source: str  # one of SOURCES
    doc: str
    dtype: str = "f8"
    fill: Any = math.nan
    #: part of the trajectory every producer fills (checked for finiteness by the metrics)
    core: bool = False
    #: "" (the unit is fixed), "command": the wheel command's unit, resolved
    #: per run from the wheels' interface, or "law": the unit the law
    #: commands (its own states; ``resolved_unit``)
    unit_rule: str = ""

    def resolved_unit(self, torque_command: bool, law_torque: bool | None = None) -> str:
        """The unit on a run whose wheels take torque (``torque_command``) or
        acceleration commands, its law commanding torques (``law_torque``;
        None: unknown, taken as the wheels'): "N m" or "rad/s^2" under the
        "command" rule (the wheels') and the "law" rule (the law's), else
        ``unit``."""
        if self.unit_rule == "law":
            torque_command = torque_command if law_torque is None else law_torque
        if self.unit_rule in ("command", "law"):
            return "N m" if torque_command else "rad/s^2"
        return self.unit


def _f(name, shape, unit, source, doc, core=False, dtype="f8", fill=math.nan) -> Field:
    return Field(name, shape, unit, source, doc, dtype, fill, core)


def _fill(dtype: str, name: str) -> Any:
    """A core field's fill value: NaN for floats; -1 for ``ctrl_mode`` (no
    step ran) and the magnetic part's modes ``unloading``, ``detumble_mode``
    (none kept), 0 for the other integers."""
    if dtype != "i8":
        return math.nan
    return -1 if name in ("ctrl_mode", "unloading", "detumble_mode") else 0


def core_fields(table=None) -> tuple[Field, ...]:
    """The fields the C++ core declares (``_core.FIELD_TABLE``, built from
    cpp/include/sc_rt/fields.hpp), as ``Field`` rows in table order.

    Parameters
    ----------
    table : list of dict, optional
        The table to read (default: ``_core.FIELD_TABLE``); a test hands a
        copy to see that an edit shows.
    """
    rows = _core.FIELD_TABLE if table is None else table
    return tuple(Field(r["name"], () if r["width"] == 1 else (r["width"],), r["unit"], r["source"], r["doc"],
                       r["dtype"], _fill(r["dtype"], r["name"]), r["core"], r["unit_rule"]) for r in rows)


#: The fields only Python produces (the emulator, the sensed engine's
#: derivations, the bench's timing), each after the core field it follows in
#: a run's file (None: at the end).
_PYTHON_FIELDS: dict[str | None, tuple[Field, ...]] = {
    "lam": (
        _f("bound_ok", (3,), "-", "derived",
           "-dmin chi(t) < sigma_BD < dmax chi(t) per axis, from the scenario's envelope", True, "?", False),
    ),
    "ctrl_mode": (
        _f("cmd_seq_applied", (), "-", "truth", "seq of the wheel_cmd_t the plant applied (-1: none)",
           dtype="i8", fill=-1),
        _f("cmd_stale", (), "-", "truth", "1 when the watchdog applied zero (no valid command)",
           dtype="i8", fill=0),
        _f("fault_Y", (4,), "-", "truth", "fault evolution Y_i(t) (16)"),
        _f("fault_effectiveness", (4,), "-", "truth", "wheel effectiveness L_i of the active fault"),
        _f("fault_bias", (4,), "rad/s^2", "truth", "wheel bias of the active fault"),
        _f("fault_stuck", (4,), "-", "truth", "1 when the wheel is stuck", dtype="i8", fill=0),
    ),
    None: (
        _f("sigma_BD_true", (3,), "-", "derived",
           "true tracking error mrp_subtract(sigma_BN, sigma_DN) (sensor runs: the bound is judged on it)"),
        _f("omega_BD_B_true", (3,), "rad/s", "derived",
           "true rate tracking error omega_BN_B - [BD] omega_DN_D(t), [BD] of sigma_BD_true (sensor runs)"),
        _f("latency_us", (), "us", "timing", "state publish to receipt of the command answering it"),
        _f("tick_lateness_us", (), "us", "timing", "real time: the emulator's tick behind its deadline"),
        _f("wake_lateness_us", (), "us", "timing", "the controller's wake behind its schedule"),
        _f("compute_us", (), "us", "timing", "the controller's compute time for this state"),
        _f("state_age_us", (), "us", "timing", "age of the state when the controller used it"),
        _f("state_log_us", (), "us", "timing", "logger receive time of the state (log rebuilds)"),
    ),
}


def merge_fields(core: tuple[Field, ...]) -> tuple[Field, ...]:
    """The core's fields with the Python-only ones at their places."""
    out: list[Field] = []
    for f in core:
        out.append(f)
        out.extend(_PYTHON_FIELDS.get(f.name, ()))
    out.extend(_PYTHON_FIELDS[None])
    return tuple(out)


#: Every per-row array of a run, in the order trajectory.arrow's columns list them: the
#: core's table (``_core.FIELD_TABLE``) with the Python-only fields merged in.
FIELDS: tuple[Field, ...] = merge_fields(core_fields())
FIELD: dict[str, Field] = {f.name: f for f in FIELDS}
#: The fields as the columns of a run's file (results/record/store.py ``Column``: name, row shape, dtype, fill).
COLUMNS: tuple[tuple[str, tuple[int, ...], str, Any], ...] = tuple((f.name, f.shape, f.dtype, f.fill) for f in FIELDS)
#: The trajectory every producer fills (checked for finiteness by the metrics).
CORE_FIELDS: tuple[str, ...] = tuple(f.name for f in FIELDS if f.core)
assert all(f.source in SOURCES for f in FIELDS)


def empty_arrays(n: int) -> dict[str, np.ndarray]:
    """Every field of ``n`` rows at its fill value."""
    return {f.name: np.full((n, *f.shape), f.fill, dtype=f.dtype) for f in FIELDS}


def packed_layout(fields, size: int) -> dict[str, slice]:
    """name -> slice of a packed row of the core (``_core.PACKED_FIELDS``,
    ``_core.NAV_FIELDS``: (name, width) in the order the C++ writes them);
    ValueError when the widths do not add up to ``size``."""
    out: dict[str, slice] = {}
    at = 0
    for name, n in fields:
        out[name] = slice(at, at + n)
        at += n
    if at != size:
        raise ValueError(f"the packed fields add up to {at}, not {size}")
    return out
