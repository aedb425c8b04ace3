"""``--law``: a law of the core's table (sc_rt.scenario.model.LAWS) or a
Python law ``module:Class`` / ``file.py:Class`` (sc_rt.pylaw), checked when
the command line is parsed: a class that does not import is refused in one
line (exit 2) before anything runs."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from sc_rt import _core
from sc_rt.pylaw import is_python_law, load_law
from sc_rt.scenario.model import LAWS, PLUGIN_PREFIX, law_spec

__all__ = ["law_choice", "core_law_choice", "LAW_HELP"]

LAW_HELP = (f"control law: {', '.join(LAWS)} (default: the scenario's), a C++ law plugin "
            "plugin:PATH_OR_NAME, or a Python law module:Class or path/file.py:Class (docs/LAWS.md)")


def plugin_choice(value: str) -> str:
    """A C++ law plugin ``plugin:PATH_OR_NAME``, loaded now (a relative path
    against the working directory): its problem in one line (exit 2)."""
    spec = law_spec(value, Path.cwd())
    try:
        _core.load_law_plugin(spec[len(PLUGIN_PREFIX):])
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from e
    return spec


def law_choice(value: str) -> str:
    if value in LAWS:
        return value
    if value.startswith(PLUGIN_PREFIX):
        return plugin_choice(value)
    if is_python_law(value):
        if os.getcwd() not in sys.path and "" not in sys.path:
            sys.path.insert(0, os.getcwd())  # module:Class from the working directory, as python -m does
        try:
            load_law(value)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e).removeprefix(f"--law {value!r}: ")) from e
        return law_spec(value, Path.cwd())  # python:..., a file made absolute (a worker's cwd may differ)
    raise argparse.ArgumentTypeError(f"{value!r} is not one of {', '.join(LAWS)} "
                                     "nor a Python law module:Class")


def core_law_choice(value: str) -> str:
    """Only a law of the core (commands that run the C++ controller)."""
    if value in LAWS:
        return value
    if value.startswith(PLUGIN_PREFIX):
        return plugin_choice(value)
    raise argparse.ArgumentTypeError(f"invalid choice: {value!r} (choose from {', '.join(LAWS)} "
                                     "or plugin:PATH_OR_NAME)")
