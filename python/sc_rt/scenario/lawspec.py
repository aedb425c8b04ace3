"""The law spec a scenario names (docs/LAWS.md): the core's law table
(``LAWS``), what a spec string may be (:func:`law_problem`), a spec's file
made absolute against the scenario's folder (:func:`law_spec`) and who a
spec is for the run's record (:func:`law_identity`).

A spec is a built-in name of ``LAWS``, ``plugin:PATH_OR_NAME`` or a Python
law ``python:FILE_OR_MODULE:Class``; the reader checks its form only and
loads no law (law code runs where the run is planned, sc_rt.plan.law).
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

from sc_rt import _core
from sc_rt.pylaw import PYTHON_PREFIX, is_python_law, law_label, python_law

__all__ = ["LAWS", "LAW_NAMES", "PLUGIN_PREFIX", "law_identity", "law_spec", "law_problem"]

# The law table: the core's law registry at import (the built-in laws: name ->
# code, = controller_status_t.law); every other module takes it from here. A
# plugin law is given as "plugin:PATH_OR_NAME" (docs/LAWS.md).
LAWS: dict[str, int] = {name: code for code, name in enumerate(_core.law_names())}
LAW_NAMES: dict[int, str] = {v: k for k, v in LAWS.items()}
PLUGIN_PREFIX = "plugin:"


def law_identity(spec: str) -> dict[str, Any]:
    """Who a law spec is, for the run's record and its log: ``name`` (the
    registered name: a plugin is labelled by it, not by its path), ``spec``,
    and for a plugin its ``source`` file and that file's ``sha256`` (the
    same name from another build is another law). A spec the registry does
    not know (an external controller) is its own name. A Python law is
    labelled by its ``name``; its file (when given by one) and that file's
    ``sha256`` are kept as a plugin's."""
    if (cls := python_law(spec)) is not None:
        target = spec[len(PYTHON_PREFIX):] if spec.startswith(PYTHON_PREFIX) else spec
        src = Path(target.rpartition(":")[0])
        is_file = src.suffix == ".py" and src.is_file()
        return {"name": law_label(cls), "spec": spec, "source": str(src) if is_file else "python",
                "sha256": hashlib.sha256(src.read_bytes()).hexdigest() if is_file else None}
    if not spec.startswith(PLUGIN_PREFIX):
        return {"name": spec, "spec": spec, "source": "built-in" if spec in LAWS else "external"}
    info = _core.law_info(spec)  # loads the plugin (refused before a run when it cannot be)
    src = Path(info["source"])
    sha = hashlib.sha256(src.read_bytes()).hexdigest() if src.is_file() else None
    return {"name": info["name"], "spec": spec, "source": str(src), "sha256": sha}


def law_spec(spec: str, base: Path) -> str:
    """``spec`` with a relative plugin file path made absolute against ``base``
    (a path: has a "/" or ends in ".so"; a plugin name is searched in
    SCRT_LAW_PATH by the core), and so a Python law's file
    (``python:file.py:Class``; ``file.py:Class`` and ``module:Class`` get the
    prefix)."""
    if is_python_law(spec) and not spec.startswith(PYTHON_PREFIX):
        spec = PYTHON_PREFIX + spec
    if spec.startswith(PYTHON_PREFIX):
        target, sep, cls = spec[len(PYTHON_PREFIX):].rpartition(":")
        if sep and target.endswith(".py") and not Path(target).is_absolute():
            return f"{PYTHON_PREFIX}{(base / target).resolve()}:{cls}"
        return spec
    if not spec.startswith(PLUGIN_PREFIX):
        return spec
    target = spec[len(PLUGIN_PREFIX):]
    if ("/" in target or target.endswith(".so")) and not Path(target).is_absolute():
        return PLUGIN_PREFIX + str((base / target).resolve())
    return spec


def law_problem(spec: Any) -> str:
    """Why ``spec`` cannot name a law ("" if it can: a name of LAWS or of a
    loaded plugin, or "plugin:PATH_OR_NAME"; the plugin itself is checked by
    sc_rt.plan.law.probe_law, where a run is planned)."""
    if not isinstance(spec, str):
        return "must be a string"
    if spec.startswith(PLUGIN_PREFIX):
        return "" if spec[len(PLUGIN_PREFIX):] else "plugin: needs a library path or name"
    if spec.startswith(PYTHON_PREFIX):  # the class itself is checked by sc_rt.plan.law.probe_law
        return "" if ":" in spec[len(PYTHON_PREFIX):] else "python: needs module:Class or file.py:Class"
    if spec in LAWS or spec in _core.law_names():
        return ""
    return ("must be one of " + ", ".join(f'"{n}"' for n in _core.law_names())
            + ', "plugin:PATH_OR_NAME" or "python:FILE_OR_MODULE:Class" (docs/LAWS.md)')
