"""The plant emulator's LCM handlers (emulator/process.py), its receive
side: ``Receiver``, a part of ``Emulator``; the handlers never raise.
Every message is decoded under guard and counted by kind (``counters``);
commands and status come from one controller session at a time, a new one
adopted only once the current one is lost; fault commands (the wheels' and
the rods') change the actuators when accepted; another plant, or another controller while ours
is alive, is a bench collision (emulator/collision.py) that stops the run.
What they keep per state seq is the ``Inbox`` (emulator/inbox.py).
"""

from __future__ import annotations

import dataclasses
import math
import struct
import time
from typing import Any

import sc_rt_lcm

from sc_rt.wire.lcmio import channel
from sc_rt.emulator.inbox import (
    Cmd, Inbox, Rod, SEQ_WINDOW, _cmd_of, _rod_of, _ROD_FP, _ROD_SIZE, _ROD_LAYOUT,
    _CMD_FP, _CMD_SIZE, _CMD_LAYOUT, _STATE_FP, _STATE_SIZE, _STATUS_FP, _STATUS_SIZE, _STATUS_HEAD,
)
from sc_rt.wire.codec import decode_as
from sc_rt.emulator.peers import ControllerPeers
from sc_rt.emulator.state import Shared
from sc_rt.model.actuators import WheelFault
from sc_rt.model.rods import ROD_FAULTS, RodFault
from sc_rt.results.record.store import RowRing

__all__ = ["Receiver", "MAX_REFUSALS_KEPT"]

#: refused fault commands kept with their reason in ``faults_applied`` (timing.json); the rest are
#: counted only (``fault_rejected``), so that a flood of them cannot grow the emulator's memory
MAX_REFUSALS_KEPT = 100


class Receiver:
    """The emulator's LCM handlers (a part of ``Emulator``, built and tested
    alone: tests/test_fault.py, tests/test_inbox.py).

    Owns the receive state: ``inbox``, the newest command (``newest_cmd``,
    ``newest_cmd_ns``), the adopted controller session (``ctl_session``,
    ``ctl_last_ns``, ``peer_lost``, which the loop sets when a state went
    unanswered) and the last seqs taken from it. Shares with the other parts
    only ``shared`` (emulator/state.py): the counters, the wheels' faults
    (a fault command replaces ``shared.act``), the rods' (a rod fault
    command replaces ``shared.rods``), the run's time and a bench collision
    (``shared.collision``)."""

    def __init__(self, lc: Any, prefix: str, session: int, n_rows: int, shared: Shared, *,
                 guard: Any = None, peers: ControllerPeers | None = None, accept_faults: bool = False,
                 authenticated: bool = False, ring: RowRing | None = None, n_rods: int = 0):
        self.lc, self.prefix, self.session, self.shared = lc, prefix, session, shared
        self.counters = shared.counters
        self.guard = guard
        self.peers = peers if peers is not None else ControllerPeers(None)
        self.accept_faults = accept_faults
        #: a bus with a key: a fault command must name this emulator's session and a seq above the last
        self.authenticated = authenticated
        self.inbox = Inbox(n_rows, self.counters, ring)
        self.newest_cmd: Cmd | None = None
        self.newest_cmd_ns = 0
        self._last_cmd_seq = -1
        self._last_status_seq = -1
        #: magnetic control: the rods' newest command (rod_cmd_t) and its receipt [monotonic ns]
        self.n_rods = n_rods
        self.newest_rod: Rod | None = None
        self._last_rod_seq = -1
        # per counter, the newest unconfirmed seq jump (-2: none)
        self._jumps = {"cmd_seq_jump": -2, "status_seq_jump": -2, "rod_seq_jump": -2}
        self.ctl_session: int | None = None
        self.ctl_last_ns = 0  # monotonic ns of the adopted controller's newest message
        self.peer_lost = False
        # LCM silently drops messages beyond a subscription's queue capacity
        # (30 by default): hold many, so every one is either used or counted
        for name, handler in (("SCRT_CMD", self.on_cmd), ("SCRT_CTRL_STATUS", self.on_status),
                              ("SCRT_FAULT", self.on_fault), ("SCRT_ROD_FAULT", self.on_rod_fault),
                              ("SCRT_CTRL_INFO", self.on_info), ("SCRT_STATE", self.on_plant_state)):
            self.lc.subscribe(channel(name, self.prefix), handler).set_queue_capacity(100_000)
        if n_rods:  # a run with magnetic control: the rods' commands (docs/PROTOCOL.md)
            self.lc.subscribe(channel("SCRT_ROD_CMD", self.prefix), self.on_rod).set_queue_capacity(100_000)

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
            self._last_rod_seq = -1
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

    def on_rod(self, _ch: str, data: bytes) -> None:
        """A rod command (rod_cmd_t): the same session, order and window rules
        as a wheel command, its own seq line; kept per state seq and as the newest."""
        now = time.monotonic_ns()
        self.counters["rod_cmd_received"] += 1
        if len(data) == _ROD_SIZE and data[:8] == _ROD_FP:
            v = _ROD_LAYOUT.unpack_from(data, 8)
        else:  # not exactly one rod_cmd_t: count it by kind
            msg = decode_as(sc_rt_lcm.rod_cmd_t, data, self.counters)
            if msg is None:
                return
            data = msg.encode()
            v = _ROD_LAYOUT.unpack_from(data, 8)
        rod = _rod_of(v)
        if v[5] != self.n_rods or not all(math.isfinite(d) for d in rod.dipole):
            self.counters["invalid_rod_command"] += 1  # another rod count, or a non-finite dipole
            return
        if not self._session_ok(rod.session, now, rod.seq, "rod"):
            return
        if rod.seq <= self._last_rod_seq:
            last = self.newest_rod
            if (rod.seq == self._last_rod_seq and last is not None
                    and (rod.state_seq != last.state_seq or rod.dipole != last.dipole)):
                self.counters["rod_conflict"] += 1  # the controller's session and seq, another command
            else:
                self.counters["rod_duplicate" if rod.seq == self._last_rod_seq else "rod_out_of_order"] += 1
            return
        if self._unconfirmed_jump("rod_seq_jump", self._last_rod_seq, rod.seq):
            return
        self._last_rod_seq = rod.seq
        self.newest_rod = rod
        self.inbox.put_rod(rod.state_seq, data, now)

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

    def _admitted(self, msg) -> bool:
        """Whether a fault command (fault_cmd_t or rod_fault_cmd_t: the same
        rules, one seq line) may change the plant: the emulator accepts fault
        commands, the command is addressed to it (under authentication by its
        session, never to any) and, under authentication, its seq is above the
        last one applied (not a replay). Counted when refused."""
        if not self.accept_faults:
            self.counters["fault_ignored"] += 1
            return False
        # addressed to another emulator (or, under authentication, to none): not ours
        if (msg.session != 0 or self.authenticated) and msg.session != self.session:
            self.counters["fault_foreign_session"] += 1
            return False
        if (self.authenticated and self.counters["fault_applied"]  # the last one applied: shared.fault_seq_applied
                and msg.seq <= self.shared.fault_seq_applied):
            self.counters["fault_replayed"] += 1  # a captured command sent again: refused
            return False
        return True

    def on_fault(self, _ch: str, data: bytes) -> None:
        """A wheel fault command (fault_cmd_t), applied to ``shared.act``."""
        self._fault_command(sc_rt_lcm.fault_cmd_t, data, self._apply_fault, "wheel")

    def on_rod_fault(self, _ch: str, data: bytes) -> None:
        """A rod fault command (rod_fault_cmd_t), applied to ``shared.rods``
        (the loop takes them at the next row)."""
        self._fault_command(sc_rt_lcm.rod_fault_cmd_t, data, self._apply_rod_fault, "rod")

    def _fault_command(self, cls, data: bytes, apply, target: str) -> None:
        """A fault command of type ``cls``: admitted by the rules of ``_admitted``,
        then ``apply``-ed; one the plant refuses (ValueError) is recorded with
        its reason and its ``target`` (the wheel's or rod's number)."""
        msg = decode_as(cls, data, self.counters)
        if msg is None or not self._admitted(msg):
            return
        try:
            apply(msg)
            self.counters["fault_applied"] += 1
            self.shared.fault_seq_applied = msg.seq  # the truth echoes it; the replay rule reads it
        except ValueError as e:
            self.counters["fault_rejected"] += 1
            self.shared.fault_seq_refused = msg.seq
            if self.counters["fault_rejected"] <= MAX_REFUSALS_KEPT:  # a flood of them: counted, not all kept
                self.shared.faults_applied.append({"rejected": str(e), target: getattr(msg, target)})

    def _apply_rod_fault(self, m) -> None:
        rods = self.shared.rods
        if rods is None:
            raise ValueError("the plant has no magnetorquer rods ([magnetorquers])")
        if not 1 <= m.rod <= rods.n_rods:
            raise ValueError(f"rod must be 1..{rods.n_rods} (the plant's rods), got {m.rod}")
        r = m.rod - 1
        others = tuple(f for f in rods.faults if f.rod != r)
        if m.action == sc_rt_lcm.rod_fault_cmd_t.ACTION_CLEAR:
            new = others
            rec = {"t": self.shared.t_now, "rod": m.rod, "action": "clear"}
        elif m.action == sc_rt_lcm.rod_fault_cmd_t.ACTION_INJECT:
            kind = {v: k for k, v in ROD_FAULTS.items()}.get(m.kind)
            if kind is None:
                raise ValueError(f"unknown rod fault kind {m.kind}")
            if kind != "stuck" and m.dipole != 0.0:
                raise ValueError(f"dipole is a stuck rod's value: a {kind} rod takes none, got {m.dipole}")
            onset = self.shared.t_now if m.now else m.t_onset
            fault = RodFault(rod=r, kind=kind, dipole=m.dipole, onset=onset,
                             end=math.inf if m.t_end < 0 else m.t_end)
            new = others + (fault,)
            rec = {"t": self.shared.t_now, "rod": m.rod, "action": "inject", "kind": kind, "dipole": fault.dipole,
                   "onset": onset, "end": None if m.t_end < 0 else fault.end}
        else:
            raise ValueError(f"unknown action {m.action}")
        self.shared.rods = dataclasses.replace(rods, faults=new)  # validated by Magnetorquers
        self.shared.faults_applied.append(rec)

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
