"""Decimation of the live topics: at most so many messages per second of
the messages' own clock, per LCM channel.

A periodic channel of a run (states, commands, statuses, truth, guidance,
sensors) carries its simulation time; a message is kept when at least one
period of the configured rate has passed, in that time, since the last kept
one (the first is kept; a time that goes back, a new run on the bus,
starts again). The messages' own clock, not the wall clock, so that a
10 Hz run is never decimated and a 1 kHz one keeps every 20th state at
50 Hz, lockstep or real time alike, evenly spaced in the plots. The derived
topics follow their source message. Channels of no period (configuration,
faults, controller info, foreign channels) are never decimated.

The time is read from the raw bytes (a fixed offset of the fixed-size type),
so a message that is dropped is never decoded.
"""

from __future__ import annotations

import math
import struct

from sc_rt.wire.codec import numpy_dtype

__all__ = ["DEFAULT_RATE_HZ", "PERIODIC", "RateLimiter", "MessageClock", "parse_rates"]

#: [Hz] default cap of every periodic channel
DEFAULT_RATE_HZ = 50.0
#: the channels (lcmio.CHANNELS names, without prefix) the cap applies to
PERIODIC = frozenset({"SCRT_STATE", "SCRT_CMD", "SCRT_TRUTH", "SCRT_CTRL_STATUS", "SCRT_GUIDANCE",
                      "SCRT_GYRO", "SCRT_STAR", "SCRT_TACH", "SCRT_MAG", "SCRT_ROD_CMD"})
#: relative tolerance on the period (times on a grid: 20 ms after 0.0 is 0.020000000000000004)
_TOL = 1e-9
#: the time field of a type, in order of preference
_TIME_FIELDS = ("t", "t_delivery")


class RateLimiter:
    """Keeps at most ``rate_hz`` messages per second of the messages' time.

    Parameters
    ----------
    rate_hz : float
        The cap [Hz]; 0 keeps every message.
    """

    def __init__(self, rate_hz: float):
        self.period = 1.0 / rate_hz if rate_hz > 0 else 0.0
        self.last: float | None = None

    def keep(self, t: float | None) -> bool:
        """Whether the message of time ``t`` [s] is kept (None, not finite: kept, the clock untouched)."""
        if self.period == 0.0 or t is None or not math.isfinite(t):
            return True
        last = self.last
        if last is None or t < last or t - last >= self.period * (1.0 - _TOL):
            self.last = t
            return True
        return False


class MessageClock:
    """The time [s] of a message of one type, read from its bytes.

    Parameters
    ----------
    cls : type
        The generated ``sc_rt_lcm`` class.
    """

    def __init__(self, cls: type):
        dt = numpy_dtype(cls)
        self.offset: int | None = None
        self.size = dt.itemsize if dt is not None else -1
        self.fingerprint = cls._get_packed_fingerprint()
        names = dt.names if dt is not None else ()
        for f in _TIME_FIELDS:
            if f in names and dt[f].str == ">f8":
                self.offset = dt.fields[f][1]
                break

    def __call__(self, data: bytes) -> float | None:
        """The message's time, None when the type has none or ``data`` is not one message of it."""
        if self.offset is None or len(data) != self.size or data[:8] != self.fingerprint:
            return None
        return struct.unpack_from(">d", data, self.offset)[0]


def parse_rates(items: list[str] | None) -> dict[str, float]:
    """``CHANNEL=HZ`` items (``--rate``) as {channel: Hz}; ValueError names a bad item."""
    out: dict[str, float] = {}
    for item in items or ():
        name, eq, value = item.partition("=")
        try:
            hz = float(value)
        except ValueError:
            hz = -1.0
        if not eq or not name.strip() or not (math.isfinite(hz) and hz >= 0):
            raise ValueError(f"--rate {item}: must be CHANNEL=HZ with HZ >= 0 (0: every message)")
        out[name.strip()] = hz
    return out
