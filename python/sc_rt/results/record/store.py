"""A run's rows on disk, in chunks: an Arrow IPC file of record batches,
the one format every run's rows are written in (trajectory.arrow, docs/RECORD.md).

A long run at a high rate (an hour at 1 kHz is 3.6 M rows, ~3 GB of
per-row arrays) cannot be held in memory: its rows go to disk as they are
produced, a batch of ``CHUNK_ROWS`` rows at a time, and every reader takes
them back a batch at a time. The format is Arrow's IPC file format (the
"Feather v2" file): columnar, read by pyarrow, pandas, polars and DuckDB
without sc-rt, random access by batch, no compression to undo on the hot
path. One column per field; a field with a row shape (a 3-vector, a 4-vector)
is a fixed-size list of its flattened row. The schema's metadata carries
every field's row shape and dtype (``sc-rt:shapes``) and whatever the writer
adds (the run's meta as JSON: ``sc-rt:meta``).

- ``ChunkFile``: the writer, one batch per ``write``.
- ``ChunkReader``: the reader; ``batch(i, names)`` and ``column(name)``.
- ``RowRing``: two live chunks of rows that a producer fills by row index
  while older chunks go to a ``ChunkFile`` (the plant emulator's record:
  emulator/process.py).

Memory: a writer or a reader holds one batch (plus, for ``RowRing``, two
live chunks), whatever the run's length; ``column`` returns one whole
column (rows x its row shape), the one call whose size grows with the run.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

import numpy as np

__all__ = ["CHUNK_ROWS", "Column", "ChunkFile", "ChunkReader", "RowRing", "scratch_dir", "remove_with", "hand_over",
           "load_arrow"]

#: Rows per batch: ~3.5 MB of a run's fields (867 B/row), a few seconds at 1 kHz.
CHUNK_ROWS = 4096

#: (name, row shape, numpy dtype, fill value) of one column
Column = tuple[str, tuple[int, ...], str, Any]


def scratch_dir() -> Path:
    """A new temporary directory for a run's rows (``remove_with`` ties it to the run)."""
    import tempfile

    return Path(tempfile.mkdtemp(prefix="sc-rt-record-"))


#: id(owner) -> (its finalizer, the directory it removes): what ``hand_over`` detaches
_SCRATCH: dict[int, tuple[Any, Path]] = {}


def _remove(key: int, path: str) -> None:
    import shutil

    _SCRATCH.pop(key, None)
    shutil.rmtree(path, True)


def remove_with(owner: Any, path: Path) -> None:
    """Remove directory ``path`` when ``owner`` (the run reading from it) is gone."""
    import weakref

    _SCRATCH[id(owner)] = (weakref.finalize(owner, _remove, id(owner), str(path)), Path(path))


def hand_over(owner: Any) -> Path | None:
    """The directory ``remove_with`` tied to ``owner``, no longer removed with
    it here: a run made in a child process and sent to its parent, which
    ties the directory to its copy (``remove_with``); None: no such directory."""
    entry = _SCRATCH.pop(id(owner), None)
    if entry is None:
        return None
    entry[0].detach()
    return entry[1]


def load_arrow() -> None:
    """Load the file writer now (a run that will write its rows loads it
    before its loop, not in the middle of it)."""
    _pa()


def _pa():
    """pyarrow, imported on first use (short runs never touch it), with
    Arrow's allocations from the system's malloc: its default, mimalloc,
    maps a 1 GiB arena that the emulator's mlockall (real-time runs,
    emulator/rtproc.py) makes resident at once (measured: +1.04 GB on the
    first batch written, against +20 MB with malloc). The choice is Arrow's
    environment variable, read when pyarrow is first imported."""
    os.environ.setdefault("ARROW_DEFAULT_MEMORY_POOL", "system")
    import pyarrow as pa

    return pa


def _to_arrow(a: np.ndarray):
    pa = _pa()
    if a.ndim == 1:
        return pa.array(a)
    width = int(np.prod(a.shape[1:]))
    return pa.FixedSizeListArray.from_arrays(pa.array(np.ascontiguousarray(a).reshape(-1)), width)


def _from_arrow(col, shape: tuple[int, ...], dtype: str) -> np.ndarray:
    """A column of a batch as a numpy array of its own (writable: a chunk's
    derived fields are filled in place)."""
    if not shape:
        return np.array(col.to_numpy(zero_copy_only=False), dtype=dtype)
    flat = col.flatten().to_numpy(zero_copy_only=False)
    return np.array(flat, dtype=dtype).reshape(-1, *shape)


class ChunkFile:
    """Append batches of rows to an Arrow IPC file (module docstring).

    Parameters
    ----------
    path : Path or None
        The file, created (replaced when it exists); None: nowhere (the
        bytes are counted and dropped).
    columns : iterable of Column
        The columns, in order: name, row shape, dtype, fill.
    metadata : dict of str to str, optional
        More schema metadata (e.g. ``{"sc-rt:meta": json}``).
    """

    def __init__(self, path: Path | None, columns: Iterable[Column], metadata: dict[str, str] | None = None):
        pa = _pa()
        self.path = Path(path) if path is not None else None
        self.columns = tuple(columns)
        self.rows = 0
        fields = []
        for name, shape, dtype, _fill in self.columns:
            t = pa.from_numpy_dtype(np.dtype(dtype))
            if shape:
                t = pa.list_(t, int(np.prod(shape)))
            fields.append(pa.field(name, t, nullable=False))
        shapes = {name: [list(shape), dtype] for name, shape, dtype, _ in self.columns}
        meta = {"sc-rt:shapes": json.dumps(shapes), **(metadata or {})}
        self.schema = pa.schema(fields, metadata=meta)
        # (no path: the bytes are counted and dropped, a writer warmed up before a run)
        self._sink = pa.OSFile(str(self.path), "wb") if path is not None else pa.MockOutputStream()
        # LZ4 frames: the fields a producer leaves at their fill value cost next to nothing.
        # Compressed in the calling thread: Arrow's pool would start threads mid-run, whose
        # stacks a real-time emulator's mlockall makes resident (+2-3 MB at the first batch)
        opts = pa.ipc.IpcWriteOptions(compression="lz4", use_threads=False)
        self._w = pa.ipc.new_file(self._sink, self.schema, options=opts)

    def write(self, cols: dict[str, np.ndarray], rows: int) -> None:
        """The first ``rows`` rows of ``cols`` (every column by name) as one batch."""
        if rows <= 0:
            return
        pa = _pa()
        arrays = [_to_arrow(cols[name][:rows]) for name, *_ in self.columns]
        self._w.write_batch(pa.RecordBatch.from_arrays(arrays, schema=self.schema))
        self.rows += rows

    def discard(self) -> None:
        """Stop writing without a footer (the file is to be removed: a write
        failed); errors closing it are ignored."""
        w, self._w = self._w, None
        for c in (w, self._sink):
            try:
                if c is not None:
                    c.close()
            except (OSError, ValueError, RuntimeError):  # (pyarrow's ArrowIOError is an OSError)
                pass

    def close(self) -> Path | None:
        """Write the file's footer; returns its path."""
        if self._w is not None:
            self._w.close()
            self._sink.close()
            self._w = None
        return self.path


class ChunkReader:
    """A ``ChunkFile`` read back a batch at a time (module docstring).

    Parameters
    ----------
    path : Path
        The file.
    defaults : iterable of Column, optional
        Columns to give at their fill value when the file has none of that
        name (a record written before the field existed).
    """

    def __init__(self, path: Path, defaults: Iterable[Column] = ()):
        pa = _pa()
        self.path = Path(path)
        self._src = pa.OSFile(str(self.path), "rb")
        self._r = pa.ipc.open_file(self._src)
        md = self._r.schema.metadata or {}
        self.metadata = {k.decode(): v.decode() for k, v in md.items()}
        self.shapes = {k: (tuple(s), d) for k, (s, d) in json.loads(self.metadata["sc-rt:shapes"]).items()}
        #: name -> (row shape, dtype, fill) of the columns the file lacks, given at their fill value
        self.filled = {n: (tuple(s), d, f) for n, s, d, f in defaults if n not in self.shapes}
        self.n_batches = self._r.num_record_batches
        self.rows = int(self._r.count_rows())  # from the batches' headers, not their data
        #: readers of some columns only (``_reader``), by their indices in the file
        self._readers: dict[tuple[int, ...], Any] = {}

    @property
    def names(self) -> tuple[str, ...]:
        """The file's columns, then those given at their fill value (``defaults``)."""
        return (*self.shapes, *self.filled)

    def _reader(self, names: tuple[str, ...]):
        """A reader of the file that decompresses only the columns ``names``
        (Arrow's ``included_fields``): one column of a batch costs that
        column, not the whole batch (measured: 40x faster for one of ~40)."""
        idx = tuple(sorted({self._r.schema.get_field_index(n) for n in names if n in self.shapes}))
        if len(idx) == len(self.shapes):
            return self._r
        if idx not in self._readers:
            pa = _pa()
            opts = pa.ipc.IpcReadOptions(included_fields=list(idx), use_threads=False)
            self._readers[idx] = pa.ipc.open_file(self._src, options=opts)
        return self._readers[idx]

    def batch(self, i: int, names: Iterable[str] | None = None) -> dict[str, np.ndarray]:
        """Batch ``i``'s columns (all, or ``names``) as numpy arrays."""
        names = self.names if names is None else tuple(names)
        b = self._reader(names).get_batch(i)
        out = {}
        for n in names:
            if n in self.shapes:
                out[n] = _from_arrow(b.column(n), *self.shapes[n])
            else:
                shape, dtype, fill = self.filled[n]
                out[n] = np.full((b.num_rows, *shape), fill, dtype)
        return out

    def column(self, name: str) -> np.ndarray:
        """The whole column (rows x its row shape): its size grows with the run."""
        shape, dtype = self.shapes[name] if name in self.shapes else self.filled[name][:2]
        out = np.empty((self.rows, *shape), dtype)
        k = 0
        for i in range(self.n_batches):
            v = self.batch(i, (name,))[name]
            out[k:k + len(v)] = v
            k += len(v)
        return out

    def close(self) -> None:
        self._src.close()


class RowRing:
    """Rows filled by index, two chunks of ``chunk`` rows live at a time.

    A producer asks ``slot(k)`` for row k's chunk and offset and writes the
    columns there. Rows [base, base + 2 chunk) are live; ``reach(k)`` makes
    row k live, handing the older chunk to ``on_full`` (its columns and its
    first row) first, then resetting it to the fill values as the newer
    chunk. A row below ``base`` is gone (written), one at or past
    ``base + 2 chunk`` not yet live: ``slot`` returns None for both.
    ``finish(rows)`` hands over what is left, up to row ``rows``.
    """

    def __init__(self, columns: Iterable[Column], chunk: int,
                 on_full: Callable[[dict[str, np.ndarray], int, int], dict[str, np.ndarray] | None]):
        self.columns = tuple(columns)
        self.chunk = int(chunk)
        self.on_full = on_full
        # np.full writes every element: the pages are resident from the start
        self._bufs = [{n: np.full((self.chunk, *s), f, d) for n, s, d, f in self.columns} for _ in range(2)]
        self.base = 0  # first row of the older chunk, _bufs[0]

    def slot(self, k: int) -> tuple[dict[str, np.ndarray], int] | None:
        j = k - self.base
        if 0 <= j < self.chunk:
            return self._bufs[0], j
        if self.chunk <= j < 2 * self.chunk:
            return self._bufs[1], j - self.chunk
        return None

    def reach(self, k: int) -> None:
        """Make row k live (rows only move forward). ``on_full`` may return
        the chunk to use as the newer one, already at the fill values (a
        writer that keeps the older chunk to write it later); None: the older
        chunk is reset and reused here."""
        while k >= self.base + 2 * self.chunk:
            old = self._bufs[0]
            new = self.on_full(old, self.base, self.chunk)
            if new is None:
                for n, _s, _d, f in self.columns:
                    old[n][...] = f
                new = old
            self._bufs = [self._bufs[1], new]
            self.base += self.chunk

    def finish(self, rows: int) -> None:
        """Hand over the live rows below ``rows``."""
        for i, buf in enumerate(self._bufs):
            start = self.base + i * self.chunk
            n = min(self.chunk, rows - start)
            if n > 0:
                self.on_full(buf, start, n)

    def iter_live(self) -> Iterator[tuple[dict[str, np.ndarray], int]]:
        for i, buf in enumerate(self._bufs):
            yield buf, self.base + i * self.chunk
