"""A lockstep bench never outruns its logger (docs/HIL.md, "A complete log").

sc-rt-logger, started by ``sc-rt hil`` with ``--ack-channel``, publishes a
``log_ack_t`` on SCRT_LOG_ACK after every 8 plant states it has written to
the log. Before the emulator publishes a state, ``LogPace.before_state``
makes sure fewer than ``window`` of its states are still unwritten, handling
the bus (the acknowledgements, and the controller's messages, which go on
being recorded) until they are; a logger that writes none of them for
``timeout_s`` stops the run, invalid and named. So the messages in flight
to the logger are bounded by the window, whatever the machine's load, and
its socket buffer cannot overflow: a complete log by construction, not by
the scheduler's grace. Real time does not wait (its clock is the wall's):
the log's completeness is checked after the run as before."""

from __future__ import annotations

import time
from collections import Counter
from typing import Any, Callable

import sc_rt_lcm

from sc_rt.wire.auth import unauthenticated
from sc_rt.wire.lcmio import channel

__all__ = ["LogPace", "LOG_WINDOW", "LOG_WAIT_S"]

#: states the logger may be behind; with ~7 messages of ~250 B a row, ~56 kB
#: in flight: inside the kernel's default socket buffer (208 kB)
LOG_WINDOW = 32
#: [s] a logger that writes none of the unwritten states for this long stops the run
LOG_WAIT_S = 10.0


class LogPace:
    """The emulator's side of the logger's acknowledgements (module docstring)."""

    def __init__(self, bus: Any, prefix: str, counters: Counter, window: int = LOG_WINDOW,
                 timeout_s: float = LOG_WAIT_S):
        self.window, self.timeout_s = int(window), float(timeout_s)
        self.counters = counters
        self.sent = 0  # states published
        self.logged = 0  # states the logger says it has written
        self._lc = bus
        unauthenticated(bus).subscribe(channel("SCRT_LOG_ACK", prefix), self._on_ack)

    def _on_ack(self, _ch: str, data: bytes) -> None:
        try:
            m = sc_rt_lcm.log_ack_t.decode(data)
        except (ValueError, IndexError):
            self.counters["log_ack_malformed"] += 1
            return
        self.logged = max(self.logged, int(m.counted))

    def before_state(self, should_stop: Callable[[], bool]) -> str | None:
        """Wait until a state may be published (fewer than ``window`` unwritten);
        the reason to stop the run when the logger stalled, else None."""
        if self.sent - self.logged < self.window:
            return None
        self.counters["log_waits"] += 1
        t0 = time.monotonic()
        last, last_t = self.logged, t0
        while self.sent - self.logged >= self.window:
            if should_stop():
                return None
            now = time.monotonic()
            if self.logged != last:
                last, last_t = self.logged, now
            elif now - last_t > self.timeout_s:
                return (f"sc-rt-logger wrote none of the last {self.sent - self.logged} states for "
                        f"{self.timeout_s:g} s (it has written {self.logged} of {self.sent}): the log would "
                        "lose them; the run stops here")
            self._lc.handle_timeout(10)
        self.counters["log_wait_us"] += int((time.monotonic() - t0) * 1e6)
        return None
