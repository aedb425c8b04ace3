"""The plant as an LCM process (``sc-rt emulator``).

Publishes ``guidance_t`` (SCRT_GUIDANCE, the reference, just before each
state), ``plant_state_t`` (SCRT_STATE) and ``plant_truth_t`` (SCRT_TRUTH),
applies the newest valid ``wheel_cmd_t`` it holds (zero-order hold), with the
scenario's saturation and faults (and those injected live: ``fault_cmd_t``,
``rod_fault_cmd_t``, from the row they arrive in), and records the run
(docs/PROTOCOL.md).

- lockstep: publish state k, wait for the command answering k (and the
  controller's status for k from a controller that sends them: emulator/peers.py),
  apply it over one control period. The same loop and arithmetic as
  ``sim.simulate(engine="python")``: same numbers.
- realtime: a tick every 1/rate s of wall clock divided by the time scale;
  at each tick the newest command is applied over the next period; commands
  older than ``stale_periods`` periods, or invalid, are replaced by zero and
  flagged (watchdog).

Both loops publish the next state first, then the truth of the row just
applied (the controller computes while the emulator records), integrate with
the C++ plant twin (bitwise the Python model; ``cpp_plant=False`` runs the
Python one: emulator/twin.py), and run with the garbage collector frozen
(emulator/rtproc.py). Real time sleeps in ``select`` until ``spin_us`` before
the tick and polls from there.

A row (the command applied, the next state out first, then the record and
the truth, deferred in real time) is emulator/rows.py; the publishing side
(guidance, state, truth, the sensors' samples) emulator/outbox.py; the
receive side emulator/receiver.py, the handlers (bad input never stops the
loop: every message is decoded under guard and counted by kind,
``counters``), and emulator/inbox.py, per state seq, the commands, statuses
and publish times. The rows go into the run's record, emulator/record.py:
two chunks of rows allocated when the emulator is made, the older rows
written to disk as the run goes, so that its memory stays flat however long
the run lasts.
"""

from __future__ import annotations

import dataclasses
import math
import secrets
import select
import time
from collections import Counter
from typing import Any, Callable

import numpy as np

from sc_rt.wire.auth import open_bus
from sc_rt.emulator.collision import CollisionGuard
from sc_rt.emulator.receiver import Receiver
from sc_rt.emulator.logpace import LogPace
from sc_rt.emulator.record import BYTES_PER_ROW, Record
from sc_rt.emulator.outbox import Publisher
from sc_rt.emulator.state import Options, Shared
from sc_rt.wire.lcmio import channel
from sc_rt.emulator.peers import ControllerPeers, GuidancePublisher
from sc_rt.emulator.rows import RowPipeline
from sc_rt.emulator.rtproc import RealtimeThread
from sc_rt.emulator.sensorpub import SensorPublisher
from sc_rt.emulator.twin import PlantTwin, RodHold
from sc_rt.results.record.run import Run, RunMeta, provenance
from sc_rt.scenario.model import Scenario
from sc_rt.scenario.overrides import grid, initial_state, with_overrides

__all__ = ["Emulator", "Options", "BYTES_PER_ROW", "ROD_GRACE_NS"]

#: [ns] lockstep: how long the rods' command of a state may trail its wheel command
ROD_GRACE_NS = 50_000_000

class Emulator:
    """The plant process: the loops (lockstep, real time) over its parts,
    the receiver (emulator/receiver.py), the publisher (emulator/outbox.py),
    the plant twin (emulator/twin.py) and the sensors, which share only
    ``shared`` (emulator/state.py)."""

    def __init__(self, scn: Scenario, opts: Options = Options(), *,
                 stop: Callable[[], str | None] | None = None):
        if opts.mode not in ("lockstep", "realtime"):
            raise ValueError(f"mode must be lockstep or realtime, got {opts.mode!r}")
        if not (opts.time_scale > 0 and math.isfinite(opts.time_scale)):
            raise ValueError(f"time scale must be > 0, got {opts.time_scale}")
        scn = with_overrides(scn, control_rate_hz=opts.rate, duration=opts.duration)
        self.opts = opts
        self.scn, self.mode, self.prefix = scn, opts.mode, opts.prefix
        self.rate = scn.run.control_rate_hz
        self.duration = scn.run.duration
        self.time_scale = opts.time_scale
        #: real time: poll (no sleep) for the last spin_us before each tick
        self._spin_ns = int(max(0.0, opts.spin_us) * 1e3)
        #: the emulator thread's CPU, SCHED_FIFO + mlockall, gc (emulator/rtproc.py)
        self._rt = RealtimeThread(freeze_gc=opts.freeze_gc, cpu=opts.cpu, fifo=opts.realtime_priority)
        #: the row's arithmetic: the C++ plant twin, or the Python model (emulator/twin.py)
        self.twin = PlantTwin(scn.plant, opts.cpp_plant)
        #: where the loop's microseconds went (emulator/loopstats.py), after the run
        self._breakdown: dict[str, Any] = {}
        self._guidance_next: tuple | None = None  # guidance values of the next state, computed ahead
        #: real time: ticks that applied the answer to the state of the period just ended
        self.fresh_ticks = 0
        self.cmd_timeout, self.retries = opts.cmd_timeout, opts.retries
        self.stop_unanswered = opts.stop_unanswered
        self.stale_periods = (scn.controller.safety.stale_periods if opts.stale_periods is None
                              else opts.stale_periods)
        #: the controllers' announcements and status senders (emulator/peers.py):
        #: lockstep waits for a status only from a controller that sends them
        self.peers = ControllerPeers(opts.wait_status)
        #: [s] wait this long for a first answer to state 0 before the run
        #: starts (a controller process still starting; None: no wait)
        self.start_timeout = opts.start_timeout
        self.start_wait_s = 0.0  # [s] how long the first answer took (start_timeout)
        #: asked every step (and while waiting for a command): a reason to stop
        #: the run early (a signal, a dead logger), None to go on; a run stopped
        #: so is returned with the rows done and marked partial
        self.stop = stop
        self.url = opts.url
        #: what the parts share: counters, faults, the run's time, invalid/stopped (emulator/state.py)
        self.shared = Shared(Counter(), scn.actuators, rods=scn.plant.magnetorquers)
        #: with auth_key every message carries an HMAC trailer; failures count as auth_failed (wire/auth.py)
        self.lc = open_bus(opts.url, opts.auth_key, self.shared.counters)
        self.session = secrets.randbits(62)
        n_rows = grid(scn)[0] + 1
        #: the run's record (results/record/store.py): every row's fields, its command and status as
        #: received, its stamps; two chunks live, the older rows written as the run goes
        #: (``record_dir``/trajectory.arrow, once the run outgrows the two chunks)
        self.record = Record(n_rows, opts.record_chunk, opts.record_dir)
        self.ring = self.record.ring
        #: the handlers and, per state seq of the run's rows, its command,
        #: status and publish times, preallocated (emulator/inbox.py); a second
        #: bench on our URL and prefix stops the run, marked invalid (emulator/collision.py)
        #: magnetic control: the rods' commands each row holds (emulator/twin.py), the field before each state
        self.rods = RodHold(scn.plant.magnetorquers.n_rods if scn.magnetic_control is not None else 0,
                            self.shared.counters)
        self.receiver = Receiver(
            self.lc, opts.prefix, self.session, n_rows, self.shared, peers=self.peers, n_rods=self.rods.n_rods,
            accept_faults=opts.accept_fault_commands, authenticated=opts.auth_key is not None, ring=self.ring,
            guard=CollisionGuard(opts.url, opts.prefix, self.session,
                                 alive_s=max(0.5, self.stale_periods / self.rate / opts.time_scale)))
        self.inbox = self.receiver.inbox
        guidance = GuidancePublisher(self.lc, channel("SCRT_GUIDANCE", opts.prefix), scn.core_config().guidance,
                                     self.rate, self.session)
        #: a [sensors] scenario: the sensor models, publishing their samples (emulator/sensorpub.py)
        self.sensors = (SensorPublisher(scn, self.session, self.lc.publish, opts.prefix)
                        if scn.sensors is not None else None)
        self.publisher = Publisher(self.lc, opts.prefix, self.session, guidance, self.inbox, self.twin,
                                   self.sensors, self.ring)
        self.guidance = guidance
        if self.sensors is not None:  # [sensors.magnetometer]: its samples of the true field
            self.sensors.field = self.twin.field_B
        elif self.rods.n_rods:  # no sensors: the ideal magnetometer's true field before each state
            self.publisher.field, self.publisher.n_sub = self.twin.field_B, grid(scn)[1]
        if opts.log_paced and self.mode == "lockstep":  # never ahead of the logger (emulator/logpace.py)
            self.publisher.pace = LogPace(self.lc, opts.prefix, self.shared.counters)
            self.publisher.should_stop = self._should_stop
            self.publisher.shared_stop = self._stop_for
        #: a row's steps, and the real-time deferral of its record and truth (emulator/rows.py)
        self.rows = RowPipeline(self.twin, self.publisher, self.ring, self.receiver, self.shared, self.sensors,
                                self._should_stop)

    # the shared values, by their old names (the CLI, the HIL runner, tests)
    @property
    def counters(self) -> Counter:
        return self.shared.counters

    @property
    def act(self):
        return self.shared.act

    @property
    def invalid(self) -> str | None:
        return self.shared.invalid

    @property
    def stopped(self) -> str | None:
        return self.shared.stopped

    @property
    def faults_applied(self) -> list[dict[str, Any]]:
        return self.shared.faults_applied

    @property
    def controller_info(self) -> dict[str, Any] | None:
        """The controller_info_t of the session in use (None: none announced)."""
        return self.receiver.controller_info

    def _handle_until(self, deadline_ns: int, spin_ns: int = 0) -> None:
        """Handle messages until ``deadline_ns``: asleep in ``select`` until
        ``spin_ns`` before it, then polling (a wake-up from sleep is late by
        the scheduler's latency; a poll is not)."""
        fd = self.lc.fileno()
        rows = self.rows
        while True:
            rows.flush_due(self.inbox.has_cmd)  # the answer is in (or half a period passed): now the truth
            rem = deadline_ns - time.monotonic_ns()
            if rem <= 0:
                self.publisher.drain()  # what is already there, without waiting
                return
            wait = rem - spin_ns
            if rows.pending is not None:  # wake for the deferred truth at the latest
                wait = min(wait, rows.pending_by_ns - time.monotonic_ns())
            if select.select([fd], [], [], wait / 1e9 if wait > 0 else 0)[0]:
                self.lc.handle()

    def _stop_for(self, why: str) -> None:
        """Stop the run at the loop's next check, for ``why`` (the first reason kept)."""
        if self.shared.stopped is None:
            self.shared.stopped = why

    def _should_stop(self) -> bool:
        if self.shared.stopped is None and self.stop is not None:
            self.shared.stopped = self.stop()
        return self.shared.stopped is not None

    # --- the loops -----------------------------------------------------------
    def run(self) -> Run:
        """The whole run; returns its record (metrics are the caller's:
        ``sc_rt.results.judge.metrics.finish_run``)."""
        if self.sensors is not None:  # tick 0: its samples go out before state 0
            self.publisher.sense(0, 0.0, initial_state(self.scn), 0)
        if self.start_timeout is not None:
            self._await_controller(initial_state(self.scn))
        with self._rt:
            if self.mode == "lockstep":
                return self._run_lockstep()
            return self._run_realtime()

    @property
    def scheduler(self) -> str:
        """What the emulator's thread got (emulator/rtproc.py)."""
        return self._rt.description

    @property
    def t_reached(self) -> float:
        """[s] the time of the newest row recorded."""
        return self.rows.t_reached

    def breakdown(self) -> dict[str, Any]:
        """Where each row's microseconds went (emulator/loopstats.py), after the run."""
        return self._breakdown

    def _await_controller(self, x0: np.ndarray) -> None:
        """Re-send state 0 until a controller answers it (raises RuntimeError
        after ``start_timeout`` s): a process that is still starting, or one
        a person starts by hand, gets the run from its first state."""
        t_start = time.monotonic_ns()
        end = t_start + int(self.start_timeout * 1e9)
        while not self.inbox.has_cmd(0):
            now = time.monotonic_ns()
            if now >= end:
                raise RuntimeError(f"no controller answered the first state within {self.start_timeout:g} s")
            self.shared.counters["start_state_sent"] += 1
            if self.sensors is not None and self.shared.counters["start_state_sent"] > 1:
                self.sensors.resend_first()  # a controller still starting gets tick 0's samples too
            self.publisher.state(0, 0.0, x0)
            resend = min(end, now + 100_000_000)
            while not self.inbox.has_cmd(0) and time.monotonic_ns() < resend:
                if self._should_stop():
                    return  # the run loop ends at once, with no rows
                self.lc.handle_timeout(20)
        self.start_wait_s = (time.monotonic_ns() - t_start) / 1e9

    def _meta(self) -> RunMeta:
        return RunMeta.of_scenario(self.scn, f"hil-{self.mode}", mode=self.mode)

    def _run_lockstep(self) -> Run:
        scn = self.scn
        n_ctrl, n_sub, h, rate = grid(scn)
        inbox = self.inbox
        ring = self.ring
        x = initial_state(scn)
        rows = 0
        silent = 0  # consecutive states without an answer
        self.rows.next_published = -1  # the state a row published already (the state first)
        for k in range(n_ctrl + 1):
            t = k / rate
            self.shared.t_now = t
            ring.reach(k + 1)  # rows k and k + 1 live: the record's older chunk goes to disk
            cmd = None
            # a silent peer (crashed controller) gets one short wait per state
            # instead of the full timeout and retries: the run goes on under
            # the watchdog and resumes when a controller answers again
            timeout = self.cmd_timeout if silent == 0 else min(self.cmd_timeout, 0.05)
            retries = self.retries if silent == 0 else 0
            for attempt in range(retries + 1):
                if attempt:
                    self.shared.counters["state_resent"] += 1
                if attempt or self.rows.next_published != k:
                    self.publisher.state(k, t, x)
                if attempt == 0 and k < n_ctrl:  # the next state's guidance while the controller works
                    self._guidance_next = self.guidance.values((k + 1) / rate)
                deadline = time.monotonic_ns() + int(timeout * 1e9)
                while time.monotonic_ns() < deadline and not self._should_stop():
                    if inbox.has_cmd(k) and (
                            inbox.has_status(k) or not self.peers.wants_status(inbox.cmd_session(k))):
                        # the rods' command goes out just before the wheels' (the same publisher, in order):
                        # one not in by then gets a short grace, then the rods are held (a controller that
                        # sends no rods: RodHold counts it) rather than the state re-sent
                        if not self.rods.n_rods or inbox.has_rod(k):
                            break
                        deadline = min(deadline, time.monotonic_ns() + ROD_GRACE_NS)
                    rem_ms = max(1, (deadline - time.monotonic_ns()) // 1_000_000)
                    try:
                        self.lc.handle_timeout(int(min(rem_ms, 100)))
                    except OSError:  # EINTR: a signal (self.stop decides), within the deadline
                        continue
                cmd = inbox.cmd(k)
                if cmd is not None or self.shared.stopped:
                    break
            if cmd is None and self.stop_unanswered and not self.shared.stopped:
                wait = self.cmd_timeout * (retries + 1)
                self._stop_for(f"the controller did not answer state {k} (t = {t:.6g} s) within {wait:g} s "
                               "(lockstep waits for every answer: a hung or stopped controller fails the run)")
            if self.shared.stopped:  # row k was not applied: the run ends with row k - 1
                break
            stale = cmd is None
            silent = silent + 1 if stale else 0
            if stale:
                # watchdog: no answer to this state: apply zero, flag, go on
                self.shared.counters["cmd_timeout"] += 1
            row, j = ring.slot(k)
            stamps = row["stamps"][j]
            stamps[0] = time.monotonic_ns()
            d_cmd = self.rods.for_row(cmd, inbox.rod(k))
            x = self._apply(k, t, x, cmd, n_sub, h, None if k == n_ctrl else (k + 1, (k + 1) / rate), stamps,
                            d_cmd=d_cmd)
            rows = k + 1
            if k == n_ctrl or x is None or self._should_stop():
                break
        return self._finish(rows, x is None and rows < n_ctrl + 1)

    def _run_realtime(self) -> Run:
        scn = self.scn
        n_ticks, n_sub, h, rate = grid(scn)
        period = 1.0 / rate
        wall_period_ns = int(round(period / self.time_scale * 1e9))
        stale_ns = int(self.stale_periods * wall_period_ns)
        ring = self.ring
        defer_ns = wall_period_ns // 2  # a row's truth waits at most half a period for the answer
        x = initial_state(scn)
        rows = 0
        self.publisher.state(0, 0.0, x)
        start = time.monotonic_ns()
        spin = self._spin_ns
        for k in range(n_ticks + 1):
            t = k * period
            self.shared.t_now = t
            ring.reach(k + 1)  # rows k and k + 1 live: the record's older chunk goes to disk
            deadline = start + (k + 1) * wall_period_ns
            # the next state's guidance while there is time (it needs no command)
            self._guidance_next = (self.guidance.values((k + 1) * period) if k < n_ticks else None)
            self._handle_until(deadline, spin)
            now = time.monotonic_ns()
            row, j = ring.slot(k)
            stamps = row["stamps"][j]
            stamps[0] = now
            row["tick_lateness_us"][j] = (now - deadline) / 1e3
            cmd = self.receiver.newest_cmd
            if cmd is None or now - self.receiver.newest_cmd_ns > stale_ns:
                self.shared.counters["cmd_stale_ticks"] += 1
                cmd = None
            elif cmd.state_seq == k:  # computed from the state of the period that just ended
                self.fresh_ticks += 1
            d_cmd = self.rods.for_row(cmd, self.receiver.newest_rod)
            x = self._apply(k, t, x, cmd, n_sub, h, None if k == n_ticks else (k + 1, (k + 1) * period),
                            stamps, defer_ns=defer_ns, d_cmd=d_cmd)
            rows = k + 1
            if k == n_ticks or x is None or self._should_stop():
                break
        return self._finish(rows, x is None and rows < n_ticks + 1)

    def _apply(self, k: int, t: float, x: np.ndarray, cmd, n_sub: int, h: float,
               next_state: tuple[int, float] | None = None, stamps=None, defer_ns: int | None = None,
               d_cmd: tuple | None = None):
        """Row k (RowPipeline.apply), with the next state's guidance computed ahead."""
        guidance, self._guidance_next = self._guidance_next, None
        return self.rows.apply(k, t, x, cmd, n_sub, h, next_state, stamps, defer_ns, d_cmd, guidance)

    def _finish(self, rows: int, diverged: bool) -> Run:
        self.rows.close(rows)
        # let the last status arrive
        self._handle_until(time.monotonic_ns() + 20_000_000)
        run, self._breakdown = self.record.close(rows, self._meta(), self.mode)
        if self.sensors is not None:
            self.shared.counters.update(self.sensors.counters())
        if self.publisher.field is not None:  # the ideal magnetometer's (with sensors: the samples' count above)
            self.shared.counters["mag_sent"] = self.publisher.mag_sent
        run.counters = dict(self.shared.counters)
        run.gaps = list(self.rows.gaps)
        run.faults_applied = list(self.shared.faults_applied)
        run.diverged = diverged
        label = self.peers.label(self.receiver.ctl_session)  # the law's name, as the controller announced it
        if label:
            run.meta = dataclasses.replace(run.meta, law=label)
        if self.shared.stopped is not None:
            run.partial = True
            run.message = self.shared.stopped
            run.metrics.update(stopped=self.shared.stopped, t_reached_s=self.rows.t_reached if rows else None)
        run.metrics.update(provenance(self.session, self.receiver.ctl_session, self.shared.invalid))
        return run
