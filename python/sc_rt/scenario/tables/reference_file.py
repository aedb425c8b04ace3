"""Reading a ``[guidance]`` reference file (``kind = "file"``,
docs/SCENARIOS.md): the samples (t, sigma_DN, omega_DN_D) of a CSV or NPZ
file, every problem named with its line or row, cached by the file's
resolved path, modification time and size. The table's reader,
sc_rt.scenario.tables.guidance, turns them into a ``FileGuidance``."""

from __future__ import annotations

import csv
import errno
import functools
import io
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt import _core
from sc_rt.scenario.files import MAX_FILE_BYTES, FileProblem, read_bounded
from sc_rt.scenario.schema import read_only

__all__ = ["MAX_SAMPLES", "MRP_TOL", "UNIT_TOL", "read_reference_file"]

#: Quaternions in a reference file must be unit to this tolerance (then normalised).
UNIT_TOL = 1e-6
#: MRPs in a reference file may exceed norm 1 by this much (then mapped to the short set).
MRP_TOL = 1e-6
#: Most rows of a reference file (= the C++ core's limit, what controller_config_t carries).
MAX_SAMPLES = int(_core.GUIDANCE_TABLE_MAX)
_MAX_ISSUES = 10  # problems of a reference file reported before "... and N more"

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
