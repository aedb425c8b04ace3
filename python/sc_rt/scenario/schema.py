"""Schema machinery of the scenario files (sc_rt.scenario.model): field specs,
value conversion with bounds, the file/line locator (tomllib gives no
positions) and the error types. Generic: nothing here knows about
spacecraft."""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

# --------------------------------------------------------------------------- #
# Field specifications: what a TOML value must look like. A dataclass below
# carries one in each field's metadata, so the dataclass is the schema.


@dataclass(frozen=True)
class Spec:
    kind: str  # "number" | "int" | "bool" | "str" | "vector" | "matrix"
    shape: tuple[int, ...] = ()  # (n,) for a vector, (rows, cols) for a matrix
    scalar_ok: bool = False  # a vector may be given as one number for all
    gt: float | None = None
    ge: float | None = None
    le: float | None = None
    allow_inf: bool = False  # +inf is a valid value (a limit that is "none")
    mrp: bool = False  # a 3-vector that must satisfy |sigma| <= 1
    choices: tuple[str, ...] = ()


def spec(kind: str, **kw: Any) -> dict[str, Spec]:
    return {"spec": Spec(kind, **kw)}


def vector_spec(n: int, **kw: Any) -> dict[str, Spec]:
    return spec("vector", shape=(n,), **kw)


def read_only(a: Any) -> np.ndarray:
    """A read-only float copy: the dataclasses holding it are frozen."""
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


# --------------------------------------------------------------------------- #
# Errors.


class ScenarioIssue(NamedTuple):
    """One problem of a scenario file."""

    line: int  # 1-based; 0 when no line applies
    key: str  # dotted key, e.g. "controller.ppc.chi0" or "faults[1].wheel"
    value: Any  # the value as read from the file; None when the key is missing
    message: str


class ScenarioError(ValueError):
    """A scenario file is unreadable or invalid; ``errors`` lists every problem.

    A ValueError; its message has one line per problem,
    ``path:line: key = value: message``.

    Parameters
    ----------
    path : str or Path
        The file (or what stands for it, e.g. ``"<file> (override)"`` for
        an override); kept as a string.
    errors : list of ScenarioIssue
        Every problem found: line (0: none applies), dotted key, value as
        read (None: the key is missing) and message.

    Attributes
    ----------
    path : str
        ``path`` as a string.
    errors : list of ScenarioIssue
        ``errors``, sorted by line.
    """

    def __init__(self, path: str | Path, errors: list[ScenarioIssue]):
        self.path = str(path)
        self.errors = sorted(errors, key=lambda e: e.line)
        super().__init__("\n".join(_format_issue(self.path, e) for e in self.errors))

    def __reduce__(self):  # pickled whole (a pool worker's, a child's): path and errors, not the text
        return type(self), (self.path, self.errors)


def _format_issue(path: str, e: ScenarioIssue) -> str:
    where = f"{path}:{e.line}: " if e.line else f"{path}: "
    what = e.key + ("" if e.value is None else f" = {format_value(e.value)}")
    return f"{where}{what}: {e.message}" if what else f"{where}{e.message}"


def format_value(v: Any) -> str:
    """A value as TOML would write it."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(format_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{...}"  # a table: its keys are reported one by one
    return str(v)


# --------------------------------------------------------------------------- #
# Line locator: tomllib gives no positions, so scan the text for table headers
# and "key =" lines (best effort; multi-line arrays and strings are skipped).

_HEADER_RE = re.compile(r"^\s*(\[\[?)\s*([^\[\]]+?)\s*\]\]?\s*(?:#.*)?$")
_KEY_PART = r"""(?:[\w-]+|"[^"]*"|'[^']*')"""
_KEY_RE = re.compile(rf"^\s*({_KEY_PART}(?:\s*\.\s*{_KEY_PART})*)\s*=")
_KEY_PART_RE = re.compile(r""""([^"]*)"|'([^']*)'|([^.\s]+)""")
_STRING_RE = re.compile(r""""(?:\\.|[^"\\])*"|'[^']*'""")


def _split_key(text: str) -> list[str]:
    return ["".join(p) for p in _KEY_PART_RE.findall(text)]


def _bracket_depth(text: str) -> int:
    code = _STRING_RE.sub("", text).split("#", 1)[0]
    return code.count("[") + code.count("{") - code.count("]") - code.count("}")


def key_lines(text: str) -> dict[str, int]:
    """Dotted key (``a.b.c``, ``faults[0].wheel``) -> its 1-based line."""
    lines: dict[str, int] = {}
    table: list[str] = []
    array_counts: dict[str, int] = {}
    depth, open_string = 0, ""
    for n, line in enumerate(text.splitlines(), 1):
        if open_string:  # inside a multi-line string
            open_string = "" if open_string in line else open_string
            continue
        if depth > 0:  # inside a multi-line array or inline table
            depth += _bracket_depth(line)
            continue
        if m := _HEADER_RE.match(line):
            table = _split_key(m.group(2))
            if m.group(1) == "[[":  # array of tables: name the element by its index
                base = ".".join(table)
                table[-1] += f"[{array_counts.get(base, 0)}]"
                array_counts[base] = array_counts.get(base, 0) + 1
            lines.setdefault(".".join(table), n)
        elif m := _KEY_RE.match(line):
            lines.setdefault(".".join(table + _split_key(m.group(1))), n)
            rest = line[m.end() :]
            open_string = next((q for q in ('"""', "'''") if rest.count(q) % 2), "")
            depth = _bracket_depth(rest)
    return lines


# --------------------------------------------------------------------------- #
# Reading: typed values out of the parsed TOML, every problem collected.

_REQUIRED = object()


class Doc:
    """The file being read: its path, key lines and the problems found."""

    def __init__(self, path: str, lines: dict[str, int]):
        self.path = path
        self.lines = lines
        self.errors: list[ScenarioIssue] = []

    def line_of(self, key: str) -> int:
        """Line of ``key``, else of its nearest enclosing table, else 0."""
        while key:
            if key in self.lines:
                return self.lines[key]
            key = key.rpartition(".")[0]
        return 0

    def error(self, key: str, value: Any, message: str) -> None:
        self.errors.append(ScenarioIssue(self.line_of(key), key, value, message))


def _bounds(s: Spec) -> str:
    lo = f"[{s.ge:g}" if s.ge is not None else f"({s.gt:g}" if s.gt is not None else None
    if lo and s.le is not None:
        return f"in {lo}, {s.le:g}]"
    return f">= {s.ge:g}" if s.ge is not None else f"> {s.gt:g}" if s.gt is not None else ""


def _in_bounds(x: float, s: Spec) -> bool:
    return (
        (s.gt is None or x > s.gt) and (s.ge is None or x >= s.ge) and (s.le is None or x <= s.le)
    )


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def convert(v: Any, s: Spec) -> tuple[Any, str]:
    """(typed value, "") or (None, what is wrong)."""
    if s.kind == "bool":
        return (v, "") if isinstance(v, bool) else (None, "must be true or false")
    if s.kind == "str":
        if not isinstance(v, str):
            return None, "must be a string"
        if s.choices and v not in s.choices:
            return None, "must be one of " + ", ".join(f'"{c}"' for c in s.choices)
        return v, ""
    if s.kind == "int" and not (isinstance(v, int) and not isinstance(v, bool)):
        return None, "must be an integer"
    if s.kind in ("number", "int"):
        if not _is_number(v):
            return None, "must be a number"
        if not (math.isfinite(v) or (s.allow_inf and v == math.inf)):
            return None, "must be finite"
        if not _in_bounds(v, s):
            return None, f"must be {_bounds(s)}"
        return (v if s.kind == "int" else float(v)), ""
    # vector or matrix
    if s.kind == "vector" and s.scalar_ok and _is_number(v):
        v = [v] * s.shape[0]
    shape_text = (
        f"a list of {s.shape[0]} numbers" + (" or one number" if s.scalar_ok else "")
        if s.kind == "vector"
        else f"a {s.shape[0]}x{s.shape[1]} array ({s.shape[0]} rows of {s.shape[1]} numbers)"
    )
    rows = v if s.kind == "matrix" and isinstance(v, list) else [v]
    if not (
        isinstance(v, list)
        and len(rows) == (s.shape[0] if s.kind == "matrix" else 1)
        and all(isinstance(r, list) and len(r) == s.shape[-1] for r in rows)
        and all(_is_number(x) for r in rows for x in r)
    ):
        return None, f"must be {shape_text}"
    a = np.array(v, dtype=float)
    if not np.all(np.isfinite(a) | (s.allow_inf & (a == np.inf))):
        return None, "must be finite"
    if not all(_in_bounds(x, s) for x in a.flat):
        return None, f"must have every element {_bounds(s)}"
    if s.mrp and np.linalg.norm(a) > 1.0 + 1e-12:
        norm = np.linalg.norm(a)
        return None, f"must be an MRP with norm <= 1, got norm {norm:.4g} (MRP, not degrees?)"
    return read_only(a), ""


class Table:
    """One TOML table being read. data None: missing or broken (reported once)."""

    def __init__(self, doc: Doc, key: str, data: dict[str, Any] | None):
        self.doc, self.key, self.data = doc, key, data
        self.used: set[str] = set()

    def dotted(self, name: str) -> str:
        return f"{self.key}.{name}" if self.key else name

    def has(self, name: str) -> bool:
        return self.data is not None and name in self.data

    def raw(self, name: str) -> Any:
        return self.data.get(name) if self.data is not None else None

    def sub(self, name: str, required: bool = True) -> Table:
        """The sub-table ``name``; an optional missing one reads as empty."""
        self.used.add(name)
        key = self.dotted(name)
        if self.data is None:
            return Table(self.doc, key, None)
        if name not in self.data:
            if required:
                self.doc.error(key, None, "required table is missing")
            return Table(self.doc, key, None if required else {})
        value = self.data[name]
        if not isinstance(value, dict):
            self.doc.error(key, value, f"{name} must be a table")
            return Table(self.doc, key, None)
        return Table(self.doc, key, value)

    def read(self, name: str, spec: Spec, default: Any = _REQUIRED, missing: str = "") -> Any:
        """The typed value of ``name``, its default, or None after reporting a problem."""
        self.used.add(name)
        if self.data is None:
            return None
        if name not in self.data:
            if default is _REQUIRED:
                self.doc.error(self.dotted(name), None, missing or "required key is missing")
                return None
            return default
        value, problem = convert(self.data[name], spec)
        if problem:
            self.doc.error(self.dotted(name), self.data[name], f"{name} {problem}")
        return value

    def fail(self, name: str, message: str) -> None:
        """Report a problem of a key that read well (a cross-check)."""
        self.doc.error(self.dotted(name), self.raw(name), message)

    def finish(self) -> None:
        """Report every key that was never read."""
        for name, value in (self.data or {}).items():
            if name not in self.used:
                close = difflib.get_close_matches(name, self.used, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                kind = "table" if isinstance(value, dict) else "key"
                self.doc.error(self.dotted(name), value, f"unknown {kind}{hint}")


def field_spec(cls: type, name: str) -> Spec:
    return next(f.metadata["spec"] for f in dataclasses.fields(cls) if f.name == name)


def read_fields(t: Table, cls: type) -> Any:
    """An instance of dataclass ``cls`` from table ``t`` (None if any field failed)."""
    values = read_values(t, cls)
    return None if any(v is None for v in values.values()) else cls(**values)


def read_values(t: Table, cls: type) -> dict[str, Any]:
    """The fields of dataclass ``cls`` from table ``t``, None for each that failed.

    The fields' metadata hold the specs, their defaults the defaults.
    """
    values = {}
    for f in dataclasses.fields(cls):
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            default = _REQUIRED
        values[f.name] = t.read(f.name, f.metadata["spec"], default)
    t.finish()
    return values


def build(t: Table, cls: type, nullable: tuple[str, ...] = (), **fields: Any) -> Any:
    """``cls(**fields)`` once every field read well (is not None, but for
    ``nullable`` ones), else None.

    The plant's and actuators' dataclasses validate themselves too; a
    problem only they see is reported on the table instead of escaping.
    """
    if any(v is None for k, v in fields.items() if k not in nullable):
        return None
    try:
        return cls(**fields)
    except ValueError as e:
        t.doc.error(t.key, None, str(e))
        return None
