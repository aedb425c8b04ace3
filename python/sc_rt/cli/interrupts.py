"""SIGINT and SIGTERM for the ``sc-rt`` commands.

``main`` turns both into ``Interrupted`` (exit code 128 + the signal: 130,
143, after a one-line message). A command that writes partial outputs
handles them itself while it runs: ``flag_signals`` records the signal and
lets the work stop at its next step (``sc-rt sim``'s python engine, the
bench's emulator through ``sc_rt.hil.procs.Stopper``), and ``sc-rt
montecarlo`` keeps the runs already in its dataset.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator

__all__ = ["Interrupted", "raise_on_signals", "flag_signals", "SIGNALS"]

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(Exception):
    """SIGINT or SIGTERM arrived; exit code 128 + ``signum``."""

    def __init__(self, signum: int):
        self.signum = signum
        super().__init__(f"interrupted by {signal.Signals(signum).name}")

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


def _raise(signum: int, _frame) -> None:
    raise Interrupted(signum)


def raise_on_signals() -> None:
    """SIGINT and SIGTERM raise ``Interrupted`` (main thread only)."""
    if threading.current_thread() is threading.main_thread():
        for s in SIGNALS:
            signal.signal(s, _raise)


@contextlib.contextmanager
def flag_signals(on_signal: Callable[[int], None]) -> Iterator[list[int]]:
    """While the block runs, SIGINT and SIGTERM call ``on_signal(signum)``
    (the first only) instead of raising; yields the list of signals seen."""
    seen: list[int] = []

    def handler(signum: int, _frame) -> None:
        if not seen:
            on_signal(signum)
        seen.append(signum)

    old = {}
    if threading.current_thread() is threading.main_thread():
        old = {s: signal.signal(s, handler) for s in SIGNALS}
    try:
        yield seen
    finally:
        for s, h in old.items():
            signal.signal(s, h)
