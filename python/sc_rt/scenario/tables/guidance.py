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
- ``"file"``: samples read from a CSV or NPZ file, validated here and sent
  to the controller as arrays (:class:`FileGuidance`).
"""

from __future__ import annotations

import csv
import errno
import functools
import io
import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from sc_rt import _core
from sc_rt.scenario.files import MAX_FILE_BYTES, FileProblem, read_bounded
from sc_rt.scenario.schema import read_fields, read_only, spec, Spec, Table, vector_spec

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
    "read_reference_file",
]

#: Quaternions in a reference file must be unit to this tolerance (then normalised).
UNIT_TOL = 1e-6
#: MRPs in a reference file may exceed norm 1 by this much (then mapped to the short set).
MRP_TOL = 1e-6
#: Most rows of a reference file (= the C++ core's limit, what controller_config_t carries).
MAX_SAMPLES = int(_core.GUIDANCE_TABLE_MAX)
_MAX_ISSUES = 10  # problems of a reference file reported before "... and N more"


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
    arrays of controller_config_t (at most :data:`MAX_SAMPLES`)."""

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


# --------------------------------------------------------------------------- #
# Reference files.

_QUAT = ("q_w", "q_x", "q_y", "q_z")
_MRP = ("sigma_x", "sigma_y", "sigma_z")
_RATE = ("omega_x", "omega_y", "omega_z")


def read_reference_file(path: str | Path) -> tuple[tuple[np.ndarray, ...] | None, list[str]]:
    """((t, sigma, omega) read-only arrays, []) or (None, problems).

    CSV: a header row naming the columns ``t``, ``q_w, q_x, q_y, q_z`` (unit
    quaternion of D relative to N, scalar first) or ``sigma_x, sigma_y,
    sigma_z`` (MRP), and ``omega_x, omega_y, omega_z``; ``#`` lines and blank
    lines are skipped; a problem names the file's line. NPZ: arrays ``t``
    (n,), ``q`` (n, 4) [w, x, y, z] or ``sigma`` (n, 3), and ``omega`` (n, 3);
    a problem names the row index. Times finite and strictly increasing,
    every value finite, quaternions unit to 1e-6 (normalised; sign with
    q_w >= 0), MRPs of norm <= 1 (+1e-6), 2 .. MAX_SAMPLES rows.
    """
    path = Path(path)
    try:
        st = path.stat()
    except OSError as e:
        return None, [f"cannot read the reference file: {e.strerror}"
                      + (" (a symlink loop)" if e.errno == errno.ELOOP else "")]
    return _read_cached(str(path.resolve()), st.st_mtime_ns, st.st_size)


@functools.lru_cache(maxsize=8)
def _read_cached(path: str, mtime_ns: int, size: int) -> tuple[Any, list[str]]:
    del mtime_ns, size  # the cache key: a changed file is read again
    p = Path(path)
    if p.suffix.lower() == ".npz":
        cols, where, problems = _npz_columns(p)
    elif p.suffix.lower() == ".csv":
        cols, where, problems = _csv_columns(p)
    else:
        return None, [f"a reference file must be .csv or .npz, got {p.suffix or 'no suffix'!r}"]
    if problems:
        return None, problems
    return _validate(cols, where)


def _csv_columns(p: Path) -> tuple[dict[str, np.ndarray], list[str], list[str]]:
    """The columns by name, each row's place ("line N") and the problems."""
    try:
        text = read_bounded(p).decode("utf-8")
    except (FileProblem, UnicodeDecodeError) as e:
        return {}, [], [f"cannot read the reference file: {e}"]
    header, rows, where, problems = None, [], [], []
    for n, fields_ in enumerate(csv.reader(text.splitlines()), 1):
        if not fields_ or not "".join(fields_).strip() or fields_[0].lstrip().startswith("#"):
            continue
        fields_ = [f.strip() for f in fields_]
        if header is None:
            header = fields_
            if problem := _column_problem(header, "column"):
                return {}, [], [f"line {n}: {problem}"]
            continue
        if len(fields_) != len(header):
            problems.append(f"line {n}: {len(fields_)} values for {len(header)} columns")
        else:
            try:
                rows.append([float(f) for f in fields_])
                where.append(f"line {n}")
            except ValueError:
                bad = next(f for f in fields_ if not _is_float(f))
                problems.append(f"line {n}: {bad!r} is not a number")
        if len(problems) >= _MAX_ISSUES:
            break
    if header is None:
        return {}, [], ["no header row (t, q_w, q_x, q_y, q_z or sigma_x, sigma_y, sigma_z, "
                        "omega_x, omega_y, omega_z)"]
    a = np.array(rows, float).reshape(len(rows), len(header))
    return {name: a[:, i] for i, name in enumerate(header)}, where, problems


def _is_float(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _npz_columns(p: Path) -> tuple[dict[str, np.ndarray], list[str], list[str]]:
    try:
        raw = read_bounded(p)
    except FileProblem as e:
        return {}, [], [f"cannot read the reference file: {e}"]
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as z:
            unpacked = sum(i.file_size for i in z.zip.infolist())
            if unpacked > MAX_FILE_BYTES:  # a small archive of large arrays: not unpacked
                return {}, [], [f"its arrays unpack to {unpacked} bytes, more than the limit of "
                                f"{MAX_FILE_BYTES} bytes"]
            arrays = {k: np.asarray(z[k]) for k in z.files}
    except Exception as e:  # noqa: BLE001  (zip, format and pickle errors alike)
        return {}, [], [f"cannot read the reference file as NPZ: {e}"]
    names = {"t": ("t",), "q": _QUAT, "sigma": _MRP, "omega": _RATE}
    if unknown := sorted(set(arrays) - set(names)):
        return {}, [], [f"unknown array {unknown[0]!r} (arrays: t, q or sigma, omega)"]
    if "q" in arrays and "sigma" in arrays:
        return {}, [], ["give the attitude once: array q (quaternions) or sigma (MRPs)"]
    if missing := [k for k in ("t", "q" if "q" in arrays else "sigma", "omega") if k not in arrays]:
        return {}, [], [f"missing arrays: {', '.join(missing)}"]
    n = arrays["t"].shape[0] if arrays["t"].ndim == 1 else -1
    cols: dict[str, np.ndarray] = {}
    for k, a in arrays.items():
        width = len(names[k])
        ok = a.dtype.kind in "iuf" and a.shape == ((n,) if k == "t" else (n, width))
        if not ok:
            want = "(n,)" if k == "t" else f"(n, {width}) with n = len(t)"
            return {}, [], [f"array {k!r} must be numbers of shape {want}, got {a.dtype} {a.shape}"]
        for i, name in enumerate(names[k]):
            cols[name] = (a if k == "t" else a[:, i]).astype(float)
    return cols, [f"row {i}" for i in range(n)], []


def _column_problem(names: list[str], what: str) -> str:
    known = {"t", *_QUAT, *_MRP, *_RATE}
    if unknown := [n for n in names if n not in known]:
        return (f"unknown {what} {unknown[0]!r} (columns: t, q_w, q_x, q_y, q_z or "
                "sigma_x, sigma_y, sigma_z, omega_x, omega_y, omega_z)")
    if dup := [n for n in set(names) if names.count(n) > 1]:
        return f"{what} {dup[0]!r} given twice"
    has_q, has_s = any(n in names for n in _QUAT), any(n in names for n in _MRP)
    if has_q and has_s:
        return "give the attitude once: quaternion (q_w, q_x, q_y, q_z) or MRP (sigma_x, ...)"
    need = ["t", *(_QUAT if has_q else _MRP), *_RATE]
    if missing := [n for n in need if n not in names]:
        return f"missing {what}s: {', '.join(missing)}"
    return ""


def _validate(cols: dict[str, np.ndarray], where: list[str]) -> tuple[Any, list[str]]:
    t = cols["t"]
    n = t.size
    problems: list[str] = []
    if not 2 <= n <= MAX_SAMPLES:
        return None, [f"{n} samples: a reference file needs 2 .. {MAX_SAMPLES}"]
    for name, c in cols.items():
        for k in np.flatnonzero(~np.isfinite(c))[:_MAX_ISSUES]:
            problems.append(f"{where[k]}: {name} = {c[k]} must be finite")
    if problems:
        return None, _cap(problems)
    for k in np.flatnonzero(np.diff(t) <= 0)[:_MAX_ISSUES] + 1:
        problems.append(f"{where[k]}: t = {t[k]:g} must be greater than the previous time "
                        f"{t[k - 1]:g} ({where[k - 1]}): times must be strictly increasing")
    if "q_w" in cols:
        q = np.stack([cols[c] for c in _QUAT], axis=1)
        norm = np.linalg.norm(q, axis=1)
        for k in np.flatnonzero(np.abs(norm - 1.0) > UNIT_TOL)[:_MAX_ISSUES]:
            problems.append(f"{where[k]}: the quaternion {_list(q[k])} has norm {norm[k]:.9g}: "
                            f"must be unit (to {UNIT_TOL:g})")
        q = q / norm[:, None]
        q = np.where(q[:, :1] < 0, -q, q)  # q_w >= 0: the short-set MRP
        sigma = q[:, 1:] / (1.0 + q[:, :1])
    else:
        sigma = np.stack([cols[c] for c in _MRP], axis=1)
        norm = np.linalg.norm(sigma, axis=1)
        for k in np.flatnonzero(norm > 1.0 + MRP_TOL)[:_MAX_ISSUES]:
            problems.append(f"{where[k]}: the MRP {_list(sigma[k])} has norm {norm[k]:.6g}: "
                            "must be <= 1 (MRP, not degrees?)")
        big = norm > 1.0
        sigma[big] = -sigma[big] / (norm[big] ** 2)[:, None]
    if problems:
        return None, _cap(problems)
    omega = np.stack([cols[c] for c in _RATE], axis=1)
    return (read_only(t), read_only(sigma), read_only(omega)), []


def _cap(problems: list[str]) -> list[str]:
    if len(problems) <= _MAX_ISSUES:
        return problems
    return problems[:_MAX_ISSUES] + [f"... and {len(problems) - _MAX_ISSUES} more"]


def _list(v: np.ndarray) -> str:
    return "[" + ", ".join(f"{x:.9g}" for x in v) + "]"


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
