"""The plant as an LCM process (``sc-rt emulator``).

Publishes ``guidance_t`` (SCRT_GUIDANCE, the reference, just before each
state), ``plant_state_t`` (SCRT_STATE) and ``plant_truth_t`` (SCRT_TRUTH),
applies the newest valid ``wheel_cmd_t`` it holds (zero-order hold), with the
scenario's saturation and faults, and records the run (docs/PROTOCOL.md).

- lockstep: publish state k, wait for the command answering k (and the
  controller's status for k from a controller that sends them: bus/peers.py),
  apply it over one control period. The same loop and arithmetic as
  ``sim.simulate(engine="python")``: same numbers.
- realtime: a tick every 1/rate s of wall clock divided by the time scale;
  at each tick the newest command is applied over the next period; commands
  older than ``stale_periods`` periods, or invalid, are replaced by zero and
  flagged (watchdog).

Both loops publish the next state first, then the truth of the row just
applied (the controller computes while the emulator records), integrate with
the C++ plant twin (``_core.plant_rk4_step``, bitwise the Python
``model.plant.rk4_step``; ``cpp_plant=False`` runs the Python one, for a
changed model/plant.py), and run with the garbage collector frozen
(bus/rtproc.py). Real time sleeps in ``select`` until ``spin_us`` before
the tick and polls from there.

Bad input never stops the loop: every message is decoded under guard and
counted by kind (``counters``).
"""

from __future__ import annotations

import dataclasses
import math
import secrets
import select
import struct
import time
from collections import Counter
from typing import Any, Callable, NamedTuple

import numpy as np
import sc_rt_lcm

from sc_rt import _core
from sc_rt.model import actuators, plant
from sc_rt.model.actuators import WheelFault
from sc_rt.bus.auth import open_bus
from sc_rt.bus.collision import CollisionGuard
from sc_rt.bus.lcmio import channel
from sc_rt.bus.loopstats import loop_breakdown
from sc_rt.bus.peers import ControllerPeers, GuidancePublisher
from sc_rt.bus.rtproc import RealtimeThread
from sc_rt.bus.wire import STATUS_RUN_FIELDS, STATUS_TIMING_FIELDS, decode_as
from sc_rt.results.run import Run, RunMeta, provenance
from sc_rt.scenario.model import Scenario
from sc_rt.scenario.overrides import grid, initial_state, with_overrides

__all__ = ["Emulator"]
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


# plant_state_t: utime, seq, session, t, sigma_BN[3], omega_BN_B[3], wheel_speed[4]
_STATE_FP = sc_rt_lcm.plant_state_t._get_packed_fingerprint()
_STATE_LAYOUT = struct.Struct(">qqqd3d3d4d")
# plant_truth_t: utime, seq, t, cmd_seq_applied, u_cmd[4], wheel_accel[4],
# delta2[3], disturbance[3], fault_Y[4], fault_effectiveness[4], fault_bias[4],
# fault_stuck[4] (int8), cmd_stale (int8)
_TRUTH_FP = sc_rt_lcm.plant_truth_t._get_packed_fingerprint()
_TRUTH_LAYOUT = struct.Struct(">qqdq4d4d3d3d4d4d4d4bb")
assert _STATE_LAYOUT.size + 8 == len(sc_rt_lcm.plant_state_t().encode())
assert _TRUTH_LAYOUT.size + 8 == len(sc_rt_lcm.plant_truth_t().encode())


class _Cmd(NamedTuple):
    """The fields of a wheel_cmd_t the loop uses."""

    seq: int
    session: int
    state_seq: int
    u_cmd: tuple
    u_sat: tuple
    mode: int = -1
    flags: int = 0


class Emulator:
    def __init__(self, scn: Scenario, *, mode: str = "lockstep", url: str, prefix: str = "",
                 rate: float | None = None, time_scale: float = 1.0, duration: float | None = None,
                 accept_fault_commands: bool = False, cmd_timeout: float = 1.0, retries: int = 3,
                 stale_periods: float | None = None, wait_status: bool | None = None,
                 start_timeout: float | None = None,
                 stop: Callable[[], str | None] | None = None, auth_key: bytes | None = None,
                 spin_us: float = 100.0, cpu: int | None = None, realtime_priority: bool = False,
                 freeze_gc: bool = True, cpp_plant: bool = True):
        if mode not in ("lockstep", "realtime"):
            raise ValueError(f"mode must be lockstep or realtime, got {mode!r}")
        if not (time_scale > 0 and math.isfinite(time_scale)):
            raise ValueError(f"time scale must be > 0, got {time_scale}")
        scn = with_overrides(scn, control_rate_hz=rate, duration=duration)
        self.scn, self.mode, self.prefix = scn, mode, prefix
        self.rate = scn.run.control_rate_hz
        self.duration = scn.run.duration
        self.time_scale = time_scale
        #: real time: poll (no sleep) for the last spin_us before each tick
        self._spin_ns = int(max(0.0, spin_us) * 1e3)
        #: the emulator thread's CPU, SCHED_FIFO + mlockall, gc (bus/rtproc.py)
        self._rt = RealtimeThread(freeze_gc=freeze_gc, cpu=cpu, fifo=realtime_priority)
        self.cpp_plant = cpp_plant
        self._cpp_params: tuple = (None,)
        #: per row, monotonic ns: [tick or answer, integrated, state published, truth started, truth done]
        self._stamps: np.ndarray | None = None
        #: real time: row k's record and truth wait (bounded) until the answer to
        #: state k + 1 is in, so the command is handled as it arrives
        self._pending: tuple | None = None
        self._pending_by_ns = 0
        self._cmd_utime: dict[int, int] = {}  # state seq -> the answer's utime (controller's publish) [us]
        self._pub_wall_us: dict[int, int] = {}  # state seq -> its utime (our publish) [us]
        self._guidance_next: tuple | None = None  # guidance values of the next state, computed ahead
        self._next_published = -1
        self._guidance_sent: tuple = (-1, None)  # (seq, guidance values) of the newest state out
        #: real time: ticks that applied the answer to the state of the period just ended
        self.fresh_ticks = 0
        self.accept_faults = accept_fault_commands
        self.cmd_timeout, self.retries = cmd_timeout, retries
        self.stale_periods = (scn.controller.safety.stale_periods if stale_periods is None
                              else stale_periods)
        self.wait_status = wait_status
        #: the controllers' announcements and status senders (bus/peers.py):
        #: lockstep waits for a status only from a controller that sends them
        self.peers = ControllerPeers(wait_status)
        #: [s] wait this long for a first answer to state 0 before the run
        #: starts (a controller process still starting; None: no wait)
        self.start_timeout = start_timeout
        self.start_wait_s = 0.0  # [s] how long the first answer took (start_timeout)
        #: asked every step (and while waiting for a command): a reason to stop
        #: the run early (a signal, a dead logger), None to go on; a run stopped
        #: so is returned with the rows done and marked partial
        self.stop = stop
        self.stopped: str | None = None
        self.url = url
        self.counters: Counter = Counter()
        #: with auth_key every message carries an HMAC trailer; failures count as auth_failed (bus/auth.py)
        self.lc = open_bus(url, auth_key, self.counters)
        self.act = scn.actuators
        self._cmd: dict[int, Any] = {}  # state seq -> first valid command answering it
        self._cmd_rx: dict[int, int] = {}  # state seq -> monotonic ns of receipt
        self._status: dict[int, Any] = {}
        self._newest_cmd = None
        self._newest_cmd_ns = 0
        self._last_cmd_seq = -1
        self._last_status_seq = -1
        self._ctl_session: int | None = None
        self._ctl_last_ns = 0  # monotonic ns of the adopted controller's newest message
        self._peer_lost = False
        self._fault_fields: tuple = (None,)
        self._ch_state = channel("SCRT_STATE", prefix)
        self._ch_truth = channel("SCRT_TRUTH", prefix)
        self._ch_guidance = channel("SCRT_GUIDANCE", prefix)
        self._gaps: list[tuple[float, float]] = []
        self._gap_start: float | None = None
        self.session = secrets.randbits(62)
        #: a second bench on our URL and prefix stops the run, marked invalid (bus/collision.py)
        self.guard = CollisionGuard(url, prefix, self.session, alive_s=max(
            0.5, self.stale_periods / self.rate / time_scale))
        self.invalid: str | None = None
        self.guidance = GuidancePublisher(self.lc, self._ch_guidance, scn.core_config().guidance,
                                          self.rate, self.session)
        self._pub_ns: dict[int, int] = {}
        self._t_now = 0.0
        self.faults_applied: list[dict[str, Any]] = []
        # LCM silently drops messages beyond a subscription's queue capacity
        # (30 by default): hold many, so every one is either used or counted
        for name, handler in (("SCRT_CMD", self._on_cmd), ("SCRT_CTRL_STATUS", self._on_status),
                              ("SCRT_FAULT", self._on_fault), ("SCRT_CTRL_INFO", self._on_info),
                              ("SCRT_STATE", self._on_plant_state)):
            self.lc.subscribe(channel(name, prefix), handler).set_queue_capacity(100_000)

    # --- handlers: never raise -------------------------------------------
    def _collision(self, reason: str | None) -> None:
        if reason is not None and self.invalid is None:
            self.invalid = reason
            self.counters["bench_collision"] += 1
            if self.stopped is None:
                self.stopped = reason  # the loop stops at its next check: partial and invalid

    def _on_plant_state(self, _ch: str, data: bytes) -> None:
        """Our own states come back (multicast loopback); another plant's mean another bench."""
        if len(data) == _STATE_LAYOUT.size + 8 and data[:8] == _STATE_FP:
            _, seq, session = struct.unpack_from(">qqq", data, 8)
            if session != self.session:
                self._collision(self.guard.plant_state(session, seq, self._ctl_session))

    def _session_ok(self, session: int, now: int, seq: int = -1, kind: str = "cmd") -> bool:
        """Commands and status come from one controller session at a time; a
        new session is adopted only once the current controller is lost (the
        loop saw an unanswered state in lockstep or a stale command in real
        time: a crashed or restarted controller), never while it answers."""
        if session == self._ctl_session:
            self._ctl_last_ns = now
            return True
        if self._ctl_session is None or self._peer_lost:
            if self._ctl_session is not None:
                self.counters["controller_sessions_adopted"] += 1
            self._ctl_session = session
            self._ctl_last_ns = now
            self._peer_lost = False
            self._last_cmd_seq = -1
            self._last_status_seq = -1
            return True
        self.counters["foreign_session"] += 1
        self._collision(self.guard.controller_msg(session, seq, self._ctl_session, self._ctl_last_ns,
                                                  now, kind))
        return False

    def _on_cmd(self, _ch: str, data: bytes) -> None:
        now = time.monotonic_ns()
        self.counters["cmd_received"] += 1
        if len(data) == _CMD_SIZE and data[:8] == _CMD_FP:  # the fixed layout, unpacked at once
            v = _CMD_LAYOUT.unpack_from(data, 8)
            msg = _Cmd(seq=v[1], session=v[2], state_seq=v[3], u_cmd=v[5:9], u_sat=v[9:13],
                       mode=v[13], flags=v[14])
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
            self.counters["duplicate" if msg.seq == self._last_cmd_seq else "out_of_order"] += 1
            return
        self._last_cmd_seq = msg.seq
        self._newest_cmd, self._newest_cmd_ns = msg, now
        if msg.state_seq >= 0 and msg.state_seq not in self._cmd:
            self._cmd[msg.state_seq] = msg
            self._cmd_rx[msg.state_seq] = now
            if len(data) == _CMD_SIZE:
                self._cmd_utime[msg.state_seq] = v[0]

    def _on_status(self, _ch: str, data: bytes) -> None:
        # The loop needs only the header (session, seqs) now; the full decode
        # (~35 us in Python) waits until the run is over (_fill_status).
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
        self._last_status_seq = cmd_seq
        self.peers.saw_status(session)
        if state_seq >= 0 and state_seq not in self._status:
            self._status[state_seq] = data

    def _on_info(self, _ch: str, data: bytes) -> None:
        self.peers.on_info(data, self.counters)

    @property
    def controller_info(self) -> dict[str, Any] | None:
        """The controller_info_t of the session in use (None: none announced)."""
        return self.peers.info.get(self._ctl_session) if self._ctl_session is not None else None

    def _on_fault(self, _ch: str, data: bytes) -> None:
        msg = decode_as(sc_rt_lcm.fault_cmd_t, data, self.counters)
        if msg is None:
            return
        if not self.accept_faults:
            self.counters["fault_ignored"] += 1
            return
        try:
            self._apply_fault(msg)
            self.counters["fault_applied"] += 1
        except ValueError as e:
            self.counters["fault_rejected"] += 1
            self.faults_applied.append({"rejected": str(e), "wheel": msg.wheel})

    def _apply_fault(self, m) -> None:
        if not 1 <= m.wheel <= 4:
            raise ValueError(f"wheel must be 1..4, got {m.wheel}")
        w = m.wheel - 1
        others = tuple(f for f in self.act.faults if f.wheel != w)
        if m.action == sc_rt_lcm.fault_cmd_t.ACTION_CLEAR:
            new = others
            rec = {"t": self._t_now, "wheel": m.wheel, "action": "clear"}
        elif m.action == sc_rt_lcm.fault_cmd_t.ACTION_INJECT:
            onset = self._t_now if m.now else m.t_onset
            fault = WheelFault(wheel=w, effectiveness=m.effectiveness, bias=m.bias, onset=onset,
                               end=None if m.t_end < 0 else m.t_end, rate=m.rate, stuck=bool(m.stuck))
            new = others + (fault,)
            rec = {"t": self._t_now, "wheel": m.wheel, "action": "inject",
                   **{k: getattr(fault, k) for k in ("effectiveness", "bias", "onset", "end", "rate", "stuck")}}
        else:
            raise ValueError(f"unknown action {m.action}")
        self.act = dataclasses.replace(self.act, faults=new)  # validated by ActuatorParams
        self.faults_applied.append(rec)

    # --- publishing --------------------------------------------------------
    def _publish_state(self, k: int, t: float, x: np.ndarray, guidance: tuple | None = None) -> None:
        if guidance is None:  # computed now, or the values state k went out with (a re-sent state)
            guidance = self._guidance_sent[1] if self._guidance_sent[0] == k else self.guidance.values(t)
        self._guidance_sent = (k, guidance)
        self.guidance.publish(k, t, guidance)  # the reference first: a controller has it with the state
        utime = time.time_ns() // 1000
        data = _STATE_FP + _STATE_LAYOUT.pack(utime, k, self.session, t, *x[0:10])
        self._pub_wall_us.setdefault(k, utime)
        self._pub_ns[k] = time.monotonic_ns()
        self.lc.publish(self._ch_state, data)
        self._drain()  # our own guidance and state come back (loopback): handled while the controller works

    def _drain(self) -> None:
        """Handle what is already in the socket, without waiting."""
        fd = self.lc.fileno()
        while select.select([fd], [], [], 0)[0]:
            self.lc.handle()

    def _publish_truth(self, run, k, t, cmd_seq, u_cmd, accel, delta2, stale, act=None) -> None:
        act = self.act if act is None else act  # the faults row k was applied with
        if self._fault_fields[0] is not act:  # the fault set changed (live injection)
            faults = {f.wheel: f for f in act.faults}
            self._fault_fields = (
                act, [faults.get(i) for i in range(4)],
                [faults[i].effectiveness if i in faults else 1.0 for i in range(4)]
                + [faults[i].bias if i in faults else 0.0 for i in range(4)]
                + [1 if i in faults and faults[i].stuck else 0 for i in range(4)])
        _, per_wheel, eff_bias_stuck = self._fault_fields
        fault_y = [actuators.fault_Y(f, t) for f in per_wheel]
        data = _TRUTH_FP + _TRUTH_LAYOUT.pack(
            time.time_ns() // 1000, k, t, cmd_seq, *u_cmd, *accel, *delta2,
            *plant.disturbance(self.scn.plant, t), *fault_y, *eff_bias_stuck, 1 if stale else 0)
        self.lc.publish(self._ch_truth, data)
        run["fault_Y"][k] = fault_y
        run["fault_effectiveness"][k] = eff_bias_stuck[0:4]
        run["fault_bias"][k] = eff_bias_stuck[4:8]
        run["fault_stuck"][k] = eff_bias_stuck[8:12]

    def _handle_until(self, deadline_ns: int, spin_ns: int = 0) -> None:
        """Handle messages until ``deadline_ns``: asleep in ``select`` until
        ``spin_ns`` before it, then polling (a wake-up from sleep is late by
        the scheduler's latency; a poll is not)."""
        fd = self.lc.fileno()
        while True:
            if self._pending is not None and (self._next_published in self._cmd
                                              or time.monotonic_ns() >= self._pending_by_ns):
                self._flush_pending()  # the answer is in (or half a period passed): now the truth
            rem = deadline_ns - time.monotonic_ns()
            if rem <= 0:
                self._drain()  # what is already there, without waiting
                return
            wait = rem - spin_ns
            if self._pending is not None:  # wake for the deferred truth at the latest
                wait = min(wait, self._pending_by_ns - time.monotonic_ns())
            if select.select([fd], [], [], wait / 1e9 if wait > 0 else 0)[0]:
                self.lc.handle()

    def _should_stop(self) -> bool:
        if self.stopped is None and self.stop is not None:
            self.stopped = self.stop()
        return self.stopped is not None

    # --- the loops -----------------------------------------------------------
    def run(self) -> Run:
        """The whole run; returns its record (metrics are the caller's:
        ``sc_rt.results.metrics.finish_run``)."""
        if self.start_timeout is not None:
            self._await_controller(initial_state(self.scn))
        with self._rt:
            if self.mode == "lockstep":
                return self._run_lockstep()
            return self._run_realtime()

    @property
    def scheduler(self) -> str:
        """What the emulator's thread got (bus/rtproc.py)."""
        return self._rt.description

    def breakdown(self) -> dict[str, Any]:
        """Where each row's microseconds went (bus/loopstats.py)."""
        return loop_breakdown(self._stamps, self.mode, self._cmd_utime, self._pub_wall_us, self._cmd_rx,
                              self._pub_ns)

    def _await_controller(self, x0: np.ndarray) -> None:
        """Re-send state 0 until a controller answers it (raises RuntimeError
        after ``start_timeout`` s): a process that is still starting, or one
        a person starts by hand, gets the run from its first state."""
        t_start = time.monotonic_ns()
        end = t_start + int(self.start_timeout * 1e9)
        while 0 not in self._cmd:
            now = time.monotonic_ns()
            if now >= end:
                raise RuntimeError(f"no controller answered the first state within {self.start_timeout:g} s")
            self.counters["start_state_sent"] += 1
            self._publish_state(0, 0.0, x0)
            resend = min(end, now + 100_000_000)
            while 0 not in self._cmd and time.monotonic_ns() < resend:
                if self._should_stop():
                    return  # the run loop ends at once, with no rows
                self.lc.handle_timeout(20)
        self.start_wait_s = (time.monotonic_ns() - t_start) / 1e9

    def _allocate(self, n: int) -> Run:
        return Run.allocate(n, RunMeta.of_scenario(self.scn, f"hil-{self.mode}", mode=self.mode))

    @staticmethod
    def _record(run, k, t, x, cmd, u_cmd, u_sat_ctrl, accel, delta2) -> None:
        run["t"][k] = t
        run["sigma_BN"][k] = x[0:3]
        run["omega_BN_B"][k] = x[3:6]
        run["wheel_speed"][k] = x[6:10]
        run["u_cmd"][k] = u_cmd
        run["u_sat"][k] = u_sat_ctrl
        run["wheel_accel"][k] = accel
        run["delta2"][k] = delta2
        run["cmd_stale"][k] = cmd is None
        if cmd is not None:
            run["cmd_seq_applied"][k] = cmd.seq
            run["flags"][k] = cmd.flags
            run["ctrl_mode"][k] = cmd.mode

    def _fill_status(self, run: Run) -> None:
        """The controller's telemetry and timing for every state it answered."""
        for k in range(len(run)):
            raw = self._status.get(k)
            if raw is None:
                continue
            s = sc_rt_lcm.controller_status_t.decode(raw)
            for name in STATUS_RUN_FIELDS + STATUS_TIMING_FIELDS:
                run[name][k] = getattr(s, name)
        lat = run["latency_us"]
        for k in range(len(run)):
            if k in self._cmd_rx and k in self._pub_ns:
                lat[k] = (self._cmd_rx[k] - self._pub_ns[k]) / 1e3

    def _run_lockstep(self) -> Run:
        scn = self.scn
        n_ctrl, n_sub, h, rate = grid(scn)
        traj = self._allocate(n_ctrl + 1)
        self._stamps = stamps = np.zeros((n_ctrl + 1, 5), np.int64)
        x = initial_state(scn)
        rows = 0
        silent = 0  # consecutive states without an answer
        self._next_published = -1  # the state _apply published already (the state first)
        for k in range(n_ctrl + 1):
            t = k / rate
            self._t_now = t
            cmd = None
            # a silent peer (crashed controller) gets one short wait per state
            # instead of the full timeout and retries: the run goes on under
            # the watchdog and resumes when a controller answers again
            timeout = self.cmd_timeout if silent == 0 else min(self.cmd_timeout, 0.05)
            retries = self.retries if silent == 0 else 0
            for attempt in range(retries + 1):
                if attempt:
                    self.counters["state_resent"] += 1
                if attempt or self._next_published != k:
                    self._publish_state(k, t, x)
                if attempt == 0 and k < n_ctrl:  # the next state's guidance while the controller works
                    self._guidance_next = self.guidance.values((k + 1) / rate)
                deadline = time.monotonic_ns() + int(timeout * 1e9)
                while time.monotonic_ns() < deadline and not self._should_stop():
                    cmd = self._cmd.get(k)
                    if cmd is not None and (k in self._status or not self.peers.wants_status(cmd.session)):
                        break
                    rem_ms = max(1, (deadline - time.monotonic_ns()) // 1_000_000)
                    try:
                        self.lc.handle_timeout(int(min(rem_ms, 100)))
                    except OSError:  # EINTR: a signal (self.stop decides), within the deadline
                        continue
                cmd = self._cmd.get(k)
                if cmd is not None or self.stopped:
                    break
            if self.stopped:  # row k was not applied: the run ends with row k - 1
                break
            stale = cmd is None
            silent = silent + 1 if stale else 0
            if stale:
                # watchdog: no answer to this state: apply zero, flag, go on
                self.counters["cmd_timeout"] += 1
            stamps[k, 0] = time.monotonic_ns()
            x = self._apply(traj, k, t, x, cmd, n_sub, h, None if k == n_ctrl else (k + 1, (k + 1) / rate),
                            stamps[k])
            rows = k + 1
            if k == n_ctrl or x is None or self._should_stop():
                break
        return self._finish(traj, rows, x is None and rows < n_ctrl + 1)

    def _run_realtime(self) -> Run:
        scn = self.scn
        n_ticks, n_sub, h, rate = grid(scn)
        period = 1.0 / rate
        wall_period_ns = int(round(period / self.time_scale * 1e9))
        stale_ns = int(self.stale_periods * wall_period_ns)
        traj = self._allocate(n_ticks + 1)
        self._stamps = stamps = np.zeros((n_ticks + 1, 5), np.int64)
        defer_ns = wall_period_ns // 2  # a row's truth waits at most half a period for the answer
        x = initial_state(scn)
        lateness = traj["tick_lateness_us"]
        rows = 0
        self._publish_state(0, 0.0, x)
        start = time.monotonic_ns()
        spin = self._spin_ns
        for k in range(n_ticks + 1):
            t = k * period
            self._t_now = t
            deadline = start + (k + 1) * wall_period_ns
            # the next state's guidance while there is time (it needs no command)
            self._guidance_next = (self.guidance.values((k + 1) * period) if k < n_ticks else None)
            self._handle_until(deadline, spin)
            now = time.monotonic_ns()
            stamps[k, 0] = now
            lateness[k] = (now - deadline) / 1e3
            cmd = self._newest_cmd
            if cmd is None or now - self._newest_cmd_ns > stale_ns:
                self.counters["cmd_stale_ticks"] += 1
                cmd = None
            elif cmd.state_seq == k:  # computed from the state of the period that just ended
                self.fresh_ticks += 1
            x = self._apply(traj, k, t, x, cmd, n_sub, h, None if k == n_ticks else (k + 1, (k + 1) * period),
                            stamps[k], defer_ns=defer_ns)
            rows = k + 1
            if k == n_ticks or x is None or self._should_stop():
                break
        return self._finish(traj, rows, x is None and rows < n_ticks + 1)

    def _integrate(self, t: float, x: np.ndarray, u_cmd: np.ndarray, n_sub: int, h: float) -> np.ndarray:
        """n_sub RK4 steps of h from t with u_cmd held: the C++ twin (bitwise
        the Python reference) or model.plant.rk4_step."""
        if not self.cpp_plant:
            for j in range(n_sub):
                x = plant.rk4_step(self.scn.plant, self.act, t + j * h, x, h, u_cmd)
            return x
        if self._cpp_params[0] is not self.act:  # the fault set changed (live injection)
            self._cpp_params = (self.act, plant.plant_params_to_cpp(self.scn.plant),
                                actuators.actuator_params_to_cpp(self.act))
        _, pp, ap = self._cpp_params
        xs = _core.PlantState.from_vector(x)
        for j in range(n_sub):
            xs = _core.plant_rk4_step(pp, ap, t + j * h, xs, h, u_cmd)
        return xs.to_vector()

    def _apply(self, traj, k: int, t: float, x: np.ndarray, cmd, n_sub: int, h: float,
               next_state: tuple[int, float] | None = None, stamps=None, defer_ns: int | None = None):
        """Row k: apply ``cmd`` (None: the watchdog's zero) over one control
        period; publish the next state (``next_state``: its seq and t; not when
        the run stops or diverged) first, then record row k with the truth at t and publish the
        truth. ``stamps``: the row's monotonic ns (integrated, state out, truth
        out) go to stamps[1:5]. ``defer_ns``: the record and the truth wait
        until the answer to the next state is in, at most this long
        (``_handle_until``). Returns the next state, or None when it is not
        finite."""
        stale = cmd is None
        self._peer_lost = stale
        if stale:
            u_cmd, u_sat_ctrl, cmd_seq = np.zeros(4), np.zeros(4), -1
            if self._gap_start is None:
                self._gap_start = t
        else:
            u_cmd, u_sat_ctrl, cmd_seq = np.array(cmd.u_cmd), np.array(cmd.u_sat), cmd.seq
            if self._gap_start is not None:
                self._gaps.append((self._gap_start, t))
                self._gap_start = None
        act = self.act  # the row's faults (a handler may change self.act only while we wait)
        x_next = self._integrate(t, x, u_cmd, n_sub, h)
        finite = bool(np.all(np.isfinite(x_next)))
        if stamps is not None:
            stamps[1] = time.monotonic_ns()
        if next_state is not None and finite and not self._should_stop():
            self._t_now = next_state[1]  # what arrives from now on arrives during the next row
            guidance, self._guidance_next = self._guidance_next, None
            self._publish_state(next_state[0], next_state[1], x_next, guidance)
            self._next_published = next_state[0]
        if stamps is not None:
            stamps[2] = time.monotonic_ns()
        if self._pending is not None:  # a late tick: the previous row's record and truth first, never lost
            self._flush_pending()
        self._pending = (traj, k, t, x, cmd, u_cmd, u_sat_ctrl, cmd_seq, stale, act, stamps)
        if defer_ns is None or next_state is None or not finite:
            self._flush_pending()
        else:
            self._pending_by_ns = time.monotonic_ns() + defer_ns
        return x_next if finite else None

    def _flush_pending(self) -> None:
        """The deferred part of a row: its record and its truth."""
        traj, k, t, x, cmd, u_cmd, u_sat_ctrl, cmd_seq, stale, act, stamps = self._pending
        self._pending = None
        if stamps is not None:
            stamps[3] = time.monotonic_ns()
        if self.cpp_plant:  # the C++ twins (bitwise the Python functions below)
            if self._cpp_params[0] is not act:
                self._cpp_params = (act, plant.plant_params_to_cpp(self.scn.plant),
                                    actuators.actuator_params_to_cpp(act))
            _, pp, ap = self._cpp_params
            w = _core.wheel_accel(ap, t, u_cmd, x[6:10])
            u_sat, accel = w.u_sat, w.accel
            delta2 = _core.lumped_disturbance(pp, t, _core.PlantState.from_vector(x), u_sat, accel)
        else:
            u_sat, accel, _ = actuators.wheel_accel(act, t, u_cmd, x[6:10])
            delta2 = plant.lumped_disturbance(self.scn.plant, t, x, u_sat, accel)
        self._record(traj, k, t, x, cmd, u_cmd, u_sat_ctrl, accel, delta2)
        self._drain()  # an answer that came meanwhile is received now, not after the truth's publish
        self._publish_truth(traj, k, t, cmd_seq, u_cmd, accel, delta2, stale, act)
        if stamps is not None:
            stamps[4] = time.monotonic_ns()

    def _finish(self, run: Run, rows: int, diverged: bool) -> Run:
        if self._pending is not None:
            self._flush_pending()
        if self._gap_start is not None and rows > 0:
            self._gaps.append((self._gap_start, float(run["t"][rows - 1])))
            self._gap_start = None
        # let the last status arrive
        self._handle_until(time.monotonic_ns() + 20_000_000)
        run = run.head(rows)
        self._fill_status(run)
        run.counters = dict(self.counters)
        run.gaps = list(self._gaps)
        run.faults_applied = list(self.faults_applied)
        run.diverged = diverged
        label = self.peers.label(self._ctl_session)  # the law's name, as the controller announced it
        if label is None and self._ctl_session is not None and self._ctl_session not in self.peers.status_sessions:
            label = "external"  # commands only: not sc-rt-controller, and no name announced
        if label:
            run.meta = dataclasses.replace(run.meta, law=label)
        if self.stopped is not None:
            run.partial = True
            run.message = self.stopped
            run.metrics.update(stopped=self.stopped, t_reached_s=float(run["t"][rows - 1]) if rows else None)
        run.metrics.update(provenance(self.session, self._ctl_session, self.invalid))
        return run
