"""Where the runs execute: this process, a local process pool, or Dask.

Every backend maps ``fn(shared, batch)`` over batches of run ids and yields
each batch's result as it completes (any order). ``shared`` (the scenario and
the campaign's settings) travels once per worker, not once per batch. The
results do not depend on the backend: a run is a pure function of (shared,
run id).

- ``serial``: this process (one worker, no pool);
- ``pool``: ``concurrent.futures.ProcessPoolExecutor`` (the local default);
- ``dask``: a ``distributed`` cluster: a ``LocalCluster`` of ``workers``
  single-threaded processes, or a running scheduler (``address`` such as
  ``tcp://host:8786``, or a ``scheduler_file``).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import Any

__all__ = ["Backend", "SchedulerUnreachable", "make_backend"]

_SHARED: Any = None


class SchedulerUnreachable(RuntimeError):
    """No Dask scheduler answered at the given address (or file) in time."""


def _init(shared: Any) -> None:
    global _SHARED
    _SHARED = shared
    # a Ctrl-C at the terminal reaches the workers too: the parent decides
    # (it stops the campaign and keeps the batches done), the workers finish
    # the batch they have
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _call_with_shared(fn: Callable, batch: list[int]) -> Any:
    return fn(_SHARED, batch)


class Backend:
    name = "serial"

    def __init__(self, workers: int = 1):
        self.workers = workers

    def map(self, fn: Callable, shared: Any, batches: list[list[int]]) -> Iterator[Any]:
        for b in batches:
            yield fn(shared, b)

    def close(self) -> None:
        pass

    def describe(self) -> dict[str, Any]:
        return {"backend": self.name, "workers": self.workers}


class PoolBackend(Backend):
    name = "pool"

    def map(self, fn, shared, batches):
        with ProcessPoolExecutor(self.workers, initializer=_init, initargs=(shared,)) as ex:
            try:
                yield from self._map(ex, fn, batches)
            finally:  # stopped early (a signal): drop the queued batches, not wait for them
                ex.shutdown(wait=True, cancel_futures=True)

    def _map(self, ex, fn, batches):
        # keep a bounded number of batches queued (a 10^5-run campaign has thousands)
        pending, todo = set(), iter(batches)
        for b in todo:
            pending.add(ex.submit(_call_with_shared, fn, b))
            if len(pending) >= 4 * self.workers:
                break
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for f in done:
                nxt = next(todo, None)
                if nxt is not None:
                    pending.add(ex.submit(_call_with_shared, fn, nxt))
                yield f.result()


class DaskBackend(Backend):
    name = "dask"

    def __init__(self, workers: int | None = None, address: str | None = None,
                 scheduler_file: str | None = None, timeout_s: float = 3.0):
        from distributed import Client, LocalCluster

        self.cluster = None
        self.address = address or scheduler_file
        try:
            if address or scheduler_file:
                self.client = Client(address, scheduler_file=scheduler_file, timeout=f"{timeout_s}s")
            else:
                self.cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1,
                                            threads_per_worker=1, processes=True,
                                            dashboard_address=None, host="127.0.0.1")
                self.client = Client(self.cluster)
        except (OSError, TimeoutError, ValueError) as e:
            where = address or f"the scheduler file {scheduler_file}"
            raise SchedulerUnreachable(f"no Dask scheduler answered at {where} within "
                                       f"{timeout_s:g} s ({type(e).__name__}: {e})") from None
        n = sum(self.client.nthreads().values())
        super().__init__(n)

    def map(self, fn, shared, batches):
        from distributed import as_completed

        if not self.client.nthreads():
            self.client.wait_for_workers(1, timeout=60)
        remote = self.client.scatter(shared, broadcast=True, hash=False)
        futures = [self.client.submit(fn, remote, b, pure=False) for b in batches]
        try:
            for f in as_completed(futures):
                yield f.result()
                f.release()
        finally:
            self.client.cancel(futures)

    def close(self):
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()

    def describe(self):
        return {"backend": self.name, "workers": self.workers,
                "scheduler": self.address or "LocalCluster"}


def make_backend(kind: str, workers: int | None = None, address: str | None = None,
                 scheduler_file: str | None = None) -> Backend:
    """``kind``: "local" (serial with one worker, else a pool), "pool", "serial" or "dask"."""
    if address or scheduler_file or kind == "dask":
        return DaskBackend(workers, address, scheduler_file)
    workers = workers or os.cpu_count() or 1
    if kind == "serial" or (kind == "local" and workers == 1):
        return Backend(1)
    if kind in ("local", "pool"):
        return PoolBackend(workers)
    raise ValueError(f"backend must be 'local', 'pool', 'serial' or 'dask', got {kind!r}")
