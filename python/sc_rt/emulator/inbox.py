"""What the plant emulator's receive side (emulator/process.py) keeps per
state seq.

- ``Inbox``: per state seq k of the run's n rows, the first valid command
  answering k (its bytes, the monotonic ns of its receipt, its utime), the
  first valid rod command answering k (a run with magnetic control), the
  first status for k (its bytes, decoded after the run) and the times state
  k went out (the utime of its first publish, the monotonic ns of its last).
  Columns of the emulator's record (results/record/store.py ``RowRing``): two
  chunks of rows live, allocated and touched when the emulator is made,
  the older rows on disk, so nothing grows with the run. A state seq outside
  [0, n) (a hostile or stray message) is counted (``state_seq_out_of_range``)
  and not kept, as is one outside the live rows (``state_seq_not_live``);
  -1 (answers no state) is not kept either, as always.
- The handlers that fill it, ``Receiver``, are emulator/receiver.py.
"""

from __future__ import annotations

import struct
from collections import Counter
from typing import NamedTuple

import numpy as np
import sc_rt_lcm

from sc_rt.emulator.loopstats import MISSING
from sc_rt.wire.codec import STATUS_FROM_COMMANDS, STATUS_NAV_FIELDS, STATUS_RUN_FIELDS, STATUS_TIMING_FIELDS
from sc_rt.results.record.store import RowRing

__all__ = ["Inbox", "Cmd", "Rod", "SEQ_WINDOW", "INBOX_COLUMNS", "decode_status", "fill_from_inbox"]

# controller_status_t's fixed layout: fingerprint, then utime, cmd_seq,
# session, state_seq (big-endian int64), as generated from the .lcm file
_STATUS_FP = sc_rt_lcm.controller_status_t._get_packed_fingerprint()
_STATUS_SIZE = len(sc_rt_lcm.controller_status_t().encode())
_STATUS_HEAD = struct.Struct(">qqqq")
# wheel_cmd_t: utime, seq, session, state_seq, t, u_cmd[4], u_sat[4], mode, flags
_CMD_FP = sc_rt_lcm.wheel_cmd_t._get_packed_fingerprint()
_CMD_SIZE = len(sc_rt_lcm.wheel_cmd_t().encode())
_CMD_LAYOUT = struct.Struct(">qqqqd4d4dbi")
assert _CMD_LAYOUT.size + 8 == _CMD_SIZE and _STATUS_HEAD.size + 8 < _STATUS_SIZE
# rod_cmd_t: utime, seq, session, state_seq, t, n_rods, dipole[6]
_ROD_FP = sc_rt_lcm.rod_cmd_t._get_packed_fingerprint()
_ROD_SIZE = len(sc_rt_lcm.rod_cmd_t().encode())
_ROD_LAYOUT = struct.Struct(">qqqqdb6d")
assert _ROD_LAYOUT.size + 8 == _ROD_SIZE
# plant_state_t: its seq and session (after utime), to tell another plant's
_STATE_SIZE = len(sc_rt_lcm.plant_state_t().encode())
_STATE_FP = sc_rt_lcm.plant_state_t._get_packed_fingerprint()
_NONE = int(MISSING)  # a Python int: compared and stored per message


#: Commands (and statuses) the controller may skip at once; a seq further ahead
#: is taken as the newest only when its successor confirms it (docs/PROTOCOL.md,
#: "Sequence numbers"): one forged message cannot make the genuine ones "old"
SEQ_WINDOW = 1000


class Cmd(NamedTuple):
    """The fields of a wheel_cmd_t the loop uses."""

    seq: int
    session: int
    state_seq: int
    u_cmd: tuple
    u_sat: tuple
    mode: int = -1
    flags: int = 0


class Rod(NamedTuple):
    """The fields of a rod_cmd_t the loop uses."""

    seq: int
    session: int
    state_seq: int
    dipole: tuple  # [A m^2] the n_rods commands


def _rod_of(v: tuple) -> Rod:
    return Rod(seq=v[1], session=v[2], state_seq=v[3], dipole=v[6:6 + max(0, min(6, v[5]))])


def _cmd_of(v: tuple) -> Cmd:
    return Cmd(seq=v[1], session=v[2], state_seq=v[3], u_cmd=v[5:9], u_sat=v[9:13], mode=v[13], flags=v[14])


#: The inbox's columns in the emulator's record (results/record/store.py ``Column``):
#: per state seq, the command and the status as received and their times.
INBOX_COLUMNS = (
    ("cmd_raw", (_CMD_SIZE,), "u1", 0),
    ("cmd_rx", (), "i8", MISSING),  # [monotonic ns] receipt; MISSING: no command for k
    ("cmd_utime", (), "i8", MISSING),  # [us] the command's utime (the controller's publish)
    ("pub_wall_us", (), "i8", MISSING),  # [us] utime of state k's first publish
    ("pub_ns", (), "i8", MISSING),  # [monotonic ns] state k's last publish
    ("status_raw", (_STATUS_SIZE,), "u1", 0),
    ("status_len", (), "i4", -1),  # -1: no status for k; 0: one not kept (too long)
    ("rod_raw", (_ROD_SIZE,), "u1", 0),  # the rod command answering k (magnetic control)
    ("rod_rx", (), "i8", MISSING),  # [monotonic ns] its receipt; MISSING: none for k
)


class Inbox:
    """Per state seq of a run of ``n`` rows: its command, its status and
    its publish times (module docstring), in the live rows of the
    emulator's record ``ring`` (results/record/store.py ``RowRing``: two chunks of
    rows, the older ones on disk). The int64 times are ``MISSING``
    (emulator/loopstats.py) where there is none. A message for a seq that is
    no longer live (older than a chunk of rows) or not yet (ahead of the
    states published) is counted (``state_seq_not_live``) and not kept.
    Without ``ring`` every row is live (a ring of one chunk of ``n`` rows)."""

    #: bytes per row: the command and the status as received, four int64 times, the status length
    BYTES_PER_ROW = _CMD_SIZE + _STATUS_SIZE + 4 * 8 + 4 + _ROD_SIZE + 8

    def __init__(self, n: int, counters: Counter, ring: RowRing | None = None):
        self.n, self.counters = n, counters
        self.ring = ring if ring is not None else RowRing(INBOX_COLUMNS, max(1, n), lambda *_: None)

    def _slot(self, k: int, count: bool = True) -> tuple[dict[str, np.ndarray], int] | None:
        """Row k's columns and offset when k is a live row of the run; a seq
        past the run, or not live, is counted (-1 and other negative seqs
        answer no state)."""
        if 0 <= k < self.n:
            s = self.ring.slot(k)
            if s is None and count:
                self.counters["state_seq_not_live"] += 1
            return s
        if k >= self.n and count:
            self.counters["state_seq_out_of_range"] += 1
        return None

    # --- commands ------------------------------------------------------------
    def put_cmd(self, k: int, data: bytes | None, msg: Cmd, now: int, utime: int = _NONE) -> None:
        """The first valid command answering state k (``data``: its bytes in
        the fixed layout, None: pack ``msg``); later ones are not kept."""
        s = self._slot(k)
        if s is None:
            return
        c, j = s
        if c["cmd_rx"][j] != _NONE:
            return
        if data is not None:
            c["cmd_raw"][j] = np.frombuffer(data, np.uint8)
        else:
            _CMD_LAYOUT.pack_into(c["cmd_raw"][j], 8, 0, msg.seq, msg.session, msg.state_seq, 0.0,
                                  *msg.u_cmd, *msg.u_sat, msg.mode, msg.flags)
        c["cmd_rx"][j] = now
        c["cmd_utime"][j] = utime

    def has_cmd(self, k: int) -> bool:
        s = self._slot(k, count=False)
        return s is not None and s[0]["cmd_rx"][s[1]] != _NONE

    def cmd(self, k: int) -> Cmd | None:
        """The first valid command answering state k, None when none came."""
        s = self._slot(k, count=False)
        if s is None or s[0]["cmd_rx"][s[1]] == _NONE:
            return None
        return _cmd_of(_CMD_LAYOUT.unpack_from(s[0]["cmd_raw"][s[1]], 8))

    def cmd_session(self, k: int) -> int:
        """The session of the command answering k (has_cmd(k))."""
        c, j = self._slot(k, count=False)
        return _CMD_LAYOUT.unpack_from(c["cmd_raw"][j], 8)[2]

    def cmd_times(self, k: int) -> tuple[int, int]:
        """(receipt [monotonic ns], utime [us]) of the command answering k (MISSING: none)."""
        c, j = self._slot(k, count=False)
        return int(c["cmd_rx"][j]), int(c["cmd_utime"][j])

    # --- rod commands -----------------------------------------------------------
    def put_rod(self, k: int, data: bytes, now: int) -> None:
        """The first valid rod command answering state k (its bytes, the fixed
        layout); later ones are not kept."""
        s = self._slot(k)
        if s is None:
            return
        c, j = s
        if c["rod_rx"][j] != _NONE:
            return
        c["rod_raw"][j] = np.frombuffer(data, np.uint8)
        c["rod_rx"][j] = now

    def has_rod(self, k: int) -> bool:
        s = self._slot(k, count=False)
        return s is not None and s[0]["rod_rx"][s[1]] != _NONE

    def rod(self, k: int) -> Rod | None:
        """The first valid rod command answering state k, None when none came."""
        s = self._slot(k, count=False)
        if s is None or s[0]["rod_rx"][s[1]] == _NONE:
            return None
        return _rod_of(_ROD_LAYOUT.unpack_from(s[0]["rod_raw"][s[1]], 8))

    # --- status ----------------------------------------------------------------
    def put_status(self, k: int, data: bytes) -> None:
        """The first status for state k, as its bytes (one longer than the
        fixed layout, possible only for a type with variable fields, counts
        as received and is not kept: ``status_not_kept``)."""
        s = self._slot(k)
        if s is None:
            return
        c, j = s
        if c["status_len"][j] >= 0:
            return
        m = len(data)
        if m > _STATUS_SIZE:
            self.counters["status_not_kept"] += 1
            c["status_len"][j] = 0
            return
        c["status_raw"][j][:m] = np.frombuffer(data, np.uint8)
        c["status_len"][j] = m

    def has_status(self, k: int) -> bool:
        s = self._slot(k, count=False)
        return s is not None and s[0]["status_len"][s[1]] >= 0

    def status(self, k: int):
        """State k's controller_status_t, decoded (None: none kept)."""
        s = self._slot(k, count=False)
        return None if s is None else decode_status(s[0], s[1])

    # --- our states ------------------------------------------------------------
    def published(self, k: int, utime: int, now: int) -> None:
        """State k went out at ``utime`` [us] (the first time counts) and
        monotonic ``now`` [ns] (the last time counts)."""
        s = self._slot(k, count=False)
        if s is not None:
            c, j = s
            if c["pub_wall_us"][j] == _NONE:
                c["pub_wall_us"][j] = utime
            c["pub_ns"][j] = now

    def pub_times(self, k: int) -> tuple[int, int]:
        """(first publish utime [us], last publish [monotonic ns]) of state k (MISSING: none)."""
        c, j = self._slot(k, count=False)
        return int(c["pub_wall_us"][j]), int(c["pub_ns"][j])


def decode_status(cols: dict[str, np.ndarray], j: int):
    """Row j's controller_status_t of an inbox's columns, decoded (None: none kept)."""
    m = int(cols["status_len"][j])
    if m <= 0:
        return None
    return sc_rt_lcm.controller_status_t.decode(cols["status_raw"][j][:m].tobytes())


def fill_from_inbox(run, cols: dict[str, np.ndarray]) -> None:
    """A chunk of the run's rows (``run``, in memory) and the inbox's columns
    of the same rows (``cols``): the controller telemetry and timing from
    every status kept (decoded now: ~35 us each), and the latency (state
    publish to the command's receipt) of every state answered."""
    rows = len(run)
    for k in np.flatnonzero(cols["status_len"][:rows] > 0):
        s = decode_status(cols, k)
        for name in STATUS_RUN_FIELDS + STATUS_TIMING_FIELDS:
            if name not in STATUS_FROM_COMMANDS:  # those: the commands the row applied (emulator/process.py)
                run[name][k] = getattr(s, name)
        if s.nav:  # a [sensors] run: the controller's estimator, its flag into the row's (as offline)
            for name in STATUS_NAV_FIELDS:
                run[name][k] = getattr(s, name)
            run["flags"][k] |= s.nav_flags
    rx, pub = cols["cmd_rx"][:rows], cols["pub_ns"][:rows]
    ok = (rx != MISSING) & (pub != MISSING)
    run["latency_us"][ok] = (rx[ok] - pub[ok]) / 1e3
