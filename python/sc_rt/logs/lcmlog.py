"""A strict reader of ``lcm-logger`` files, byte for byte.

``lcm.EventLog`` silently resynchronises over damage and cannot return an
event whose channel name is not UTF-8; an exporter that must carry every
event needs to know where a log is damaged. The format (LCM's
``eventlog.c``): per event, big-endian

    uint32 sync 0xEDA1DA01, int64 event number, int64 timestamp [us],
    int32 channel length, int32 data length, channel bytes, data bytes

``read_events`` yields ``(number, timestamp_us, channel_bytes, data)`` in
file order. Damage raises ``LogDamaged`` (offset, what) unless
``partial``: then a torn last event is dropped and bytes between events
that are not an event are skipped up to the next sync word; both are
counted in ``LogScan``.
"""

from __future__ import annotations

import mmap
import struct
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["SYNC", "LogDamaged", "LogScan", "read_events", "MAX_CHANNEL"]

SYNC = 0xEDA1DA01
_SYNC_BYTES = struct.pack(">I", SYNC)
_HEADER = struct.Struct(">IqqII")
#: longest channel name accepted (LCM's own reader refuses longer ones too)
MAX_CHANNEL = 1000


class LogDamaged(ValueError):
    """The file is not an intact LCM log."""

    def __init__(self, path, offset: int, what: str, recoverable: bool = True):
        self.offset = offset
        self.recoverable = recoverable  # whether reading with partial=True gets past it
        super().__init__(f"{path}: {what} at byte {offset}")


@dataclass
class LogScan:
    """What was read (filled while iterating)."""

    size: int = 0
    events: int = 0
    skipped_bytes: int = 0  # bytes between events that were no event (partial)
    damaged_at: list[int] = field(default_factory=list)  # offsets of damage (at most 100)
    torn_tail_bytes: int = 0  # a last event cut short (partial)

    def note(self, offset: int) -> None:
        if len(self.damaged_at) < 100:
            self.damaged_at.append(offset)


def read_events(path: str | Path, scan: LogScan | None = None, partial: bool = False):
    """Iterate over the events of ``path`` (see the module's docstring)."""
    path = Path(path)
    scan = LogScan() if scan is None else scan
    with open(path, "rb") as f:
        size = f.seek(0, 2)
        scan.size = size
        if size == 0:
            raise LogDamaged(path, 0, "empty file, not an LCM log", recoverable=False)
        with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as mm:
            if mm[:4] != _SYNC_BYTES:
                raise LogDamaged(path, 0, "no LCM event header (sync word 0xEDA1DA01): not an LCM log",
                                 recoverable=False)
            yield from _events(mm, size, path, scan, partial)


#: Bytes of the log read between two releases of the pages behind (a log of
#: any length is read in this much resident memory)
_RELEASE_BYTES = 16 << 20


def _events(mm, size: int, path: Path, scan: LogScan, partial: bool):
    unpack = _HEADER.unpack_from
    hsize = _HEADER.size
    pos = 0
    released = 0  # the pages below this offset are given back (every event yielded is a copy)
    drop = getattr(mmap, "MADV_DONTNEED", None)
    while pos < size:
        if drop is not None and pos - released > _RELEASE_BYTES:
            cut = pos - pos % mmap.PAGESIZE
            mm.madvise(drop, released, cut - released)
            released = cut
        if size - pos < hsize:
            what = f"truncated log: a torn event header ({size - pos} of {hsize} bytes)"
            if not partial:
                raise LogDamaged(path, pos, what)
            scan.torn_tail_bytes += size - pos
            scan.note(pos)
            return
        sync, num, ts, clen, dlen = unpack(mm, pos)
        end = pos + hsize + clen + dlen
        if sync != SYNC or clen > MAX_CHANNEL:
            what = ("corrupt log: no event header (sync word)" if sync != SYNC
                    else f"corrupt log: channel name of {clen} bytes")
            if not partial:
                raise LogDamaged(path, pos, what)
            scan.note(pos)
            nxt = mm.find(_SYNC_BYTES, pos + 1)
            nxt = size if nxt < 0 else nxt
            scan.skipped_bytes += nxt - pos
            pos = nxt
            continue
        if end > size:
            # a header that runs past the end: a torn last event, unless another
            # event starts inside it (then the header itself is damage)
            nxt = mm.find(_SYNC_BYTES, pos + 1)
            what = (f"truncated log: the last event is cut short ({size - pos} of {end - pos} bytes)"
                    if nxt < 0 else "corrupt log: an event longer than the rest of the file")
            if not partial:
                raise LogDamaged(path, pos, what)
            scan.note(pos)
            if nxt < 0:
                scan.torn_tail_bytes += size - pos
                return
            scan.skipped_bytes += nxt - pos
            pos = nxt
            continue
        ch = mm[pos + hsize:pos + hsize + clen]
        data = mm[pos + hsize + clen:end]
        pos = end
        scan.events += 1
        yield num, ts, ch, data
