"""The ``[guidance]`` table of a scenario: the desired trajectory
(docs/SCENARIOS.md, docs/MODEL.md section 3).

``kind`` selects one of four references, each mirrored by C++
``sc_rt::GuidanceParams`` and carried to the controller in
``controller_config_t``:

- ``"paper"`` (the default, no ``kind`` key): the paper's
  ``omega_d(t) = bias + cos cos(freq t) + sin sin(freq t)``, ``sigma_d``
  integrated from ``sigma_d0`` (:class:`GuidanceParams`);
- ``"hold"``: a constant attitude (:class:`HoldGuidance`);
- ``"slew"``: rest to rest about the eigenaxis, cycloidal angle profile
  (:class:`SlewGuidance`);
- ``"file"``: samples read from a CSV or NPZ file, validated by
  sc_rt.scenario.tables.reference_file and sent to the controller as arrays
  (:class:`FileGuidance`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from sc_rt import _core
from sc_rt.scenario.schema import read_fields, read_only, spec, Spec, Table, vector_spec
from sc_rt.scenario.tables.reference_file import read_reference_file

__all__ = [
    "KINDS",
    "FileGuidance",
    "Guidance",
    "GuidanceParams",
    "HoldGuidance",
    "SlewGuidance",
    "coverage_problem",
    "guidance_phases",
    "read_guidance",
]


@dataclass(frozen=True)
class GuidanceParams:
    """The paper's reference (mirror of C++ sc_rt::GuidanceParams, kind Paper):
    omega_DN_D(t) = omega_bias + omega_cos cos(omega_freq t) + omega_sin sin(omega_freq t),
    sigma_DN integrated from sigma_d0 by the controller.
    """

    kind: ClassVar[str] = "paper"
    sigma_d0: np.ndarray = field(metadata=vector_spec(3, mrp=True))  # [-] sigma_DN at t = 0
    omega_bias: np.ndarray = field(metadata=vector_spec(3))  # [rad/s]
    omega_cos: np.ndarray = field(metadata=vector_spec(3))  # [rad/s]
    omega_sin: np.ndarray = field(metadata=vector_spec(3))  # [rad/s]
    omega_freq: float = field(metadata=spec("number", ge=0))  # [rad/s]

    def data(self) -> dict[str, Any]:
        """The table as TOML data (no ``kind``: the files of the paper have none)."""
        return {f.name: _plain(getattr(self, f.name)) for f in fields(self)}

    def fill_config(self, m: Any) -> None:
        """Its fields of controller_config_t."""
        m.guidance_kind = m.GUIDANCE_PAPER
        m.sigma_d0 = self.sigma_d0.tolist()
        m.omega_d_bias = self.omega_bias.tolist()
        m.omega_d_cos = self.omega_cos.tolist()
        m.omega_d_sin = self.omega_sin.tolist()
        m.omega_d_freq = float(self.omega_freq)


@dataclass(frozen=True)
class HoldGuidance:
    """Inertial hold: sigma_DN = sigma_d0 for all t, omega_DN_D = 0."""

    kind: ClassVar[str] = "hold"
    sigma_d0: np.ndarray = field(metadata=vector_spec(3, mrp=True))  # [-] the held attitude

    def data(self) -> dict[str, Any]:
        return {"kind": self.kind, "sigma_d0": self.sigma_d0.tolist()}

    def fill_config(self, m: Any) -> None:
        m.guidance_kind = m.GUIDANCE_HOLD
        m.sigma_d0 = self.sigma_d0.tolist()


@dataclass(frozen=True)
class SlewGuidance:
    """Rest-to-rest slew from sigma_d0 to target about the eigenaxis of the
    short rotation between them (angle Phi in [0, pi]), from ``start`` over
    ``duration`` T, with the cycloidal angle profile
    theta(s) = Phi (s - sin(2 pi s) / (2 pi)), s = (t - start) / T
    (rate and acceleration zero at both ends; see :attr:`max_rate`,
    :attr:`max_accel`)."""

    kind: ClassVar[str] = "slew"
    sigma_d0: np.ndarray = field(metadata=vector_spec(3, mrp=True))  # [-] before the slew
    target: np.ndarray = field(metadata=vector_spec(3, mrp=True))  # [-] after the slew
    duration: float = field(metadata=spec("number", gt=0))  # [s]
    start: float = field(default=0.0, metadata=spec("number", ge=0))  # [s]

    @property
    def angle(self) -> float:
        """[rad] Phi = 4 atan |target (-) sigma_d0|, in [0, pi]."""
        return 4.0 * math.atan(float(np.linalg.norm(_core.mrp_subtract(self.target, self.sigma_d0))))

    @property
    def max_rate(self) -> float:
        """[rad/s] 2 Phi / T, at mid-slew."""
        return 2.0 * self.angle / self.duration

    @property
    def max_accel(self) -> float:
        """[rad/s^2] 2 pi Phi / T^2, at a quarter and three quarters of the slew."""
        return 2.0 * math.pi * self.angle / self.duration**2

    def data(self) -> dict[str, Any]:
        return {"kind": self.kind, "sigma_d0": self.sigma_d0.tolist(),
                "target": self.target.tolist(), "start": float(self.start),
                "duration": float(self.duration)}  # fmt: skip

    def fill_config(self, m: Any) -> None:
        m.guidance_kind = m.GUIDANCE_SLEW
        m.sigma_d0 = self.sigma_d0.tolist()
        m.slew_target = self.target.tolist()
        m.slew_start = float(self.start)
        m.slew_duration = float(self.duration)


@dataclass(frozen=True)
class FileGuidance:
    """A reference read from ``file`` (CSV or NPZ): samples (t, sigma_DN,
    omega_DN_D); attitude by SLERP between samples, rate linear, omega_dot
    the slope of the linear rate. The samples reach the controller as
    arrays of controller_config_t (at most sc_rt.scenario.tables.reference_file.MAX_SAMPLES)."""

    kind: ClassVar[str] = "file"
    file: str  # as written in the scenario
    path: Path  # resolved (relative to the scenario file's folder)
    t: np.ndarray  # [s] (n,), strictly increasing
    sigma: np.ndarray  # [-] (n, 3) sigma_DN, short set
    omega: np.ndarray  # [rad/s] (n, 3) omega_DN_D
    sigma_d0: np.ndarray  # [-] sigma_DN(0), interpolated (computed, not a key)

    def data(self) -> dict[str, Any]:
        return {"kind": self.kind, "file": self.file}

    def fill_config(self, m: Any) -> None:
        m.guidance_kind = m.GUIDANCE_TABLE
        m.sigma_d0 = self.sigma_d0.tolist()  # information only: the table rules
        m.ref_n = int(self.t.size)
        m.ref_t = self.t.tolist()
        m.ref_sigma = self.sigma.tolist()
        m.ref_omega = self.omega.tolist()


Guidance = GuidanceParams | HoldGuidance | SlewGuidance | FileGuidance
_CLASSES: dict[str, type] = {c.kind: c for c in (GuidanceParams, HoldGuidance, SlewGuidance,
                                                 FileGuidance)}  # fmt: skip
KINDS = tuple(_CLASSES)
_KEYS: dict[str, tuple[str, ...]] = {
    "paper": tuple(f.name for f in fields(GuidanceParams)),
    "hold": tuple(f.name for f in fields(HoldGuidance)),
    "slew": tuple(f.name for f in fields(SlewGuidance)),
    "file": ("file",),
}


def _plain(v: Any) -> Any:
    return v.tolist() if isinstance(v, np.ndarray) else v


def coverage_problem(g: Guidance, duration: float) -> str:
    """Why the reference does not cover a run of ``duration`` s ("" if it does)."""
    if not isinstance(g, FileGuidance):
        return ""
    t0, t1 = float(g.t[0]), float(g.t[-1])
    if t0 <= 0.0 and t1 >= duration:
        return ""
    return (f"{g.file}: its times {t0:g} .. {t1:g} s must cover the run, 0 .. {duration:g} s "
            "(run.duration)")


def read_guidance(t: Table, duration: float | None, base: Path) -> Guidance | None:
    """The reference of the table ``t`` (None after reporting its problems).

    ``duration``: the run's, for the coverage of a file (None: not checked);
    ``base``: the folder a relative ``file`` is taken from.
    """
    kind = t.read("kind", Spec("str", choices=KINDS), default="paper")
    if t.data is None:
        return None
    if kind is None:
        t.used.update(t.data)  # the kind is reported; its keys cannot be judged
        return None
    for name in t.data:
        if name != "kind" and name not in _KEYS[kind]:
            owners = [k for k, keys in _KEYS.items() if name in keys]
            if owners:
                t.fail(name, f"{name} is a key of kind {' or '.join(map(repr, owners))}, not of "
                       f"kind {kind!r} (its keys: {', '.join(_KEYS[kind])})")  # fmt: skip
                t.used.add(name)
    if kind != "file":
        return read_fields(t, _CLASSES[kind])
    name = t.read("file", Spec("str"))
    t.finish()
    if name is None:
        return None
    path = Path(name) if Path(name).is_absolute() else base / name
    ref, problems = read_reference_file(path)
    for p in problems:
        t.fail("file", f"{name}: {p}")
    if ref is None:
        return None
    g = FileGuidance(file=name, path=path, t=ref[0], sigma=ref[1], omega=ref[2],
                     sigma_d0=read_only(_core.sigma_d(_table_params(*ref), 0.0)))  # fmt: skip
    if duration is not None and (problem := coverage_problem(g, duration)):
        t.fail("file", problem)
        return None
    return g


def _table_params(t: np.ndarray, sigma: np.ndarray, omega: np.ndarray) -> Any:
    p = _core.GuidanceParams()
    p.kind = _core.GuidanceKind.Table
    p.table_t, p.table_sigma, p.table_omega = t, sigma, omega
    return p


def guidance_phases(g: Any) -> dict[str, tuple[float, float | None]]:
    """The named phases of a guidance, name -> (start, end) [s] (end None:
    to the run's end), what a requirement's ``phase`` selects: a slew's
    "before" (from 0 to its start, when it starts later), "slew" and "hold"
    (after it); an inertial hold's "hold"; none for the paper's reference or
    a file's (they have no phases)."""
    if isinstance(g, SlewGuidance):
        out: dict[str, tuple[float, float | None]] = {}
        if g.start > 0:
            out["before"] = (0.0, float(g.start))
        out["slew"] = (float(g.start), float(g.start + g.duration))
        out["hold"] = (float(g.start + g.duration), None)
        return out
    if isinstance(g, HoldGuidance):
        return {"hold": (0.0, None)}
    return {}
