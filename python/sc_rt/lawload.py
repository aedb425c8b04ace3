"""A Python law named by a spec (``module:Class`` or ``path/to/file.py:Class``,
optionally prefixed ``python:``, the form a scenario's ``law`` key takes):
telling one, loading its class and its label. Below the scenario layer (a
scenario names its laws' tables by these labels); the contract a law class
keeps and the controller that runs it are in sc_rt.pylaw."""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path

__all__ = ["PYTHON_PREFIX", "is_python_law", "load_law", "law_label"]

#: the prefix of a Python law in a scenario file: ``law = "python:file.py:Class"``
PYTHON_PREFIX = "python:"


def is_python_law(spec: str | None) -> bool:
    """Whether ``spec`` names a Python class (``module:Class``, ``file.py:Class``,
    either with ``python:`` before it)."""
    return isinstance(spec, str) and ":" in spec and not spec.startswith("plugin:")


def load_law(spec: str) -> type:
    """The class named by ``[python:]module:Class`` or ``[python:]path/to/file.py:Class``.
    Raises ValueError with a one-line reason."""
    target = spec[len(PYTHON_PREFIX):] if spec.startswith(PYTHON_PREFIX) else spec
    mod_name, sep, cls_name = target.rpartition(":")
    if not sep or not mod_name or not cls_name.isidentifier():
        raise ValueError(f"--law {spec!r}: expected module:Class or file.py:Class")
    try:
        if mod_name.endswith(".py"):
            path = Path(mod_name)
            if not path.is_file():
                raise ValueError(f"--law {spec!r}: no such file {mod_name}")
            key = f"sc_rt_user_law_{abs(hash(str(path.resolve())))}"
            mod = sys.modules.get(key)
            if mod is None:
                s = importlib.util.spec_from_file_location(key, path)
                mod = importlib.util.module_from_spec(s)
                sys.modules[key] = mod
                s.loader.exec_module(mod)
        else:
            mod = importlib.import_module(mod_name)
    except ValueError:
        raise
    except Exception as e:  # the user's module failed to import: say so in one line
        raise ValueError(f"--law {spec!r}: cannot import {mod_name}: {type(e).__name__}: {e}") from e
    cls = getattr(mod, cls_name, None)
    if not isinstance(cls, type):
        raise ValueError(f"--law {spec!r}: {mod_name} has no class {cls_name}")
    for meth in ("reset", "step"):
        if not callable(getattr(cls, meth, None)):
            raise ValueError(f"--law {spec!r}: {cls_name} has no {meth}() method")
    return cls


def law_label(cls: type) -> str:
    """The run's label of a Python law: its ``name`` attribute, else the class name."""
    name = getattr(cls, "name", None)
    return name if isinstance(name, str) and name else cls.__name__
