"""Every law's parameters in one scenario: the ``[laws.NAME]`` tables
(docs/SCENARIOS.md). One file serves ``compare`` and ``montecarlo`` across
laws: a run takes the table of the law it runs, and the law itself
validates it (the built-in laws as any plugin, through ``LawParams``), so
the scenario reader knows no law's parameter names.

A table's name is the law's registry name: a built-in ("dsc-ppc", "dsc",
"pd", "rft"), a plugin's declared name ("quaternion-feedback", not its
path), or a Python law's ``name`` attribute (default: its class name).

Older files keep loading: ``[controller.params]`` is the table of the law
the file runs; the tables ``[controller.dsc]`` and ``[controller.neso]``
(both laws of the paper), ``[controller.pd]`` and ``[controller.rft]``
become the built-in laws' tables, with one deprecation note
(``Scenario.deprecations``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sc_rt import _core
from sc_rt.pylaw import law_command, law_label, python_law
from sc_rt.scenario.schema import ScenarioIssue, Table, key_lines

__all__ = ["LEGACY_TABLES", "read_laws", "law_table_name", "command_of", "wheels_command", "resolved", "items_of",
           "with_items", "stray_tables", "NEAR", "report_issues"]

#: the tables of files written before [laws.NAME]: table -> (the laws it feeds, key prefix)
LEGACY_TABLES: dict[str, tuple[tuple[str, ...], str]] = {
    "dsc": (("dsc-ppc", "dsc"), ""),
    "neso": (("dsc-ppc", "dsc"), "neso_"),
    "pd": (("pd",), ""),
    "rft": (("rft",), ""),
}


def _numbers(t: Table, name: str, value: Any) -> tuple[float, ...] | None:
    vals = value if isinstance(value, list) else [value]
    if isinstance(value, bool):  # a flag: 1 or 0
        return (1.0 if value else 0.0,)
    if vals and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in vals):
        return tuple(float(x) for x in vals)
    t.fail(name, f"{name} must be a number, a list of numbers or true/false (a law parameter)")
    return None


def _table_items(t: Table) -> tuple | None:
    items, ok = [], True
    for name, value in (t.data or {}).items():
        t.used.add(name)
        vals = _numbers(t, name, value)
        ok = ok and vals is not None
        if vals is not None:
            items.append((name, vals))
    return tuple(items) if ok else None


def read_laws(root: Table, controller: Table, run_law: str | None) -> tuple[tuple, dict, list[str]] | None:
    """(the laws' tables ((name, items), ...), the dotted key of each
    (name, key) for errors, the deprecation notes), or None after reporting
    a problem. ``run_law``: the name of the law the file runs (for
    ``[controller.params]``)."""
    tables: dict[str, dict[str, tuple[float, ...]]] = {}
    where: dict[tuple[str, str], str] = {}
    notes: list[str] = []
    ok = True
    laws = root.sub("laws", required=False)
    for name, value in (laws.data or {}).items():
        laws.used.add(name)
        if not isinstance(value, dict):
            laws.fail(name, f"laws.{name} must be a table of the law's parameters ([laws.{name}])")
            ok = False
            continue
        t = Table(root.doc, f"laws.{name}", value)
        items = _table_items(t)
        if items is None:
            ok = False
            continue
        tables[name] = dict(items)
        where.update({(name, k): f"laws.{name}.{k}" for k, _ in items})
    if controller.has("params"):
        t = controller.sub("params")
        items = _table_items(t)
        if items is None:
            ok = False
        elif run_law is not None and run_law in tables and items:
            controller.fail("params", f"give the parameters of {run_law} once: [laws.{run_law}] or "
                                      "[controller.params], not both")
            ok = False
        elif run_law is not None:
            tables.setdefault(run_law, {}).update(dict(items))
            where.update({(run_law, k): f"controller.params.{k}" for k, _ in items})
    old = [name for name in LEGACY_TABLES if controller.has(name)]
    for name in old:
        t = controller.sub(name)
        items = _table_items(t)
        if items is None:
            ok = False
            continue
        feeds, prefix = LEGACY_TABLES[name]
        for law in feeds:
            table = tables.setdefault(law, {})
            for k, v in items:
                key = prefix + k
                if (law, key) in where and where[(law, key)].startswith("laws."):
                    continue  # [laws.NAME] wins over the older table
                table[key] = v
                where[(law, key)] = f"controller.{name}.{k}"
    if old:
        notes.append(f"{root.doc.path}: " + ", ".join(f"[controller.{n}]" for n in old)
                     + " read as the built-in laws' [laws.NAME] tables; write them so (docs/SCENARIOS.md, [laws])")
    if not ok:
        return None
    return tuple((name, tuple(table.items())) for name, table in tables.items()), where, notes


def report_issues(doc: Any, issues, spec: str, name: str, table: tuple, law_key: str, where: dict,
                  seen: set) -> None:
    """A law's check's ``issues`` ((key, message), ...) as errors of ``doc``:
    a parameter's (``params.KEY``) on its own dotted key (``where``: (law,
    key) -> dotted key; default ``laws.NAME.KEY``), the others on ``law_key``."""
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
            doc.error(dotted, None if value is None else (value[0] if len(value) == 1 else list(value)), message)
        else:
            doc.error(law_key, spec, message)


def law_table_name(spec: str) -> str:
    """The table name of a law spec: its registry name (a plugin's declared
    name: the library is loaded), or the spec itself (a Python law's is its
    ``name``, see ``sc_rt.pylaw.law_label``)."""
    if spec.startswith("plugin:"):
        return _core.law_info(spec)["name"]
    cls = python_law(spec)
    return spec if cls is None else law_label(cls)


def command_of(spec: str) -> str:
    """What a law spec's u_cmd is, ``"acceleration"`` or ``"torque"``
    (``sc_rt.pylaw.LAW_COMMANDS``): a plugin's declaration (the library is
    loaded), a Python law's ``command`` attribute; the built-ins command
    accelerations. ValueError when the law does not load."""
    cls = python_law(spec)
    return _core.law_info(spec)["command"] if cls is None else law_command(cls)


def wheels_command(scn: Any) -> str:
    """What a scenario's wheels take: its ``[wheels] command``, else
    ``"acceleration"`` (the paper's acceleration-commanded wheels)."""
    w = scn.actuators.wheels
    return "acceleration" if w is None else w.command


def _table_line(path: Any, name: str) -> int:
    """The line of the table [laws.NAME] in the file at ``path`` (0: unknown):
    its header, else its first key (``[laws]`` with ``NAME.k = ...``)."""
    try:
        lines = key_lines(Path(path).read_text(encoding="utf-8"))
    except (OSError, TypeError, UnicodeDecodeError):
        return 0
    key = f"laws.{name}"
    inside = [n for k, n in lines.items() if k.startswith(key + ".")]
    return lines.get(key) or min(inside, default=0) or lines.get("laws", 0)


#: How alike a table's name and a law's name must be (difflib's ratio, case
#: aside) for the table to be that law's misspelling rather than another law's.
NEAR = 0.6


def stray_tables(scn: Any, laws: tuple[str, ...] = (), names: tuple[str, ...] = ()) -> tuple[list[ScenarioIssue],
                                                                                             list[str]]:
    """The ``[laws.NAME]`` tables of ``scn`` that no law of this run reads,
    as (errors, notes). A table is named by its law: a built-in, the file's
    law, or one of ``laws`` (the laws a command names with --law; a plugin's
    declared name, a Python law's ``name``); ``names``: those laws' table
    names known already (a run's plan: no law is loaded again). Any other table is

    - an error when its name is near one of those (difflib ratio >= NEAR,
      case aside): a misspelling, which would leave that law on its
      defaults; on the table's line, naming the nearest law;
    - else a note: the table of a law this run does not run (a file that
      serves several laws through ``sc-rt compare --law``), read by none here.
    """
    import difflib

    builtins = list(_core.law_names())
    mine: list[str] = list(dict.fromkeys(names))
    for spec in () if names else (scn.run.controller, *laws):
        try:
            name = law_table_name(spec)
        except ValueError:  # a law that does not load: its own check says so
            name = spec
        if name not in mine:
            mine.append(name)
    # [controller.params] of a plugin or Python law: kept under its spec (file_law_name)
    known = list(dict.fromkeys(builtins + mine + [scn.run.controller, *laws]))
    lower = {k.lower(): k for k in known}
    errors, notes = [], []
    why = (f"a table is named by its law: a built-in ({', '.join(builtins)}) or a law of this run "
           f"({', '.join(mine)}), a plugin's declared name or a Python law's name")
    for name, _items in scn.controller.laws:
        if name in known:
            continue
        near = difflib.get_close_matches(name.lower(), list(lower), n=1, cutoff=NEAR)
        if near:
            errors.append(ScenarioIssue(_table_line(scn.path, name), f"laws.{name}", None,
                                        f'matches no law: the nearest law name is "{lower[near[0]]}" '
                                        f"([laws.{lower[near[0]]}]); as written no law reads it ({why})"))
        else:
            line = _table_line(scn.path, name)
            notes.append(f"{scn.path}{f':{line}' if line else ''}: [laws.{name}] is read by no law of this run "
                         f"({', '.join(mine)}): the table of another law (sc-rt compare --law), or misspelt")
    return errors, notes


def law_table_name_or(spec: str) -> str:
    """``law_table_name(spec)``, or the spec itself when the law does not load."""
    try:
        return law_table_name(spec)
    except ValueError:
        return spec


def items_of(laws: tuple, name: str) -> tuple:
    """The items ((key, (numbers...)), ...) of law ``name``'s table (() without one)."""
    for law, items in laws:
        if law == name:
            return items
    return ()


def resolved(laws: tuple, name: str) -> dict[str, Any]:
    """Law ``name``'s parameters as it runs them: its declared defaults
    (a built-in law's, ``_core.law_info``) overlaid with its table; one number
    as a float, more as an array."""
    defaults = dict(_core.law_info(name)["defaults"]) if name in _core.law_names() else {}
    values = {k: tuple(v) for k, v in defaults.items()}
    values.update(dict(items_of(laws, name)))
    return {k: (float(v[0]) if len(v) == 1 else np.asarray(v, float)) for k, v in values.items()}


def with_items(laws: tuple, name: str, **values: Any) -> tuple:
    """``laws`` with law ``name``'s table given ``values`` (key -> a number or
    numbers; the table is added when the law has none). Not validated: for
    studies that vary a parameter around a validated scenario."""
    def numbers(v: Any) -> tuple[float, ...]:
        return tuple(float(x) for x in np.atleast_1d(np.asarray(v, float)))

    out, done = [], False
    for law, items in laws:
        if law == name:
            table = dict(items)
            table.update({k: numbers(v) for k, v in values.items()})
            items, done = tuple(table.items()), True
        out.append((law, items))
    if not done:
        out.append((name, tuple((k, numbers(v)) for k, v in values.items())))
    return tuple(out)
