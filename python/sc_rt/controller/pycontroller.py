"""``sc-rt controller --law module:Class``: a Python law as a real LCM
controller process, for prototyping at 10-100 Hz.

The same shell as sc-rt-controller (cpp/app/controller_shell.cpp), with the
C++ shell's policy through the bindings: ``_core.InputGate`` (session
adoption, duplicates, order, rejection counters), ``_core.PhaseLock``
(real-time deadlines phase-locked to the state arrivals) and, for a scenario
with [sensors], ``_core.SensorIntake`` (the emulator's sensor messages into
the core's estimator). Two modes:

- lockstep: one command per state, on arrival, answering its seq; a re-sent
  state (a duplicate) is answered again with the same command;
- realtime, with the trigger it is given (``--trigger``, as sc-rt-controller):
  ``event`` (the default) steps on each state's arrival and publishes at
  once; ``timer`` wakes on its own deadlines at the control rate
  (``PhaseLock``), uses the newest state (stale after ``stale_periods``
  periods: SAFE zero command), publishes.

``--realtime-priority`` asks for SCHED_FIFO 80 for the thread that reads the
bus and steps (the process's main thread) and ``mlockall``, and falls back
to SCHED_OTHER with a warning where that is not permitted; ``--cpu N`` pins
it. The summary says what it got (``scheduler``) and which trigger ran
(``trigger``), so timing.json never guesses.

With magnetic control it takes each state's field and sends the rods'
commands just before each wheel command (controller/maglink.py).

It publishes wheel_cmd_t and controller_status_t per step, announces itself
with controller_info_t (at start and at each new plant session), and writes
the exit summary with the C++ process's keys (controller_summary.json). The
law runs inside the core's ``Controller`` (sc_rt.pylaw registers it), the
same controller as every other law's, so a lockstep run equals
``sc-rt sim --law module:Class`` to the last bit, with sensors too.
"""

from __future__ import annotations

import json
import secrets
import select
import signal
import sys
import time
from collections import Counter
from typing import Any

import sc_rt_lcm

from sc_rt import _core
from sc_rt.wire.auth import open_bus
from sc_rt.wire.lcmio import channel
from sc_rt.results.record.fields import packed_layout
from sc_rt.controller.maglink import MagLink
from sc_rt.wire.codec import STATUS_NAV_FIELDS, STATUS_RUN_FIELDS, decode_as

__all__ = ["PyControllerProcess", "STEP_PRIORITY", "nearest_rank", "setup_scheduler", "write_summary"]

#: SCHED_FIFO priority of the stepping thread, as sc-rt-controller's step thread
STEP_PRIORITY = 80
_MCL_CURRENT, _MCL_FUTURE = 1, 2

#: the estimator's telemetry (_core.SensorIntake.measure's) by name
_NAV: dict[str, slice] = packed_layout(_core.NAV_FIELDS, _core.NAV_SIZE)

_STATE_SIZE = len(sc_rt_lcm.plant_state_t().encode())
_V = _core.GateVerdict


def setup_scheduler(want_rt: bool, cpu: int | None) -> str:
    """The calling thread's scheduling, as sc-rt-controller's
    ``setup_scheduler``: pinned to ``cpu`` (None: anywhere); with
    ``want_rt`` SCHED_FIFO ``STEP_PRIORITY`` and ``mlockall``, each falling
    back with a warning on stderr where it is not permitted. Returns what it
    got ("SCHED_OTHER", "SCHED_FIFO 80 + mlockall, CPU 1", "SCHED_OTHER
    (SCHED_FIFO denied)", ...)."""
    import ctypes
    import errno
    import os

    pin = ""
    if cpu is not None:
        try:
            os.sched_setaffinity(0, {cpu})
            pin = f", CPU {cpu}"
        except OSError as e:
            print(f"sc-rt controller: warning: cannot pin to CPU {cpu} ({e.strerror})", file=sys.stderr)
    if not want_rt:
        return "SCHED_OTHER" + pin
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(STEP_PRIORITY))
        got = f"SCHED_FIFO {STEP_PRIORITY}"
    except OSError as e:
        print(f"sc-rt controller: warning: SCHED_FIFO not permitted ({e.strerror}): running SCHED_OTHER",
              file=sys.stderr)
        got = "SCHED_OTHER (SCHED_FIFO denied)"
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.mlockall(_MCL_CURRENT | _MCL_FUTURE) == 0:
        got += " + mlockall"
    else:
        print(f"sc-rt controller: warning: mlockall not permitted ({os.strerror(ctypes.get_errno() or errno.EPERM)})",
              file=sys.stderr)
    return got + pin


def nearest_rank(v: list[float]) -> dict[str, float]:
    """p50, p99 and max as the C++ controller computes them (nearest rank)."""
    if not v:
        return {"p50": 0.0, "p99": 0.0, "max": 0.0}
    s = sorted(v)

    def q(p: float) -> float:
        return s[min(len(s) - 1, int(p * (len(s) - 1) + 0.5))]

    return {"p50": round(q(0.5), 3), "p99": round(q(0.99), 3), "max": round(s[-1], 3)}


class PyControllerProcess:
    def __init__(self, config, *, url: str, prefix: str = "", mode: str = "lockstep",
                 max_steps: int | None = None, phase_offset_us: float = 50.0,
                 auth_key: bytes | None = None, nav: tuple | None = None, trigger: str = "event",
                 realtime_priority: bool = False, cpu: int | None = None):
        """``config``: a ControllerConfig whose law is registered (sc_rt.pylaw.register);
        ``nav``: (enabled, use_estimate, MekfParams, sigma0, mag_R_SB) of _core.nav_from_config_bytes;
        ``trigger``: real time, "event" (a step on each state's arrival) or
        "timer" (its own phase-locked deadlines); ``realtime_priority``,
        ``cpu``: the stepping thread's scheduling (``setup_scheduler``)."""
        if mode not in ("lockstep", "realtime"):
            raise ValueError(f"--mode must be lockstep or realtime, got {mode!r}")
        if trigger not in ("event", "timer"):
            raise ValueError(f"--trigger must be event or timer, got {trigger!r}")
        self.trigger, self.realtime_priority, self.cpu = trigger, realtime_priority, cpu
        self.scheduler = "SCHED_OTHER"
        self.ctl = _core.Controller(config)
        self.ctl.prepare()  # the guidance's period table now, not in a step (docs/CORE.md, the time contract)
        self.config = config
        self.intake = (_core.SensorIntake(nav[2], bool(nav[1]), nav[3]) if nav is not None and nav[0]
                       else None)
        if self.intake is not None and len(nav) > 4 and nav[4] is not None:
            self.intake.mount_magnetometer(nav[4])  # [sensors.magnetometer]: its samples give the field
        self._nav_tel = None
        self.realtime = mode == "realtime"
        # a step per state on its arrival: lockstep, and real time with the event trigger
        self.on_arrival = not self.realtime or trigger == "event"
        self.mode, self.prefix, self.max_steps = mode, prefix, max_steps
        self.phase_offset_us = phase_offset_us
        self.period_ns = int(round(1e9 / config.control_rate_hz))
        self.stale_ns = int(config.safety.stale_periods * self.period_ns)
        self.gate = _core.InputGate(_core.InputGate.session_timeout_for(self.stale_ns))
        self.session = secrets.randbits(62)
        self.plant_sessions: list[int] = []
        self.cnt: Counter = Counter()
        self.lc = open_bus(url, auth_key, self.cnt)  # with a key: auth_failed in cnt (wire/auth.py)
        self.auth = auth_key is not None
        self.url = url
        self.lat: list[float] = []
        self.comp: list[float] = []
        self.age: list[float] = []
        self._state = None
        self._fresh = self._reengage = False
        self._announced: int | None = None
        self._last = None  # the last _core.Command
        self._last_flags = 0
        self._stale_hold = False
        self._used_fresh, self._used_rx = False, 0
        self._cmd_seq = 0
        self.stop = False
        self._ch_cmd, self._ch_status = channel("SCRT_CMD", prefix), channel("SCRT_CTRL_STATUS", prefix)
        self._ch_info = channel("SCRT_CTRL_INFO", prefix)
        self.lc.subscribe(channel("SCRT_STATE", prefix), self._on_state).set_queue_capacity(100_000)
        #: magnetic control: the field in, the rods' commands out (controller/maglink.py)
        self.mag = (MagLink(config.magnetic.rods.G_B.shape[1], self.cnt, self.intake)
                    if config.magnetic.active() else None)
        self._ch_rod = channel("SCRT_ROD_CMD", prefix)
        if self.mag is not None:
            self.lc.subscribe(channel("SCRT_MAG", prefix), self.mag.on_mag).set_queue_capacity(100_000)
        if self.intake is not None:  # [sensors]: the estimator runs here, as in sc-rt-controller
            for name, cls, offer in (("SCRT_GYRO", sc_rt_lcm.gyro_t, self._gyro),
                                     ("SCRT_STAR", sc_rt_lcm.star_tracker_t, self._star),
                                     ("SCRT_TACH", sc_rt_lcm.tachometer_t, self._tach)):
                self.lc.subscribe(channel(name, prefix), self._on_sensor(cls, offer)).set_queue_capacity(100_000)

    def _on_sensor(self, cls, offer):
        def handle(_ch: str, data: bytes) -> None:
            msg = decode_as(cls, data, Counter())
            if msg is None:
                self.intake.malformed()
            else:
                offer(msg)
        return handle

    def _gyro(self, m) -> None:
        self.intake.offer_gyro(m.session, m.seq, m.t, list(m.omega), m.output)

    def _star(self, m) -> None:
        self.intake.offer_star(m.session, m.seq, m.t_exposure, m.t_delivery, list(m.sigma_BN))

    def _tach(self, m) -> None:
        self.intake.offer_tach(m.session, m.seq, m.t, list(m.wheel_speed))

    # --- input --------------------------------------------------------------
    def _on_state(self, _ch: str, data: bytes) -> None:
        now = time.monotonic_ns()
        bad: Counter = Counter()
        msg = decode_as(sc_rt_lcm.plant_state_t, data, bad)
        if msg is None:
            (self.gate.trailing_bytes if bad["trailing_bytes"] else self.gate.malformed)()
            return
        m = _core.Measurement(msg.t, list(msg.sigma_BN), list(msg.omega_BN_B), list(msg.wheel_speed))
        valid = _core.measurement_valid(m, self.config.safety)
        v = self.gate.offer(now, msg.session, msg.seq, valid)
        if v == _V.Duplicate:
            # lockstep: the plant re-sent a state it had no answer to: answer again
            if not self.realtime and self._last is not None:
                self._publish(self._last, self._last_flags, msg.seq, 0.0, 0.0, 0.0)
            return
        if v not in (_V.Accept, _V.Adopt):
            return
        if v == _V.Adopt:
            self._reengage = True  # a restarted plant: start the law afresh
        # the plant sessions followed, in order (the bench checks they are its own), as sc-rt-controller
        if (not self.plant_sessions or self.plant_sessions[-1] != msg.session) and len(self.plant_sessions) < 16:
            self.plant_sessions.append(msg.session)
        if msg.session != self._announced:
            self._announced = msg.session
            self.announce()
        if self.intake is not None:
            self.intake.use(msg.session, msg.t)  # its sensor samples up to msg.t feed the estimator
        self._state = (msg.seq, msg.t, m, msg.session)
        self._fresh = True
        if self.on_arrival:  # lockstep, or real time event-triggered: at once
            self.step(now, now)

    # --- one step -------------------------------------------------------------
    def step(self, now: int, deadline: int) -> None:
        t_start = time.monotonic_ns()
        have, fresh, rx = self.gate.have_state, self._fresh, self.gate.last_rx_ns
        self._fresh = False
        st = self._state
        nav_ready, m = True, st[2] if have else None
        if self.intake is not None and have and fresh:  # the estimate at the state's time
            nav_ready = not self.intake.use_estimate or self.intake.ready
            if nav_ready:
                m, self._nav_tel = self.intake.measure(st[2])
        stale = not have or (self.realtime and t_start - rx > self.stale_ns)
        if stale:
            cmd = self.ctl.safe_command(st[1] if have else 0.0, _core.FLAG_STALE_STATE)
            self.cnt["stale_steps"] += 1
            self.cnt["safe_steps"] += 1
        elif not fresh:  # real time, no new state yet: hold the last command
            self.cnt["stale_steps"] += 1
            cmd = self._last
            self._stale_hold = True
        elif not nav_ready:  # estimate mode, no attitude yet: SAFE until the first fix
            cmd = self.ctl.safe_command(st[1], _core.FLAG_NAV_DEGRADED)
            self.cnt["safe_steps"] += 1
            self._reengage = True
        else:
            if self._reengage:
                self._reengage = False
                self.ctl.reset(m)
            cmd = self.ctl.step(m, self.mag.field_for(st[3], st[1])) if self.mag else self.ctl.step(m)
            if cmd.mode == _core.MODE_SAFE:
                self.cnt["safe_steps"] += 1
        self._used_fresh, self._used_rx = fresh and not stale, rx
        age_us = (t_start - rx) / 1e3 if have else 0.0
        t_end = time.monotonic_ns()
        flags = cmd.flags | (_core.FLAG_STALE_STATE if self._stale_hold else 0)
        self._stale_hold = False
        self._last = cmd
        comp_us, late_us = (t_end - t_start) / 1e3, (now - deadline) / 1e3
        self.cnt["steps"] += 1
        used_seq = st[0] if have else -1
        self._publish(cmd, flags, used_seq, late_us, comp_us, age_us)
        if self.realtime and time.monotonic_ns() > deadline + self.period_ns:
            self.cnt["deadline_misses"] += 1
        self.lat.append(late_us)
        self.comp.append(comp_us)
        self.age.append(age_us)
        if self.max_steps is not None and self.cnt["steps"] >= self.max_steps:
            self.stop = True

    # --- output ---------------------------------------------------------------
    def announce(self) -> None:
        m = sc_rt_lcm.controller_info_t()
        m.utime, m.session = time.time_ns() // 1000, self.session
        m.protocol = sc_rt_lcm.controller_info_t.PROTOCOL_VERSION
        m.sends_status, m.law = True, self.ctl.law_name
        m.description = f"sc-rt controller (Python law {self.config.law})"
        self.lc.publish(self._ch_info, m.encode())

    def _publish(self, cmd, flags: int, state_seq: int, late_us: float, comp_us: float, age_us: float) -> None:
        self._last_flags = flags
        if self.mag is not None:  # the rods' command just before the wheel command it goes with (same seq)
            self.lc.publish(self._ch_rod, self.mag.rod_msg(cmd, self._cmd_seq, self.session, state_seq).encode())
        c = sc_rt_lcm.wheel_cmd_t()
        c.utime, c.seq, c.session, c.state_seq = time.time_ns() // 1000, self._cmd_seq, self.session, state_seq
        c.t, c.u_cmd, c.u_sat = cmd.t, cmd.u_cmd.tolist(), cmd.u_sat.tolist()
        c.mode, c.flags = cmd.mode, flags
        self.lc.publish(self._ch_cmd, c.encode())
        s = sc_rt_lcm.controller_status_t()
        s.utime, s.cmd_seq, s.session, s.state_seq, s.t = c.utime, self._cmd_seq, self.session, state_seq, c.t
        s.law, s.mode, s.flags = self.ctl.law_code, c.mode, flags  # a Python law: -1 (its name: controller_info_t)
        # the status-to-run table (wire/codec.py), read backwards: the Command's fields of those names
        # (translate.cpp's fill_status, whose twin this is), and the command itself
        for name in STATUS_RUN_FIELDS + ("u_cmd", "u_sat"):
            v = getattr(cmd, name)
            setattr(s, name, float(v) if isinstance(v, (int, float)) else [float(x) for x in v])
        s.n_telemetry = len(self.ctl.telemetry_names)
        s.wake_lateness_us, s.compute_us, s.state_age_us = late_us, comp_us, age_us
        s.steps, s.deadline_misses = self.cnt["steps"], self.cnt["deadline_misses"]
        s.stale_states, s.rejected = self.cnt["stale_steps"], self.gate.counts().rejected
        if self.intake is not None:
            tel = self._nav_tel
            s.nav = True
            if tel is not None:  # fill_nav_status's twin: the status fields of the run's names
                for name in STATUS_NAV_FIELDS:
                    v = tel[_NAV[name]]
                    setattr(s, name, float(v[0]) if v.size == 1 else v.tolist())
                s.nav_flags = int(tel[_NAV["nav_flags"]][0])
            c_ = self.intake.counts()
            s.gyro_used, s.star_used, s.tach_used = (int(v) for v in c_.used)
            s.sensor_rejected = c_.rejected
        self.lc.publish(self._ch_status, s.encode())
        self._cmd_seq += 1

    # --- the loops ------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self._on_signal)
        self.announce()
        self.scheduler = setup_scheduler(self.realtime_priority, self.cpu)
        print(f"sc-rt controller: {self.mode} mode on {self.url}, law {self.ctl.law_name}, {self.scheduler}"
              + (", event-triggered" if self.realtime and self.trigger == "event" else ""),
              file=sys.stderr, flush=True)
        if self.on_arrival:  # one step per state, on its arrival
            while not self.stop:
                self._handle(100)
        else:
            fd = self.lc.fileno()
            lock = _core.PhaseLock(self.period_ns, self.phase_offset_us, time.monotonic_ns())
            while not self.stop:
                deadline = lock.deadline
                while not self.stop:
                    rem = (deadline - time.monotonic_ns()) / 1e9
                    if rem <= 0:
                        break
                    if select.select([fd], [], [], rem)[0]:
                        self._handle()
                if self.stop:
                    break
                # what arrived by the deadline is in (handled on arrival)
                while select.select([fd], [], [], 0)[0] and not self.stop:
                    self._handle()
                self.step(time.monotonic_ns(), deadline)
                lock.advance(self._used_fresh, self._used_rx, time.monotonic_ns())
        return self.summary()

    def _handle(self, timeout_ms: int | None = None) -> None:
        try:  # a signal interrupts LCM's wait (EINTR: OSError; the handler runs just after)
            self.lc.handle() if timeout_ms is None else self.lc.handle_timeout(timeout_ms)
            self._errors = 0
        except OSError:
            self._errors = getattr(self, "_errors", 0) + 1
            if self._errors > 100:  # not a signal: LCM itself fails
                raise

    def _on_signal(self, _signum, _frame) -> None:
        self.stop = True

    def summary(self) -> dict[str, Any]:
        g = self.gate.counts()
        counts = self.ctl.counts
        return {"mode": self.mode, "control_rate_hz": 1e9 / self.period_ns, "law": self.ctl.law_name,
                "steps": self.cnt["steps"], "deadline_misses": self.cnt["deadline_misses"],
                "scheduler": self.scheduler, "wake_lateness_us": nearest_rank(self.lat),
                "compute_us": nearest_rank(self.comp), "state_age_us": nearest_rank(self.age),
                "received": g.received, "stale_states": self.cnt["stale_steps"],
                "safe_steps": self.cnt["safe_steps"],
                "trigger": self.trigger, "null_law": False,  # the trigger it was given, and ran
                "law_failures": self.ctl.law_failures,
                "time_jumps": {"ahead": counts.jumps_ahead, "back": counts.steps_back},
                "auth": self.auth, "auth_failed": self.cnt["auth_failed"],
                "rejected": {k: g.as_dict()[k] for k in ("malformed", "trailing_bytes", "duplicate",
                                                         "out_of_order", "invalid_state", "foreign_session",
                                                         "seq_jump")},
                "sessions_adopted": g.sessions_adopted, "plant_sessions": list(self.plant_sessions),
                **({"magnetic": self.mag.summary()} if self.mag is not None else {})}


def write_summary(summary: dict[str, Any], path: str | None) -> None:
    text = json.dumps(summary)
    print(text, flush=True)
    if path:
        with open(path, "w") as f:
            f.write(text + "\n")
