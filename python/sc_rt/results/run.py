"""One run of the bench as a declared record: ``Run``.

Every producer (the python, cpp and unsampled engines, the LCM emulator, the
rebuild of an ``lcm-logger`` log) returns a ``Run``, and every consumer
(metrics, the bound check, figures, timing reports, studies) takes one. The
per-row arrays are declared once, in ``FIELDS``: name, shape of one row,
unit, where the value comes from, and what it means. A producer fills the
fields it has; the others keep their fill value (NaN, or the integer fill
of the field), so every run has every field and readers never guess.

A row is one control instant t_k = k / rate.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from sc_rt.results.jsonsafe import json_safe, write_json
from sc_rt.results.meta import RunMeta

__all__ = ["Field", "FIELDS", "FIELD", "CORE_FIELDS", "RunMeta", "Run", "empty_arrays", "json_safe", "write_json",
           "provenance"]

SOURCES = ("plant", "controller", "truth", "timing", "derived", "estimator")


@dataclass(frozen=True)
class Field:
    """One per-row array of a run.

    ``FIELDS`` (public as ``sc_rt.FIELDS``) is the tuple of every one, in the
    order trajectory.npz lists them; ``FIELD`` maps name -> Field.

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


def _f(name, shape, unit, source, doc, core=False, dtype="f8", fill=math.nan) -> Field:
    return Field(name, shape, unit, source, doc, dtype, fill, core)


#: Every per-row array of a run, in the order trajectory.npz lists them.
FIELDS: tuple[Field, ...] = (
    _f("t", (), "s", "plant", "control instant t_k = k / rate", True),
    _f("sigma_BN", (3,), "-", "plant", "MRP attitude of the body B relative to N at t_k", True),
    _f("omega_BN_B", (3,), "rad/s", "plant", "body rate relative to N, body frame", True),
    _f("wheel_speed", (4,), "rad/s", "plant", "wheel speeds relative to the body", True),
    _f("sigma_DN", (3,), "-", "controller", "desired attitude (guidance) at t_k", True),
    _f("sigma_BD", (3,), "-", "controller", "attitude tracking error, MRP of B relative to D (8)", True),
    _f("omega_BD_B", (3,), "rad/s", "controller", "rate tracking error, body frame (8)", True),
    _f("u_cmd", (4,), "rad/s^2", "controller",
       "wheel acceleration command before saturation (what the law asked for)", True),
    _f("u_sat", (4,), "rad/s^2", "controller", "the command after the controller's saturation (15)", True),
    _f("wheel_accel", (4,), "rad/s^2", "truth", "actual wheel acceleration, faults applied (15)", True),
    _f("z1", (3,), "rad/s", "controller", "NESO estimate of the rate error state", True),
    _f("z2", (3,), "rad/s^2", "controller", "NESO estimate of the lumped disturbance", True),
    _f("delta2", (3,), "rad/s^2", "truth", "true lumped disturbance (20),(21)", True),
    _f("chi", (3,), "-", "controller", "prescribed envelope chi(t) the controller used (29)", True),
    _f("lam", (3,), "-", "controller", "normalised error lambda = sigma_BD / chi (30)", True),
    _f("bound_ok", (3,), "-", "derived",
       "-dmin chi(t) < sigma_BD < dmax chi(t) per axis, from the scenario's envelope", True, "?", False),
    _f("e1", (3,), "-", "controller", "transformed error of the PPC (34)"),
    _f("e2", (3,), "rad/s", "controller", "second DSC surface error (27)"),
    _f("vs", (4,), "rad/s^2", "controller", "anti-windup auxiliary state (42)"),
    _f("flags", (), "-", "controller", "controller flags bit set (safety, bound, invalid input)",
       dtype="i8", fill=0),
    _f("ctrl_mode", (), "-", "controller", "controller mode: 0 INIT, 1 NORMAL, 2 SAFE; -1 unknown",
       dtype="i8", fill=-1),
    _f("cmd_seq_applied", (), "-", "truth", "seq of the wheel_cmd_t the plant applied (-1: none)",
       dtype="i8", fill=-1),
    _f("cmd_stale", (), "-", "truth", "1 when the watchdog applied zero (no valid command)",
       dtype="i8", fill=0),
    _f("fault_Y", (4,), "-", "truth", "fault evolution Y_i(t) (16)"),
    _f("fault_effectiveness", (4,), "-", "truth", "wheel effectiveness L_i of the active fault"),
    _f("fault_bias", (4,), "rad/s^2", "truth", "wheel bias of the active fault"),
    _f("fault_stuck", (4,), "-", "truth", "1 when the wheel is stuck", dtype="i8", fill=0),
    # With [sensors] (sc_rt.sim.sensed; the MEKF of cpp/include/sc_rt/mekf.hpp), NaN otherwise:
    _f("sigma_BN_est", (3,), "-", "estimator",
       "MEKF attitude estimate at t_k (what the law gets with measurement = estimate)"),
    _f("bias_est", (3,), "rad/s", "estimator", "MEKF gyro bias estimate"),
    _f("bias_true", (3,), "rad/s", "truth", "the gyro's true bias (bias0 + Gauss-Markov + random walk)"),
    _f("P_diag", (6,), "rad^2, (rad/s)^2", "estimator",
       "MEKF covariance diagonal: attitude error (3, body) then bias error (3)"),
    _f("att_est_error", (3,), "rad", "truth",
       "estimation error: rotation vector of the true attitude relative to the estimate, body frame"),
    _f("innovation", (3,), "rad", "estimator",
       "star tracker residual of the last update since the previous row (NaN: none)"),
    _f("nis", (), "-", "estimator", "normalised innovation squared z' S^-1 z of that update (NaN: none)"),
    _f("sigma_BD_true", (3,), "-", "derived",
       "true tracking error mrp_subtract(sigma_BN, sigma_DN) (sensor runs: the bound is judged on it)"),
    _f("latency_us", (), "us", "timing", "state publish to receipt of the command answering it"),
    _f("tick_lateness_us", (), "us", "timing", "real time: the emulator's tick behind its deadline"),
    _f("wake_lateness_us", (), "us", "timing", "the controller's wake behind its schedule"),
    _f("compute_us", (), "us", "timing", "the controller's compute time for this state"),
    _f("state_age_us", (), "us", "timing", "age of the state when the controller used it"),
    _f("state_log_us", (), "us", "timing", "logger receive time of the state (log rebuilds)"),
)
FIELD: dict[str, Field] = {f.name: f for f in FIELDS}
#: The trajectory every producer fills (checked for finiteness by the metrics).
CORE_FIELDS: tuple[str, ...] = tuple(f.name for f in FIELDS if f.core)
assert all(f.source in SOURCES for f in FIELDS)


def empty_arrays(n: int) -> dict[str, np.ndarray]:
    """Every field of ``n`` rows at its fill value."""
    return {f.name: np.full((n, *f.shape), f.fill, dtype=f.dtype) for f in FIELDS}


class Run:
    """A run: per-row arrays (``FIELDS``), what it is (``meta``), its
    metrics, and what the bench counted while it ran.

    ``run["sigma_BD"]`` is the (rows, 3) array; ``run.t`` the times.

    Parameters
    ----------
    meta : RunMeta
        What the run is (scenario, law, engine, envelope, limits).
    arrays : dict of str to numpy.ndarray
        Per-row arrays by field name (``FIELDS``): rows first, then the
        field's row shape; cut to ``rows`` and cast to the field's dtype. A
        field not given holds its fill value (NaN, or the field's integer fill).
    rows : int, optional
        The number of rows. None: ``len(arrays["t"])``.
    metrics : dict, optional
        The run's metrics (metrics.json; ``finish_run`` fills them). None: empty.
    timing : dict, optional
        The timing report of a bench run (timing.json). None: none (offline).
    counters : dict of str to int, optional
        What the bench counted while it ran (commands received, timeouts,
        invalid or duplicate messages, ...). None: empty.
    gaps : list of (float, float), optional
        [s] (start, end) of the spans in which the plant had no valid command
        (the watchdog applied zero). None: none.
    faults_applied : list of dict, optional
        The fault commands (``sc-rt fault``) the emulator applied or rejected,
        in order. None: none.
    diverged : bool
        The plant state became non-finite and the run stopped there.
    message : str
        Why the run stopped early, in words ("" when it did not).
    partial : bool
        The run stopped before its end (a signal, a process gone).

    Attributes
    ----------
    meta, metrics, timing, counters, gaps, faults_applied, diverged, message, partial
        The parameters of the same names (``None`` become empty containers,
        except ``timing``).

    Raises
    ------
    KeyError
        ``arrays`` has a name that is not a field of ``FIELDS``.
    ValueError
        An array's shape is not ``rows`` by its field's row shape.
    """

    def __init__(self, meta: RunMeta, arrays: dict[str, np.ndarray], *, rows: int | None = None,
                 metrics: dict[str, Any] | None = None, timing: dict[str, Any] | None = None,
                 counters: dict[str, int] | None = None, gaps: list[tuple[float, float]] | None = None,
                 faults_applied: list[dict[str, Any]] | None = None, diverged: bool = False,
                 message: str = "", partial: bool = False):
        unknown = set(arrays) - set(FIELD)
        if unknown:
            raise KeyError(f"not fields of a run: {sorted(unknown)} (declared in sc_rt.results.run.FIELDS)")
        n = len(arrays["t"]) if rows is None else rows
        self._a: dict[str, np.ndarray] = {}
        for f in FIELDS:
            v = arrays.get(f.name)
            if v is None:
                v = np.full((n, *f.shape), f.fill, dtype=f.dtype)
            else:
                v = np.asarray(v)[:n]
                if v.shape != (n, *f.shape):
                    raise ValueError(f"run field {f.name}: shape {v.shape}, declared {(n, *f.shape)}")
                if v.dtype != np.dtype(f.dtype):
                    v = v.astype(f.dtype)
            self._a[f.name] = v
        self.meta = meta
        self.metrics: dict[str, Any] = metrics if metrics is not None else {}
        self.timing = timing
        self.counters: dict[str, int] = dict(counters or {})
        self.gaps: list[tuple[float, float]] = list(gaps or [])
        self.faults_applied: list[dict[str, Any]] = list(faults_applied or [])
        self.diverged = diverged
        self.message = message
        self.partial = partial
        #: the rows on disk (results/store.py), or None: in ``_a``
        self._store: Any = None

    # --- construction ---------------------------------------------------
    @classmethod
    def allocate(cls, n: int, meta: RunMeta) -> Run:
        """n rows at their fill values, to be filled row by row."""
        return cls(meta, {}, rows=n)

    @classmethod
    def stored(cls, meta: RunMeta, path: Path, **kw: Any) -> Run:
        """A run whose rows are on disk (``trajectory.arrow``, results/store.py),
        read a batch at a time (``chunks``); ``kw`` as the constructor's."""
        from sc_rt.results.store import ChunkReader

        r = cls(meta, {"t": np.zeros(0)}, **kw)
        r._a = {}
        r._store = ChunkReader(path)
        missing = set(FIELD) - set(r._store.names)
        if missing:
            raise ValueError(f"{path}: not a run's rows (no {sorted(missing)[:3]})")
        return r

    @property
    def is_stored(self) -> bool:
        """The rows are on disk (``path``), not in memory."""
        return self._store is not None

    @property
    def path(self) -> Path | None:
        """The file of a stored run's rows (None: in memory)."""
        return None if self._store is None else self._store.path

    def head(self, rows: int) -> Run:
        """The first ``rows`` rows (views), everything else shared."""
        if self._store is not None:
            raise ValueError("head() of a run on disk")
        r = Run.__new__(Run)
        r.__dict__.update(self.__dict__)
        r._a = {k: v[:rows] for k, v in self._a.items()}
        return r

    def chunks(self) -> Iterator[Run]:
        """The run as in-memory runs of consecutive rows, in order: itself
        (one chunk) when in memory, a batch at a time when on disk. A chunk
        shares ``meta`` and nothing else; writing into it changes this run
        only when the run is in memory (``map_chunks`` writes either)."""
        if self._store is None:
            yield self
            return
        for i in range(self._store.n_batches):
            yield Run(self.meta, self._store.batch(i), diverged=self.diverged, partial=self.partial)

    def map_chunks(self, fn: Any) -> None:
        """Call ``fn(chunk)`` on every chunk in order, keeping what it writes
        into the chunk's arrays (a run on disk is rewritten, a batch at a time)."""
        if self._store is None:
            fn(self)
            return
        from sc_rt.results.store import ChunkFile, ChunkReader

        src = self._store
        tmp = src.path.with_name(src.path.name + ".new")
        w = ChunkFile(tmp, [(f.name, f.shape, f.dtype, f.fill) for f in FIELDS],
                      {k: v for k, v in src.metadata.items() if k != "sc-rt:shapes"})
        for c in self.chunks():
            fn(c)
            w.write(c._a, len(c))
        w.close()
        src.close()
        tmp.replace(src.path)
        self._store = ChunkReader(src.path)

    def thinned(self, every: int) -> Run:
        """The run keeping every ``every``-th row (t_k with k a multiple of
        ``every``) and the last one, for saving (``[record] every``): a run
        on disk rewrites its file, a batch at a time."""
        if every <= 1 or len(self) == 0:
            return self
        n = len(self)
        if self._store is None:
            idx = np.unique(np.r_[np.arange(0, n, every), n - 1])
            r = self.head(n)
            r._a = {k: v[idx] for k, v in self._a.items()}
            return r
        from sc_rt.results.store import ChunkFile, ChunkReader

        src = self._store
        tmp = src.path.with_name(src.path.name + ".thin")
        w = ChunkFile(tmp, [(f.name, f.shape, f.dtype, f.fill) for f in FIELDS],
                      {k: v for k, v in src.metadata.items() if k != "sc-rt:shapes"})
        row0 = 0
        for c in self.chunks():
            k = row0 + np.arange(len(c))
            keep = (k % every == 0) | (k == n - 1)
            w.write({f.name: c[f.name][keep] for f in FIELDS}, int(keep.sum()))
            row0 += len(c)
        w.close()
        src.close()
        tmp.replace(src.path)
        self._store = ChunkReader(src.path)
        return self

    def decimated(self, max_rows: int) -> Run:
        """An in-memory copy of at most about ``max_rows`` rows for figures:
        the rows cut into buckets of consecutive rows, and of each bucket its
        first row and the rows of the largest pointing error (|sigma_BD|),
        state-to-command latency and compute time, so that peaks stay in
        the picture. A run of at most ``max_rows`` rows: itself."""
        n = len(self)
        if n <= max_rows:
            return self
        per = max(1, -(-n // max(1, max_rows // 4)))  # rows per bucket
        parts: dict[str, list[np.ndarray]] = {f.name: [] for f in FIELDS}
        row0 = 0
        for c in self.chunks():
            m = len(c)
            bucket = (row0 + np.arange(m)) // per
            starts = np.flatnonzero(np.r_[True, bucket[1:] != bucket[:-1]])
            keep = [starts]
            for key in (np.linalg.norm(c["sigma_BD"], axis=1), c["latency_us"], c["compute_us"]):
                v = np.where(np.isfinite(key), key, -np.inf)
                keep.append(np.array([s + int(np.argmax(v[s:e])) for s, e in zip(starts, np.r_[starts[1:], m])]))
            idx = np.unique(np.concatenate(keep))
            for f in FIELDS:
                parts[f.name].append(c[f.name][idx])
            row0 += m
        r = Run(self.meta, {k: np.concatenate(v) for k, v in parts.items()}, metrics=self.metrics,
                timing=self.timing, counters=self.counters, gaps=self.gaps, faults_applied=self.faults_applied,
                diverged=self.diverged, message=self.message, partial=self.partial)
        return r

    # --- pickling (a run crosses to its parent from a contained child) -----
    def __getstate__(self) -> dict[str, Any]:
        d = dict(self.__dict__)
        if d.get("_store") is not None:  # the file, by its path (its directory must outlive the child)
            d["_store"] = str(self._store.path)
        return d

    def __setstate__(self, d: dict[str, Any]) -> None:
        if isinstance(d.get("_store"), str):
            from sc_rt.results.store import ChunkReader

            d["_store"] = ChunkReader(Path(d["_store"]))
        self.__dict__.update(d)

    # --- access -----------------------------------------------------------
    def __getitem__(self, name: str) -> np.ndarray:
        """The field's array; on disk, a copy of the whole column read now
        (its size grows with the run: a long run reads ``chunks``)."""
        if self._store is not None:
            if name not in FIELD:
                raise KeyError(name)
            return self._store.column(name)
        return self._a[name]

    def __contains__(self, name: object) -> bool:
        return name in FIELD if self._store is not None else name in self._a

    def __iter__(self) -> Iterator[str]:
        return iter(FIELD) if self._store is not None else iter(self._a)

    def __len__(self) -> int:
        return self._store.rows if self._store is not None else len(self._a["t"])

    @property
    def t(self) -> np.ndarray:
        return self["t"]

    @property
    def trajectory(self) -> dict[str, np.ndarray]:
        """The per-row arrays by name (every field of ``FIELDS``; a run on
        disk reads them all now)."""
        if self._store is not None:
            return {f.name: self[f.name] for f in FIELDS}
        return self._a

    def present(self, name: str) -> np.ndarray:
        """Rows where the producer filled ``name`` (not its fill value)."""
        if self._store is not None:
            return np.concatenate([c.present(name) for c in self.chunks()]) if len(self) else np.zeros(0, bool)
        f, v = FIELD[name], self._a[name]
        flat = v.reshape(len(v), -1)
        if isinstance(f.fill, float) and math.isnan(f.fill):
            return ~np.all(np.isnan(flat), axis=1)
        return ~np.all(flat == f.fill, axis=1)

    # --- files ------------------------------------------------------------
    def save_npz(self, path: Path, *, compress: bool = True) -> Path:
        """trajectory.npz: every field by name, and the meta as JSON."""
        if self._store is not None:
            raise ValueError("a run on disk is saved as trajectory.arrow (save_arrow)")
        save = np.savez_compressed if compress else np.savez
        save(path, **self._a, meta_json=np.array(json.dumps(self.meta.to_json())))
        return path

    def save_arrow(self, path: Path) -> Path:
        """trajectory.arrow (results/store.py): every field, a batch at a
        time, and the meta as JSON in the schema's metadata. A run on disk
        moves its file there (it is the same format)."""
        from sc_rt.results.store import ChunkFile, ChunkReader

        path = Path(path)
        if self._store is not None:
            if self._store.path.resolve() != path.resolve():
                import shutil

                self._store.close()
                shutil.move(self._store.path, path)  # (a temporary directory may be another file system)
                self._store = ChunkReader(path)
            return path
        w = ChunkFile(path, [(f.name, f.shape, f.dtype, f.fill) for f in FIELDS],
                      {"sc-rt:meta": json.dumps(self.meta.to_json())})
        w.write(self._a, len(self))
        return w.close()

    @classmethod
    def load(cls, run_dir: Path) -> Run:
        """The run in ``run_dir``: trajectory.npz, or trajectory.arrow for a
        run written on disk as it ran (metrics.json and timing.json read
        when present)."""
        run_dir = Path(run_dir)
        npz, arrow = run_dir / "trajectory.npz", run_dir / "trajectory.arrow"
        if npz.exists() or not arrow.exists():
            return cls.load_npz(npz)
        from sc_rt.results.store import ChunkReader

        meta = RunMeta.from_json(json.loads(ChunkReader(arrow).metadata["sc-rt:meta"]))
        run = cls.stored(meta, arrow)
        for name, attr in (("metrics.json", "metrics"), ("timing.json", "timing")):
            p = run_dir / name
            if p.exists():
                setattr(run, attr, json.loads(p.read_text()))
        return run

    @classmethod
    def load_npz(cls, path: Path) -> Run:
        """A run written by ``save_npz`` (metrics.json / timing.json next to
        it are read when present)."""
        path = Path(path)
        with np.load(path, allow_pickle=False) as z:
            meta = RunMeta.from_json(json.loads(str(z["meta_json"])))
            arrays = {k: z[k] for k in z.files if k in FIELD}
        run = cls(meta, arrays)
        for name, attr in (("metrics.json", "metrics"), ("timing.json", "timing")):
            p = path.parent / name
            if p.exists():
                setattr(run, attr, json.loads(p.read_text()))
        return run


def provenance(plant_session: int | None, controller_session: int | None,
               invalid: str | None = None) -> dict[str, Any]:
    """The bench run's metrics keys saying where its numbers came from: the
    plant and controller sessions (LCM ids, None: none) and whether the run
    is valid (False, with the reason: another bench on the same channels
    mixed into it, emulator/collision.py)."""
    out: dict[str, Any] = {"valid": invalid is None, "plant_session": plant_session,
                           "controller_session": controller_session}
    if invalid is not None:
        out["invalid_reason"] = invalid
    return out
