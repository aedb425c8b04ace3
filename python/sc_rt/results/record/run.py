"""One run of the bench as a declared record: ``Run``.

Every producer (the python, cpp and unsampled engines, the LCM emulator, the
rebuild of an ``lcm-logger`` log) returns a ``Run``, and every consumer
(metrics, the bound check, figures, timing reports, studies) takes one. The
per-row arrays are declared once, in ``FIELDS`` (results/record/fields.py): name,
shape of one row, unit, where the value comes from, and what it means. A producer fills the
fields it has; the others keep their fill value (NaN, or the integer fill
of the field), so every run has every field and readers never guess.

A row is one control instant t_k = k / rate.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from sc_rt.pylaw import split_unit
from sc_rt.results.record.fields import COLUMNS, CORE_FIELDS, FIELD, FIELDS, Field, empty_arrays
from sc_rt.results.record.jsonsafe import json_safe, write_json
from sc_rt.results.record.meta import RunMeta
from sc_rt.results.record.provenance import provenance  # re-exported: its callers import it with Run

__all__ = ["Field", "FIELDS", "FIELD", "CORE_FIELDS", "RunMeta", "Run", "empty_arrays", "json_safe", "write_json",
           "provenance"]


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
            raise KeyError(f"not fields of a run: {sorted(unknown)} (declared in sc_rt.results.record.run.FIELDS)")
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
        #: the rows on disk (results/record/store.py), or None: in ``_a``
        self._store: Any = None

    # --- construction ---------------------------------------------------
    @classmethod
    def allocate(cls, n: int, meta: RunMeta) -> Run:
        """n rows at their fill values, to be filled row by row."""
        return cls(meta, {}, rows=n)

    @classmethod
    def stored(cls, meta: RunMeta, path: Path, **kw: Any) -> Run:
        """A run whose rows are on disk (``trajectory.arrow``, results/record/store.py),
        read a batch at a time (``chunks``); ``kw`` as the constructor's. A
        field the file lacks (a record written before the field was declared)
        reads as its fill value."""
        from sc_rt.results.record.store import ChunkReader

        r = cls(meta, {"t": np.zeros(0)}, **kw)
        r._a = {}
        r._store = ChunkReader(path, COLUMNS)
        if "t" in r._store.filled:
            raise ValueError(f"{path}: not a run's rows (no column t)")
        return r

    @property
    def is_stored(self) -> bool:
        """The rows are on disk (``path``), not in memory."""
        return self._store is not None

    @property
    def path(self) -> Path | None:
        """The file of a stored run's rows (None: in memory)."""
        return None if self._store is None else self._store.path

    def in_memory(self) -> Run:
        """The run with its rows in memory: itself when they are, else a copy
        that reads every column now (its size grows with the run)."""
        if self._store is None:
            return self
        r = Run.__new__(Run)
        r.__dict__.update(self.__dict__)
        r._a = self.trajectory
        r._store = None
        return r

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
            yield Run(self.meta, self._store.batch(i, FIELD), diverged=self.diverged, partial=self.partial)

    def map_chunks(self, fn: Any) -> None:
        """Call ``fn(chunk)`` on every chunk in order, keeping what it writes
        into the chunk's arrays (a run on disk is rewritten, a batch at a time)."""
        if self._store is None:
            fn(self)
            return

        def keep_all(c: Run, _row0: int) -> Run:
            fn(c)
            return c

        self._rewrite(keep_all)

    def _rewrite(self, fn: Any) -> None:
        """A run on disk: its file replaced by ``fn(chunk, first row)`` of each
        chunk in order (an in-memory run of the rows to keep), a batch at a time."""
        from sc_rt.results.record.store import ChunkFile, ChunkReader

        src = self._store
        tmp = src.path.with_name(src.path.name + ".new")
        w = ChunkFile(tmp, COLUMNS, {k: v for k, v in src.metadata.items() if k != "sc-rt:shapes"})
        row0 = 0
        for c in self.chunks():
            out = fn(c, row0)
            w.write(out._a, len(out))
            row0 += len(c)
        w.close()
        src.close()
        tmp.replace(src.path)
        self._store = ChunkReader(src.path, COLUMNS)

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

        def every_nth(c: Run, row0: int) -> Run:
            k = row0 + np.arange(len(c))
            keep = (k % every == 0) | (k == n - 1)
            return Run(self.meta, {f.name: c[f.name][keep] for f in FIELDS})

        self._rewrite(every_nth)
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
            from sc_rt.results.record.store import ChunkReader

            d["_store"] = ChunkReader(Path(d["_store"]), COLUMNS)
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

    def named_telemetry(self, name: str) -> np.ndarray:
        """The column of the law's named telemetry value ``name`` (as the law
        declared it, ``"tau_x [N m]"``, or without its unit, ``"tau_x"``):
        ``self["telemetry"][:, i]`` with i its place in
        ``meta.telemetry_names``. KeyError naming the declared ones."""
        names = list(self.meta.telemetry_names)
        bare = [split_unit(n)[0] for n in names]
        i = names.index(name) if name in names else bare.index(name) if name in bare else None
        if i is None:
            raise KeyError(f"{name!r}: the law's telemetry names are {names}")
        return self["telemetry"][:, i]

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
    def save_arrow(self, path: Path) -> Path:
        """trajectory.arrow, the run's one on-disk format whatever produced it
        (results/record/store.py; docs/RECORD.md):
        one column per field of ``FIELDS``, batches of ``CHUNK_ROWS`` rows,
        and the meta as JSON in the schema's metadata (``sc-rt:meta``). A run
        on disk moves its file there (it is the same format)."""
        from sc_rt.results.record.store import CHUNK_ROWS, ChunkFile, ChunkReader

        path = Path(path)
        if self._store is not None:
            if self._store.path.resolve() != path.resolve():
                import shutil

                self._store.close()
                shutil.move(self._store.path, path)  # (a temporary directory may be another file system)
                self._store = ChunkReader(path, COLUMNS)
            return path
        from sc_rt.results.record.jsonsafe import atomic_path

        with atomic_path(path) as part:  # whole or not at all: a full disk leaves no truncated record
            w = ChunkFile(part, COLUMNS, {"sc-rt:meta": json.dumps(self.meta.to_json())})
            try:
                n = len(self)
                for k in range(0, n, CHUNK_ROWS):  # batches of a run as it ran, for readers a batch at a time
                    w.write({name: v[k:k + CHUNK_ROWS] for name, v in self._a.items()}, min(CHUNK_ROWS, n - k))
                w.close()
            except BaseException:
                w.discard()
                raise
        return path

    @classmethod
    def load(cls, run_dir: Path) -> Run:
        """The run in ``run_dir``: its trajectory.arrow, read a batch at a time
        (``chunks``; ``in_memory`` reads it whole), or the trajectory.npz of a run written before every
        run was written as trajectory.arrow (``load_npz``); metrics.json and
        timing.json read when present."""
        run_dir = Path(run_dir)
        arrow = run_dir / "trajectory.arrow"
        if not arrow.exists() and (run_dir / "trajectory.npz").exists():
            return cls.load_npz(run_dir / "trajectory.npz")
        from sc_rt.results.record.store import ChunkReader

        r = ChunkReader(arrow)
        meta = RunMeta.from_json(json.loads(r.metadata["sc-rt:meta"]))
        r.close()
        run = cls.stored(meta, arrow)
        _read_json_beside(run, run_dir)
        return run

    @classmethod
    def load_npz(cls, path: Path) -> Run:
        """A run in the format sc-rt wrote short runs in before trajectory.arrow
        (trajectory.npz: every field by name and ``meta_json``), in memory;
        metrics.json / timing.json next to it read when present. Nothing
        writes it any more."""
        path = Path(path)
        with np.load(path, allow_pickle=False) as z:
            meta = RunMeta.from_json(json.loads(str(z["meta_json"])))
            arrays = {k: z[k] for k in z.files if k in FIELD}
        run = cls(meta, arrays)
        _read_json_beside(run, path.parent)
        return run


def _read_json_beside(run: Run, run_dir: Path) -> None:
    """The run's metrics.json and timing.json in ``run_dir``, when there."""
    for name, attr in (("metrics.json", "metrics"), ("timing.json", "timing")):
        p = run_dir / name
        if p.exists():
            setattr(run, attr, json.loads(p.read_text()))

