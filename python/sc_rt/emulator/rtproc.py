"""What the plant emulator's thread asks of the operating system for a
real-time run, and gives back afterwards (docs/HIL.md, "The emulator's loop").

- the garbage collector: the objects alive at the start are frozen
  (``gc.freeze``) and collection is off for the run (a generation-2 pass
  over the bench's objects takes milliseconds, at a random tick);
- timer slack 1 ns (``PR_SET_TIMERSLACK``; a SCHED_OTHER thread's default
  is 50 us, added to every timed ``select``);
- optionally one CPU (``sched_setaffinity``) and ``SCHED_FIFO`` + ``mlockall``
  (root or CAP_SYS_NICE / CAP_IPC_LOCK; refused: the run goes on without and
  says so).

Linux applies the scheduler and the affinity per thread: they are given to
every thread of the process (the emulator's, and the receive thread that
LCM's udpm provider runs inside ``lcm.LCM``, which reads the socket and
wakes the emulator through a pipe: left at SCHED_OTHER it delays every
command by a scheduler's wake-up), and given back afterwards. The timer
slack is the calling thread's.
"""

from __future__ import annotations

import ctypes
import gc
import os
import sys
from typing import Any

__all__ = ["RealtimeThread", "EMULATOR_FIFO_PRIORITY"]

#: the emulator's SCHED_FIFO priority: below the controller's 80 (the
#: controller answers within the period the emulator ticks)
EMULATOR_FIFO_PRIORITY = 70
_PR_SET_TIMERSLACK, _PR_GET_TIMERSLACK = 29, 30
_MCL_CURRENT, _MCL_FUTURE = 1, 2


def _threads() -> list[int]:
    try:
        return [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        return [0]


def _libc():
    if sys.platform != "linux":
        return None
    try:
        return ctypes.CDLL(None, use_errno=True)
    except OSError:
        return None


class RealtimeThread:
    """A context manager: the calling thread set up for a real-time loop
    (``freeze_gc``, timer slack, ``cpu``, ``fifo``); ``description`` says
    what it got ("SCHED_FIFO 70 + mlockall, CPU 0, gc frozen, slack 1 ns")."""

    def __init__(self, *, freeze_gc: bool = True, cpu: int | None = None, fifo: bool = False):
        self.freeze_gc, self.cpu, self.fifo = freeze_gc, cpu, fifo
        self.got: list[str] = []
        self.warnings: list[str] = []
        self._undo: list[Any] = []

    @property
    def description(self) -> str:
        return ", ".join(self.got) if self.got else "SCHED_OTHER"

    def __enter__(self) -> RealtimeThread:
        libc = _libc()
        if self.fifo:
            try:
                for tid in _threads():
                    old = (os.sched_getscheduler(tid), os.sched_getparam(tid))
                    os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(EMULATOR_FIFO_PRIORITY))
                    self._undo.append(lambda tid=tid, old=old: os.sched_setscheduler(tid, old[0], old[1]))
                self.got.append(f"SCHED_FIFO {EMULATOR_FIFO_PRIORITY}")
            except (OSError, AttributeError) as e:
                self.warnings.append(f"SCHED_FIFO not permitted ({e}): running SCHED_OTHER")
                self.got.append("SCHED_OTHER (SCHED_FIFO denied)")
            if libc is not None:
                if libc.mlockall(_MCL_CURRENT | _MCL_FUTURE) == 0:
                    self._undo.append(libc.munlockall)
                    self.got[-1] += " + mlockall"
                else:
                    self.warnings.append(f"mlockall not permitted ({os.strerror(ctypes.get_errno())})")
        else:
            self.got.append("SCHED_OTHER")
        if self.cpu is not None:
            try:
                for tid in _threads():
                    old_cpus = os.sched_getaffinity(tid)
                    os.sched_setaffinity(tid, {self.cpu})
                    self._undo.append(lambda tid=tid, old_cpus=old_cpus: os.sched_setaffinity(tid, old_cpus))
                self.got.append(f"CPU {self.cpu}")
            except (OSError, ValueError) as e:
                self.warnings.append(f"cannot pin to CPU {self.cpu} ({e})")
        if libc is not None:
            old_slack = libc.prctl(_PR_GET_TIMERSLACK, 0, 0, 0, 0)
            if old_slack >= 0 and libc.prctl(_PR_SET_TIMERSLACK, 1, 0, 0, 0) == 0:
                self._undo.append(lambda: libc.prctl(_PR_SET_TIMERSLACK, old_slack, 0, 0, 0))
                self.got.append("slack 1 ns")
        if self.freeze_gc:
            was_enabled = gc.isenabled()
            gc.collect()
            gc.freeze()  # what exists now is never scanned again
            gc.disable()

            def _gc_back():
                gc.unfreeze()
                if was_enabled:
                    gc.enable()

            self._undo.append(_gc_back)
            self.got.append("gc frozen")
        for w in self.warnings:
            print(f"sc-rt emulator: warning: {w}", file=sys.stderr)
        return self

    def __exit__(self, *exc: Any) -> None:
        for undo in reversed(self._undo):
            try:
                undo()
            except OSError:
                pass
        self._undo.clear()
