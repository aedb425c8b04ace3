"""The plant emulator's receive side (emulator/process.py): its LCM handlers and
what they keep per state seq.

- ``Inbox``: per state seq k of the run's n rows, the first valid command
  answering k (its bytes, the monotonic ns of its receipt, its utime), the
  first status for k (its bytes, decoded after the run) and the times state
  k went out (the utime of its first publish, the monotonic ns of its last).
  Columns of the emulator's record (results/record/store.py ``RowRing``): two
  chunks of rows live, allocated and touched when the emulator is made,
  the older rows on disk, so nothing grows with the run. A state seq outside
  [0, n) (a hostile or stray message) is counted (``state_seq_out_of_range``)
  and not kept, as is one outside the live rows (``state_seq_not_live``);
  -1 (answers no state) is not kept either, as always.
- ``Receiver``: the handlers, a part of ``Emulator``; they never raise.
  Every message is decoded under guard and counted by kind (``counters``);
  commands and status come from one controller session at a time, a new one
  adopted only once the current one is lost; fault commands change the
  actuators when accepted; another plant, or another controller while ours
  is alive, is a bench collision (emulator/collision.py) that stops the run.
"""

from __future__ import annotations

import dataclasses
import math
import struct
import time
from collections import Counter
from typing import Any, NamedTuple

import numpy as np
import sc_rt_lcm

from sc_rt.wire.lcmio import channel
from sc_rt.emulator.loopstats import MISSING
from sc_rt.wire.codec import STATUS_NAV_FIELDS, STATUS_RUN_FIELDS, STATUS_TIMING_FIELDS, decode_as
from sc_rt.emulator.peers import ControllerPeers
from sc_rt.emulator.state import Shared
from sc_rt.model.actuators import WheelFault
from sc_rt.results.record.store import RowRing

__all__ = ["Inbox", "Receiver", "Cmd", "SEQ_WINDOW", "INBOX_COLUMNS", "decode_status", "fill_from_inbox"]

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
    BYTES_PER_ROW = _CMD_SIZE + _STATUS_SIZE + 4 * 8 + 4

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
            run[name][k] = getattr(s, name)
        if s.nav:  # a [sensors] run: the controller's estimator, its flag into the row's (as offline)
            for name in STATUS_NAV_FIELDS:
                run[name][k] = getattr(s, name)
            run["flags"][k] |= s.nav_flags
    rx, pub = cols["cmd_rx"][:rows], cols["pub_ns"][:rows]
    ok = (rx != MISSING) & (pub != MISSING)
    run["latency_us"][ok] = (rx[ok] - pub[ok]) / 1e3


class Receiver:
    """The emulator's LCM handlers (a part of ``Emulator``, built and tested
    alone: tests/test_fault.py, tests/test_inbox.py).

    Owns the receive state: ``inbox``, the newest command (``newest_cmd``,
    ``newest_cmd_ns``), the adopted controller session (``ctl_session``,
    ``ctl_last_ns``, ``peer_lost``, which the loop sets when a state went
    unanswered) and the last seqs taken from it. Shares with the other parts
    only ``shared`` (emulator/state.py): the counters, the wheels' faults
    (a fault command replaces ``shared.act``), the run's time and a bench
    collision (``shared.collision``)."""

    def __init__(self, lc: Any, prefix: str, session: int, n_rows: int, shared: Shared, *,
                 guard: Any = None, peers: ControllerPeers | None = None, accept_faults: bool = False,
                 authenticated: bool = False, ring: RowRing | None = None):
        self.lc, self.prefix, self.session, self.shared = lc, prefix, session, shared
        self.counters = shared.counters
        self.guard = guard
        self.peers = peers if peers is not None else ControllerPeers(None)
        self.accept_faults = accept_faults
        #: a bus with a key: a fault command must name this emulator's session and a seq above the last
        self.authenticated = authenticated
        self._last_fault_seq: int | None = None
        self.inbox = Inbox(n_rows, self.counters, ring)
        self.newest_cmd: Cmd | None = None
        self.newest_cmd_ns = 0
        self._last_cmd_seq = -1
        self._last_status_seq = -1
        # per counter, the newest unconfirmed seq jump (-2: none)
        self._jumps = {"cmd_seq_jump": -2, "status_seq_jump": -2}
        self.ctl_session: int | None = None
        self.ctl_last_ns = 0  # monotonic ns of the adopted controller's newest message
        self.peer_lost = False
        # LCM silently drops messages beyond a subscription's queue capacity
        # (30 by default): hold many, so every one is either used or counted
        for name, handler in (("SCRT_CMD", self.on_cmd), ("SCRT_CTRL_STATUS", self.on_status),
                              ("SCRT_FAULT", self.on_fault), ("SCRT_CTRL_INFO", self.on_info),
                              ("SCRT_STATE", self.on_plant_state)):
            self.lc.subscribe(channel(name, self.prefix), handler).set_queue_capacity(100_000)

    def on_plant_state(self, _ch: str, data: bytes) -> None:
        """Our own states come back (multicast loopback); another plant's mean another bench."""
        if len(data) == _STATE_SIZE and data[:8] == _STATE_FP:
            _, seq, session = struct.unpack_from(">qqq", data, 8)
            if session != self.session and self.guard is not None:
                self.shared.collision(self.guard.plant_state(session, seq, self.ctl_session))

    def _session_ok(self, session: int, now: int, seq: int = -1, kind: str = "cmd") -> bool:
        """Commands and status come from one controller session at a time; a
        new session is adopted only once the current controller is lost (the
        loop saw an unanswered state in lockstep or a stale command in real
        time: a crashed or restarted controller), never while it answers."""
        if session == self.ctl_session:
            self.ctl_last_ns = now
            return True
        if self.ctl_session is None or self.peer_lost:
            if self.ctl_session is not None:
                self.counters["controller_sessions_adopted"] += 1
            self.ctl_session = session
            self.ctl_last_ns = now
            self.peer_lost = False
            self._last_cmd_seq = -1
            self._last_status_seq = -1
            return True
        self.counters["foreign_session"] += 1
        if self.guard is not None:
            self.shared.collision(self.guard.controller_msg(session, seq, self.ctl_session, self.ctl_last_ns,
                                                            now, kind))
        return False

    def _unconfirmed_jump(self, counter: str, last: int, seq: int) -> bool:
        """Whether ``seq`` is more than SEQ_WINDOW ahead of ``last`` (the newest
        taken) and not confirmed by being the successor of the jump held
        before: dropped, counted under ``counter`` and held in its turn."""
        if last >= 0 and seq - last > SEQ_WINDOW and seq != self._jumps[counter] + 1:
            self._jumps[counter] = seq
            self.counters[counter] += 1
            return True
        self._jumps[counter] = -2
        return False

    def on_cmd(self, _ch: str, data: bytes) -> None:
        now = time.monotonic_ns()
        self.counters["cmd_received"] += 1
        fixed = len(data) == _CMD_SIZE and data[:8] == _CMD_FP
        if fixed:  # the fixed layout, unpacked at once
            v = _CMD_LAYOUT.unpack_from(data, 8)
            msg = _cmd_of(v)
        else:  # not exactly one wheel_cmd_t: count it by kind
            msg = decode_as(sc_rt_lcm.wheel_cmd_t, data, self.counters)
            if msg is None:
                return
        # any finite command is meaningful: the wheels saturate it (15)
        if not all(math.isfinite(v) for v in msg.u_cmd):
            self.counters["invalid_command"] += 1
            return
        if not self._session_ok(msg.session, now, msg.seq, "cmd"):
            return
        if msg.seq <= self._last_cmd_seq:
            last = self.newest_cmd
            if (msg.seq == self._last_cmd_seq and last is not None
                    and (msg.state_seq != last.state_seq or tuple(msg.u_cmd) != tuple(last.u_cmd))):
                # the controller's session and seq, another command: a forged or racing sender
                self.counters["cmd_conflict"] += 1
            else:
                self.counters["duplicate" if msg.seq == self._last_cmd_seq else "out_of_order"] += 1
            return
        if self._unconfirmed_jump("cmd_seq_jump", self._last_cmd_seq, msg.seq):
            return
        self._last_cmd_seq = msg.seq
        self.newest_cmd, self.newest_cmd_ns = msg, now
        if fixed:
            self.inbox.put_cmd(msg.state_seq, data, msg, now, v[0])
        else:
            self.inbox.put_cmd(msg.state_seq, None, msg, now)

    def on_status(self, _ch: str, data: bytes) -> None:
        # The loop needs only the header (session, seqs) now; the full decode
        # (~35 us in Python) waits until the run is over (fill_from_inbox).
        now = time.monotonic_ns()
        if len(data) == _STATUS_SIZE and data[:8] == _STATUS_FP:
            _, cmd_seq, session, state_seq = _STATUS_HEAD.unpack_from(data, 8)
        else:  # not exactly one status message: count it by kind
            msg = decode_as(sc_rt_lcm.controller_status_t, data, self.counters)
            if msg is None:
                return
            cmd_seq, session, state_seq = msg.cmd_seq, msg.session, msg.state_seq
        if not self._session_ok(session, now, cmd_seq, "status"):
            return
        if cmd_seq <= self._last_status_seq:
            self.counters["status_out_of_order"] += 1
            return
        if self._unconfirmed_jump("status_seq_jump", self._last_status_seq, cmd_seq):
            return
        self._last_status_seq = cmd_seq
        self.peers.saw_status(session)
        self.inbox.put_status(state_seq, data)

    def on_info(self, _ch: str, data: bytes) -> None:
        self.peers.on_info(data, self.counters)

    @property
    def controller_info(self) -> dict[str, Any] | None:
        """The controller_info_t of the session in use (None: none announced)."""
        return self.peers.info.get(self.ctl_session) if self.ctl_session is not None else None

    def on_fault(self, _ch: str, data: bytes) -> None:
        msg = decode_as(sc_rt_lcm.fault_cmd_t, data, self.counters)
        if msg is None:
            return
        if not self.accept_faults:
            self.counters["fault_ignored"] += 1
            return
        # addressed to another emulator (or, under authentication, to none): not ours
        if (msg.session != 0 or self.authenticated) and msg.session != self.session:
            self.counters["fault_foreign_session"] += 1
            return
        if self.authenticated and self._last_fault_seq is not None and msg.seq <= self._last_fault_seq:
            self.counters["fault_replayed"] += 1  # a captured command sent again: refused
            return
        try:
            self._apply_fault(msg)
            self.counters["fault_applied"] += 1
            self._last_fault_seq = msg.seq
        except ValueError as e:
            self.counters["fault_rejected"] += 1
            self.shared.faults_applied.append({"rejected": str(e), "wheel": msg.wheel})

    def _apply_fault(self, m) -> None:
        if not 1 <= m.wheel <= 4:
            raise ValueError(f"wheel must be 1..4, got {m.wheel}")
        w = m.wheel - 1
        others = tuple(f for f in self.shared.act.faults if f.wheel != w)
        if m.action == sc_rt_lcm.fault_cmd_t.ACTION_CLEAR:
            new = others
            rec = {"t": self.shared.t_now, "wheel": m.wheel, "action": "clear"}
        elif m.action == sc_rt_lcm.fault_cmd_t.ACTION_INJECT:
            onset = self.shared.t_now if m.now else m.t_onset
            fault = WheelFault(wheel=w, effectiveness=m.effectiveness, bias=m.bias, onset=onset,
                               end=None if m.t_end < 0 else m.t_end, rate=m.rate, stuck=bool(m.stuck),
                               friction=m.friction)
            new = others + (fault,)
            rec = {"t": self.shared.t_now, "wheel": m.wheel, "action": "inject",
                   **{k: getattr(fault, k) for k in ("effectiveness", "bias", "onset", "end", "rate", "stuck",
                                                             "friction")}}
        else:
            raise ValueError(f"unknown action {m.action}")
        self.shared.act = dataclasses.replace(self.shared.act, faults=new)  # validated by ActuatorParams
        self.shared.faults_applied.append(rec)
