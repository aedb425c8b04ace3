"""The plant emulator's record of its rows (a part of ``emulator.process.Emulator``).

Every row's run fields, the command and the status of its state as received
(the inbox's columns, emulator/inbox.py) and the loop's time stamps live in
two chunks of rows (results/record/store.py ``RowRing``), allocated and touched
before the run. When the run reaches the end of the newer chunk, the older
one goes to ``record.raw.arrow`` in the record's directory, so nothing
grows with the run (docs/HIL.md, "Long runs"), written by a thread of its
own (``ChunkWriter``): the loop hands the chunk over and takes a third,
spare chunk in its place, so no compression or disk write happens inside a
tick (a spill cost the real-time tick 2-22 ms before). After the run, ``close``
reads the record back a chunk at a time, decodes the statuses and writes
``trajectory.arrow``; a run that fits in the two chunks never touches the
disk while it runs and is returned in memory (``write_run`` then writes it
as the same ``trajectory.arrow``: docs/RECORD.md).
"""

from __future__ import annotations

import json
import queue
import threading
from pathlib import Path
from typing import Any, Callable

import numpy as np

from sc_rt.emulator.inbox import INBOX_COLUMNS, Inbox, fill_from_inbox
from sc_rt.emulator.loopstats import LoopBreakdown
from sc_rt.results.record.fields import COLUMNS
from sc_rt.results.record.run import FIELDS, Run, RunMeta
from sc_rt.results.record.store import CHUNK_ROWS, ChunkFile, ChunkReader, RowRing, load_arrow, remove_with, scratch_dir

__all__ = ["Record", "ChunkWriter", "RECORD_COLUMNS", "BYTES_PER_ROW"]

#: the loop's monotonic stamps per row (``stamps``): [tick or answer, integrated,
#: state published, truth started, truth done]
_STAMPS = 5
#: what the emulator records per row besides the run's fields: the inbox
#: (emulator/inbox.py) and the loop's stamps (cli/validate.py's estimate)
BYTES_PER_ROW = Inbox.BYTES_PER_ROW + _STAMPS * 8
#: the record's columns: the run's fields, the inbox's, the stamps
RECORD_COLUMNS = (*COLUMNS, *INBOX_COLUMNS,
                  ("stamps", (_STAMPS,), "i8", 0))


class ChunkWriter:
    """Chunks of rows written to ``file`` by a thread of its own, started
    before the run (it inherits the scheduler and memory locking of the
    thread that makes it, not the run's real-time priority).

    ``hand(cols, n)`` queues a chunk (waiting only when the writer is a whole
    chunk behind: the bound on memory) and returns a spare chunk at the fill
    values to fill next; the writer writes a chunk, resets it and makes it
    the next spare. A write that fails (a full disk) is kept and raised by
    the next ``hand`` or by ``close``."""

    def __init__(self, file: ChunkFile, columns: tuple, spare: dict[str, np.ndarray],
                 warm: Callable[[], None] | None = None):
        self.file, self.columns = file, columns
        self._todo: queue.Queue = queue.Queue(maxsize=1)
        self._free: queue.Queue = queue.Queue()
        self._free.put(spare)
        self.error: BaseException | None = None
        #: times the loop had to wait for the writer (it fell a chunk behind)
        self.waits = 0
        self._warm = warm
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sc-rt record writer", daemon=True)
        self._thread.start()
        self._ready.wait()  # warmed in its own thread: its allocator's buffers exist before the run

    def _run(self) -> None:
        try:
            if self._warm is not None:
                self._warm()
        finally:
            self._ready.set()
        while (item := self._todo.get()) is not None:
            cols, n = item
            try:
                if self.error is None:
                    self.file.write(cols, n)
            except BaseException as e:  # noqa: BLE001 (kept, raised in the loop's thread)
                self.error = e
            for name, _s, _d, fill in self.columns:
                cols[name][...] = fill
            self._free.put(cols)

    def hand(self, cols: dict[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
        if self.error is not None:
            raise self.error
        if self._free.empty():
            self.waits += 1
        self._todo.put((cols, n))
        return self._free.get()

    def close(self) -> None:
        """Wait for every chunk handed over to be written; raise a write's error."""
        self._todo.put(None)
        self._thread.join()
        if self.error is not None:
            raise self.error


class Record:
    """The record of a run of ``n_rows`` rows (module docstring).

    Parameters
    ----------
    n_rows : int
        The run's rows.
    chunk : int or None
        Rows per chunk (None: results/record/store.py ``CHUNK_ROWS``; a short run's
        chunks are no longer than half the run).
    directory : path or None
        Where the raw record and trajectory.arrow go (None: a temporary
        directory that lasts as long as the run read from it).
    """

    def __init__(self, n_rows: int, chunk: int | None, directory: Any = None):
        self.chunk = min(int(chunk or CHUNK_ROWS), max(1, (n_rows + 1) // 2))
        self.ring = RowRing(RECORD_COLUMNS, self.chunk, self._spill)
        self.directory = directory
        self._raw: ChunkFile | None = None
        self._writer: ChunkWriter | None = None
        self._waits_in_run: int | None = None  # the writer's waits at the run's end (close)
        self._tmpdir: Path | None = None
        if n_rows > 2 * self.chunk:  # the rows will go to disk, on the writer's thread
            load_arrow()
            self._open()
            spare = {n: np.full((self.chunk, *sh), f, d) for n, sh, d, f in RECORD_COLUMNS}
            self._writer = ChunkWriter(self._raw, RECORD_COLUMNS, spare, warm=self._prepare)

    def _prepare(self) -> None:
        """The writer warmed before the run, in the writer's thread (each
        thread has its allocator's own buffers), not in the middle of it:
        two chunks of data that does not compress (as a run's does not)
        written to a file dropped at once, so that the allocator's buffers
        for a batch exist from here on and the run's memory is flat from its
        first row, even under mlockall (measured: +25 MB at the first batch
        of a real-time run without this; +6 MB over a 2-minute soak when
        the warm-up ran in another thread than the writes)."""
        rng = np.random.default_rng(0)
        noise = {n: (rng.random((self.chunk, *shape)) * 100).astype(dtype) for n, shape, dtype, _ in RECORD_COLUMNS}
        warm = ChunkFile(self._raw.path.with_name(".warm.arrow"), RECORD_COLUMNS)  # as the record's own file
        for _ in range(2):
            warm.write(noise, self.chunk)
        warm.close().unlink()

    def _open(self) -> None:
        d = self.directory
        if d is None:
            d = self._tmpdir = scratch_dir()
        self._raw = ChunkFile(Path(d) / "record.raw.arrow", RECORD_COLUMNS)

    def _spill(self, cols: dict[str, np.ndarray], base: int, n: int) -> dict[str, np.ndarray] | None:
        """A chunk leaves the live rows: to the raw file, by the writer's
        thread (it returns the spare chunk to fill next); without a writer
        (a run that was to fit in memory), here."""
        if self._writer is not None:
            return self._writer.hand(cols, n)
        if self._raw is None:
            self._open()
        self._raw.write(cols, n)
        return None

    @property
    def writer_waits(self) -> int:
        """Times the loop waited for the record's writer (0: it never fell behind)."""
        if self._writer is None:
            return 0
        return self._writer.waits if self._waits_in_run is None else self._waits_in_run

    def close(self, rows: int, meta: RunMeta, mode: str) -> tuple[Run, dict[str, Any]]:
        """The run of the first ``rows`` rows and where the loop's
        microseconds went (emulator/loopstats.py): held in memory when the
        rows fit in the two live chunks; else the last rows go to the raw
        file too, and the rows are read back a chunk at a time, the statuses
        decoded, and written as trajectory.arrow, which the run reads."""
        loop = LoopBreakdown(mode)
        if self._raw is None:  # the whole run is live, from row 0
            cols = {n: np.concatenate([b[n] for b, _ in self.ring.iter_live()])[:rows] for n, *_ in RECORD_COLUMNS}
            run = Run(meta, {f.name: cols[f.name] for f in FIELDS}, rows=rows)
            fill_from_inbox(run, cols)
            loop.add(cols["stamps"], cols["cmd_utime"], cols["pub_wall_us"], cols["cmd_rx"], cols["pub_ns"])
            return run, loop.result()
        if self._writer is not None:
            self._waits_in_run = self._writer.waits  # (the hand-over at the end below is not a tick's)
        self.ring.finish(rows)
        if self._writer is not None:
            self._writer.close()
        raw_path = self._raw.close()
        out = raw_path.with_name("trajectory.arrow")
        w = ChunkFile(out, COLUMNS,
                      {"sc-rt:meta": json.dumps(meta.to_json())})
        src = ChunkReader(raw_path)
        for i in range(src.n_batches):
            cols = src.batch(i)
            chunk = Run(meta, {f.name: cols[f.name] for f in FIELDS})
            fill_from_inbox(chunk, cols)
            loop.add(cols["stamps"], cols["cmd_utime"], cols["pub_wall_us"], cols["cmd_rx"], cols["pub_ns"])
            w.write(chunk.trajectory, len(chunk))
        src.close()
        w.close()
        raw_path.unlink()
        run = Run.stored(meta, out)
        if self._tmpdir is not None:
            remove_with(run, self._tmpdir)  # a temporary directory lasts as long as the run
        return run, loop.result()
