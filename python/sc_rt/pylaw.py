"""Control laws written in Python (docs/LAWS.md, "Python laws").

A Python law runs inside the core's ``Controller``, through the same door as
a C++ law (cpp/include/sc_rt/law.hpp; the trampoline is
cpp/bindings/pylaw_bindings.cpp): the controller's policy (validation, SAFE,
re-engagement, containment of a failing law) is the C++ one, so a Python law
runs on every engine, with sensors and the estimator, in ``montecarlo`` and
in ``sc-rt controller``. A law is a class:

- ``Law(setup)``: ``setup.model`` (``_core.LawModel``: J0, J0_inv, Cbar, Jw,
  umin, umax, wheel_torque_command, wheel_speed_max, w0, B, B_pinv,
  ``wheels_for_torque(tau)``, ``wheel_command(a)``), ``setup.control_rate_hz``,
  ``setup.params`` (its own table, ``[laws.NAME]`` of the scenario with NAME
  its ``name``, as a dict; a key it never reads is an unknown parameter). A bad
  value: raise ``LawParamError(key, why)``;
- ``reset(inp)`` and ``step(inp)`` with ``inp`` a ``_core.LawInput`` (t,
  t_engaged, dt, m, ref, e, ppc, u_sat_prev: the C++ LawInput, read-only);
- ``step`` returns u_cmd (4,) in the unit the law declares (``command``
  below: [rad/s^2] by default), or ``(u_cmd, telemetry)`` with a dict
  holding any of the fixed slots ``TELEMETRY`` (e1, e2, z1, z2, x2d, vs,
  rho_hat) and the law's named values;
- optional: ``telemetry_names`` (at most ``_core.LAW_MAX_TELEMETRY`` names,
  a sequence or a method, read once at setup: the names ``step`` may give,
  recorded in the run, the status and the log), ``after(u_cmd, u_sat)``
  (anti-windup, in the law's unit), ``name`` (default: the class name; labels
  the run and names its table), ``command``: what u_cmd is, ``"acceleration"``
  (wheel accelerations [rad/s^2], the default) or ``"torque"`` (motor torques
  [N m]); on wheels that take the other the controller converts it exactly
  (``law_command``; docs/LAWS.md, "What a law commands").

A command that is not real numbers of shape exactly (4,) (a list or array of
ints or floats; (2, 2), (4, 1), (1, 4), bool, complex or objects are not
reshaped or converted), a telemetry value not of its slot's shape (a named
value or rho_hat: a scalar or (1,)), an undeclared telemetry name, an
exception or a non-finite command is a failure of the law, contained by the
controller as SAFE + FLAG_LAW_INVALID and counted in ``law_failures``.

A law is named by a spec (``[python:]module:Class`` or
``[python:]path/to/file.py:Class``) or given as a class; ``register`` puts it
in the core's registry under ``python:...``, after which a
``ControllerConfig`` with that law runs it. This module sits below the
scenario layer (a scenario names its Python law and that law's table).
"""

from __future__ import annotations

import atexit
import importlib
import importlib.util
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt import _core
from sc_rt.isolate import beat

__all__ = ["PYTHON_PREFIX", "TELEMETRY", "LAW_COMMANDS", "LawParamError", "LawSetup", "is_python_law",
           "load_law", "law_command", "law_label", "law_spec", "python_law", "register", "registry_spec",
           "split_unit", "FLAG_LAW_INVALID"]

#: what a law's u_cmd may be, and its unit
LAW_COMMANDS: dict[str, str] = {"acceleration": "rad/s^2", "torque": "N m"}

#: the prefix of a Python law's spec: ``law = "python:file.py:Class"``
PYTHON_PREFIX = "python:"
#: wheel_cmd_t.FLAG_LAW_INVALID: the law gave a non-finite command or failed
FLAG_LAW_INVALID = int(_core.FLAG_LAW_INVALID)
#: The fixed telemetry slots (the C++ LawOutput's): name -> (offset, width)
#: in the adapter's output row, after u_cmd (4).
TELEMETRY: dict[str, tuple[int, int]] = {"e1": (4, 3), "e2": (7, 3), "z1": (10, 3), "z2": (13, 3),
                                         "x2d": (16, 3), "vs": (19, 4), "rho_hat": (23, 1)}
_NAMED = 24  # the named telemetry's offset in the row
assert _NAMED + _core.LAW_MAX_TELEMETRY == _core.PYTHON_LAW_OUT_SIZE

#: classes registered as classes (not loadable by a spec): spec -> class
_CLASSES: dict[str, type] = {}
# the registry's Python laws go before the interpreter does (their factories hold Python objects)
atexit.register(_core.clear_python_laws)


class LawParamError(ValueError):
    """A bad parameter of a Python law: reported as ``laws.NAME.key``, with
    the scenario's file and line, like a C++ law's."""

    def __init__(self, key: str, why: str):
        super().__init__(why)
        self.key = key


@dataclass(frozen=True)
class LawSetup:
    """The constructor's argument (the C++ LawSetup)."""

    model: Any  # _core.LawModel
    control_rate_hz: float
    params: dict[str, Any]  # the law's own table ([laws.NAME]): key -> float or array


def is_python_law(spec: Any) -> bool:
    """Whether ``spec`` names a Python class (``module:Class``, ``file.py:Class``,
    either with ``python:`` before it)."""
    return isinstance(spec, str) and ":" in spec and not spec.startswith("plugin:")


def _prefixed(spec: str) -> str:
    return spec if spec.startswith(PYTHON_PREFIX) else PYTHON_PREFIX + spec


def load_law(spec: str) -> type:
    """The class named by ``[python:]module:Class`` or ``[python:]path/to/file.py:Class``
    (or registered as a class). Raises ValueError with a one-line reason."""
    if (cls := _CLASSES.get(_prefixed(spec))) is not None:
        return cls
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
                try:
                    s.loader.exec_module(mod)
                except BaseException:
                    del sys.modules[key]
                    raise
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


def split_unit(name: str) -> tuple[str, str]:
    """("tau_x", "N m") of a telemetry name declared "tau_x [N m]"; (name, "") without a unit."""
    base, sep, rest = name.partition(" [")
    return (base, rest[:-1]) if sep and rest.endswith("]") else (name, "")


def law_label(cls: type) -> str:
    """The run's label of a Python law: its ``name`` attribute, else the class name."""
    name = getattr(cls, "name", None)
    return name if isinstance(name, str) and name else cls.__name__


def law_command(cls: type) -> str:
    """What a Python law's u_cmd is: its ``command`` attribute, one of
    ``LAW_COMMANDS`` (default ``"acceleration"``). Raises ValueError (one
    line, naming the law and the attribute) for anything else."""
    command = getattr(cls, "command", "acceleration")
    if command not in LAW_COMMANDS:
        raise ValueError(f"law {law_label(cls)}: command = {command!r}: must be one of "
                         f"{', '.join(repr(c) for c in LAW_COMMANDS)} (what u_cmd is)")
    return command


def law_spec(law: str | type) -> str:
    """The registry spec (``python:...``) of a Python law given as a spec or a
    class. A class that its module does not expose by name (defined in a
    function) gets a spec of its own in this process."""
    if isinstance(law, str):
        return _prefixed(law)
    mod = sys.modules.get(law.__module__)
    if getattr(mod, law.__qualname__, None) is law and mod is not None and "." not in law.__qualname__:
        origin = getattr(mod, "__file__", None)
        if law.__module__.startswith("sc_rt_user_law_") and origin:  # loaded from a file
            return f"{PYTHON_PREFIX}{origin}:{law.__qualname__}"
        return f"{PYTHON_PREFIX}{law.__module__}:{law.__qualname__}"
    spec = f"{PYTHON_PREFIX}{law.__module__}:{law.__qualname__}@{id(law):x}"
    _CLASSES[spec] = law
    return spec


def register(law: str | type) -> str:
    """Put the Python law (a spec or a class) in the core's registry; returns
    its spec, the ``law`` of a ``ControllerConfig`` that runs it. Raises
    ValueError (one line) when the class does not load."""
    spec = law_spec(law)
    cls = law if isinstance(law, type) else load_law(spec)
    doc = (cls.__doc__ or "").strip().splitlines()
    _core.register_python_law(spec, law_label(cls), doc[0] if doc else "", _factory(cls), law_command(cls))
    return spec


def python_law(spec: Any) -> type | None:
    """The class a Python law's spec names, loaded (ValueError when it does
    not load); None for a spec that names no Python law (a built-in, a
    plugin, an external controller's name). What the modules below the plan
    ask instead of reading a spec's form themselves (issue 38)."""
    return load_law(spec) if is_python_law(spec) else None


def registry_spec(spec: str) -> str:
    """The law a ``ControllerConfig`` runs ``spec`` by: a Python law put in
    the core's registry first (:func:`register`, once per process), any
    other law as it is."""
    return register(spec) if is_python_law(spec) else spec


class _Params(dict):
    """A law's table as a dict that remembers which keys the law read (the
    core reports the others as unknown parameters)."""

    def __init__(self, items):
        super().__init__()
        for key, values in items:
            v = [float(x) for x in values]
            dict.__setitem__(self, key, v[0] if len(v) == 1 else np.array(v))
        self.read: set[str] = set()

    def __getitem__(self, key):
        self.read.add(key)
        return dict.__getitem__(self, key)

    def get(self, key, default=None):
        self.read.add(key)
        return dict.get(self, key, default)

    def __contains__(self, key):
        self.read.add(key)
        return dict.__contains__(self, key)

    def _all(self):
        self.read.update(dict.keys(self))

    def keys(self):
        self._all()
        return dict.keys(self)

    def items(self):
        self._all()
        return dict.items(self)

    def values(self):
        self._all()
        return dict.values(self)

    def __iter__(self):
        self._all()
        return dict.__iter__(self)


def _names(law: Any) -> list[str]:
    names = getattr(law, "telemetry_names", ())
    names = list(names() if callable(names) else names)
    n = _core.LAW_MAX_TELEMETRY
    if not all(isinstance(x, str) and x for x in names):
        raise ValueError(f"telemetry_names must be non-empty strings, got {names!r}")
    if len(set(names)) != len(names) or set(names) & set(TELEMETRY):
        raise ValueError(f"telemetry_names must be unique and not a fixed slot ({', '.join(TELEMETRY)}), "
                         f"got {names!r}")
    if len(names) > n:
        raise ValueError(f"declares {len(names)} telemetry names, at most {n}")
    return names


def _real(value: Any, what: str, shape: tuple[int]) -> np.ndarray:
    """``value`` as float64 if it is real numbers (integer or floating, not
    bool, complex or objects) of exactly ``shape`` (a one-wide slot: a
    scalar too); ValueError naming its shape and dtype otherwise (no
    reshaping: (2, 2) or (4, 1) is not a command of 4 wheels)."""
    try:
        a = np.asarray(value)
    except Exception as e:  # a ragged sequence, a failing __array__
        raise ValueError(f"{what} is not an array of numbers ({type(e).__name__}: {e})") from None
    if a.dtype.kind not in "iuf":
        raise ValueError(f"{what} of dtype {a.dtype}, expected real numbers (integer or floating)")
    if a.shape != shape and not (shape == (1,) and a.shape == ()):
        raise ValueError(f"{what} of shape {a.shape}, expected {shape}" + (" or a scalar" if shape == (1,) else ""))
    return a.astype(float).reshape(shape)


def _failure(e: BaseException) -> str:
    """A law's exception as its failure's message. ``sys.exit`` and
    KeyboardInterrupt raised by the law's own code are its failures too,
    contained and named like any other (the bench owns the process; a
    signal to the bench never surfaces in the law: it sets a stop flag,
    controller/pycontroller.py, isolate.py)."""
    if isinstance(e, SystemExit):
        return f"SystemExit({e.code!r}) raised by the law (sys.exit does not end the bench)"
    if isinstance(e, KeyboardInterrupt):
        return "KeyboardInterrupt raised by the law (not a signal: the bench's signals stop it by a flag)"
    return f"{type(e).__name__}: {e}"


class _Adapter:
    """The law as the trampoline calls it: the law's results checked and
    packed into one row (u_cmd, the fixed slots, the named values), its
    exceptions formatted ("Type: what")."""

    def __init__(self, law: Any, params: _Params):
        self.law = law
        self.names = _names(law)
        self.used = sorted(params.read)
        # a value by its declared name, or by the name without its unit ("tau_x" for "tau_x [N m]")
        self._index = {k: _NAMED + i for i, k in enumerate(self.names)}
        self._index.update({split_unit(k)[0]: _NAMED + i for i, k in enumerate(self.names)})
        self.after = self._after if callable(getattr(law, "after", None)) else None

    def reset(self, inp) -> None:
        try:
            self.law.reset(inp)
        except (Exception, SystemExit, KeyboardInterrupt) as e:
            raise RuntimeError(_failure(e)) from None

    def step(self, inp) -> np.ndarray:
        try:
            res = self.law.step(inp)
        except (Exception, SystemExit, KeyboardInterrupt) as e:
            raise RuntimeError(_failure(e)) from None
        beat(inp.t)  # the law's step returned: for a parent watching a contained run (sc_rt.isolate)
        u_cmd, tel = res if isinstance(res, tuple) and len(res) == 2 else (res, None)
        out = np.zeros(_core.PYTHON_LAW_OUT_SIZE)
        out[0:4] = _real(u_cmd, "u_cmd", (4,))
        if tel is None:
            return out
        if not isinstance(tel, dict):
            raise ValueError(f"telemetry of type {type(tel).__name__}, expected a dict")
        for k, v in tel.items():
            if k in TELEMETRY:
                o, w = TELEMETRY[k]
            elif k in self._index:
                o, w = self._index[k], 1
            else:
                raise ValueError(f"telemetry {k!r} is not declared (telemetry_names: {self.names})")
            out[o:o + w] = _real(v, f"telemetry {k!r}", (w,))
        return out

    def _after(self, u_cmd, u_sat) -> None:
        try:
            self.law.after(u_cmd, u_sat)
        except (Exception, SystemExit, KeyboardInterrupt) as e:
            raise RuntimeError(_failure(e)) from None


def _factory(cls: type):
    def make(model, rate: float, items) -> _Adapter:
        params = _Params(items)
        try:
            law = cls(LawSetup(model=model, control_rate_hz=float(rate), params=params))
        except LawParamError:
            raise
        except Exception as e:
            raise RuntimeError(f"{type(e).__name__}: {e}") from None
        return _Adapter(law, params)

    return make
