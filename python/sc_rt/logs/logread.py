"""Reading an ``lcm-logger`` log for ``sc-rt report``: every event of our
channels decoded together from its raw bytes (numpy structured arrays over
the fixed big-endian layouts of the generated types), so a million events
take seconds. Channels that are not ours are skipped and counted; events on
our channels that are not exactly one message of the channel's type are
counted as undecodable, never fatal.
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import lcm
import numpy as np

from sc_rt.wire.lcmio import CHANNELS
from sc_rt.wire.startrec import end_record, start_record
from sc_rt.wire.codec import TYPES, decode_any, numpy_dtype
from sc_rt.wire.legacy import decode_current, upgrade

__all__ = ["LogData", "read_log"]


@dataclass
class LogData:
    path: Path
    events: int
    prefix: str
    decode_s: float
    records: dict[str, np.ndarray]  # base channel name -> structured array, log order
    stamps: dict[str, np.ndarray]  # base channel name -> logger receive time [us]
    messages: dict[str, list]  # variable-size types: base name -> [(stamp, msg)]
    channels: dict[str, dict[str, Any]]  # every channel: type, count, undecodable by kind
    skipped: dict[str, int] = field(default_factory=dict)
    #: the run's start record (sc-rt hil's SCRT_HIL_START, JSON: scenario,
    #: mode, trigger, rate, law identity, run id); None in a log written
    #: before it carried one (then a consumer has to guess, and says so)
    start: dict[str, Any] | None = None
    #: the run's end record (SCRT_HIL_END, JSON: why the bench stopped, how
    #: its controller ended); None in an older log or one cut before its end
    end: dict[str, Any] | None = None

    @property
    def undecodable(self) -> int:
        return sum(sum(c["undecodable_kinds"].values()) for c in self.channels.values())


def _reader(log: lcm.EventLog):
    c = getattr(log, "c_eventlog", None)
    if c is not None and hasattr(c, "read_next_event"):
        return c.read_next_event  # (eventnum, timestamp, channel, data) tuples, no Event object

    def nxt():
        e = log.read_next_event()
        return None if e is None else (e.eventnum, e.timestamp, e.channel, e.data)

    return nxt


def _detect_prefix(names) -> str:
    found = sorted({n[: -len("SCRT_STATE")] for n in names if n.endswith("SCRT_STATE")})
    if len(found) > 1:
        raise ValueError(f"the log holds several benches (channel prefixes {found}): pass --prefix")
    return found[0] if found else ""


def read_log(path: str | Path, prefix: str | None = None) -> LogData:
    """Read and decode every event of our channels."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such log")
    t0 = time.perf_counter()
    log = lcm.EventLog(str(path), "r")
    nxt = _reader(log)
    by_ch: dict[str, list] = {}
    events = bad_run = 0
    while True:
        try:
            ev = nxt()
        except (UnicodeDecodeError, ValueError, OSError):
            # an event the reader cannot even represent (a channel name that
            # is not UTF-8; the reader has moved past it): count it, go on
            by_ch.setdefault("<unreadable>", []).append((0, 0, "", b""))
            events += 1
            bad_run += 1
            if bad_run > 10000:  # a reader that no longer advances: stop, keep what was read
                break
            continue
        bad_run = 0
        if ev is None:
            break
        events += 1
        lst = by_ch.get(ev[2])
        if lst is None:
            lst = by_ch[ev[2]] = []
        lst.append(ev)
    log.close()
    prefix = _detect_prefix(by_ch) if prefix is None else prefix
    records, stamps, messages, channels = {}, {}, {}, {}
    for base, (tname, _who, _rate) in CHANNELS.items():
        ch = prefix + base
        lst = by_ch.pop(ch, [])
        cls = TYPES[tname]
        counts: Counter = Counter()
        if numpy_dtype(cls) is not None:
            rec, idx = decode_current(cls, [e[3] for e in lst], counts)  # an older layout too
            records[base] = rec
            stamps[base] = np.fromiter((e[1] for e in lst), np.int64, len(lst))[idx]
        else:
            msgs = []
            for e in lst:
                _c, m = decode_any(e[3], counts)
                m = upgrade(m)  # an older layout (a log written before it changed) as today's
                if m is not None and isinstance(m, cls):
                    msgs.append((e[1], m))
                elif m is not None:
                    counts["unknown_type"] += 1
            messages[base] = msgs
        channels[ch] = {"type": tname, "count": len(lst),
                        "undecodable": int(sum(counts.values())), "undecodable_kinds": dict(counts)}
    skipped = {ch: len(v) for ch, v in sorted(by_ch.items())}
    return LogData(path, events, prefix, time.perf_counter() - t0, records, stamps, messages,
                   channels, skipped, start_record(by_ch.get(prefix + "SCRT_HIL_START", [])),
                   end_record(by_ch.get(prefix + "SCRT_HIL_END", [])))

