"""The emulator's publishing side (a part of ``emulator.process.Emulator``):
the field (a run with magnetic control: ``magnetometer_t``, the ideal
magnetometer), the guidance and the state of a control instant, the truth of a row, the
sensors' samples of a plant step (emulator/sensorpub.py), and draining what
our own multicast brings back (handled by the receiver, emulator/receiver.py).
Owns what it last sent (the guidance values of the newest state); writes
the truth's fields of each row (and the gyro's true bias) into the
emulator's record."""

from __future__ import annotations

import math
import select
import time
from typing import Any, Callable

import numpy as np

from sc_rt.emulator.inbox import Inbox
from sc_rt.emulator.peers import GuidancePublisher
from sc_rt.emulator.sensorpub import SensorPublisher, mag_bytes
from sc_rt.emulator.twin import NO_RODS, PlantTwin, state_bytes, truth_bytes
from sc_rt.wire.lcmio import channel
from sc_rt.results.record.store import RowRing

__all__ = ["Publisher", "mag_bytes"]

_NAN3 = (math.nan, math.nan, math.nan)


class Publisher:
    def __init__(self, lc: Any, prefix: str, session: int, guidance: GuidancePublisher, inbox: Inbox,
                 twin: PlantTwin, sensors: SensorPublisher | None, ring: RowRing):
        self.lc, self.session, self.guidance, self.inbox, self.twin = lc, session, guidance, inbox, twin
        self.sensors = sensors
        self._ch_state = channel("SCRT_STATE", prefix)
        self._ch_truth = channel("SCRT_TRUTH", prefix)
        self._guidance_sent: tuple = (-1, None)  # (seq, guidance values) of the newest state out
        #: the emulator's record (results/record/store.py): the truth's fields of each row go there,
        #: and with [sensors] the gyro's true bias (the truth's gyro_bias, the run's bias_true)
        self.ring = ring
        #: lockstep with a paced logger (emulator/logpace.py): asked before each state; the emulator
        #: sets it, with ``should_stop`` (its stop check) and ``shared_stop`` (stop the run, why)
        self.pace: Any = None
        self.should_stop: Callable[[], bool] = lambda: False
        self.shared_stop: Callable[[str], None] = lambda why: None
        #: a run with magnetic control: the true field in B of (t, x) [T] (None: no field), published
        #: before each state as the ideal magnetometer (SCRT_MAG), tick = seq x ``n_sub``; None: no field
        self.field: Callable[[float, np.ndarray], Any] | None = None
        self.n_sub = 1
        self._ch_mag = channel("SCRT_MAG", prefix)
        #: the distinct magnetometer seqs sent (0 .. mag_sent - 1), for the log's completeness
        self.mag_sent = 0

    def state(self, k: int, t: float, x: np.ndarray, guidance: tuple | None = None) -> None:
        """State k (and its guidance first: a controller has it with the state)."""
        if guidance is None:  # computed now, or the values state k went out with (a re-sent state)
            guidance = self._guidance_sent[1] if self._guidance_sent[0] == k else self.guidance.values(t)
        if self.pace is not None and (why := self.pace.before_state(self.should_stop)) is not None:
            self.shared_stop(why)  # the logger stalled: the state is not published, the run stops
            return
        self._guidance_sent = (k, guidance)
        if self.field is not None:  # the field at the state's instant, before it (docs/PROTOCOL.md)
            B = self.field(t, x)
            self.lc.publish(self._ch_mag, mag_bytes(time.time_ns() // 1000, k, self.session, k * self.n_sub, t,
                                                    _NAN3 if B is None else B))
            self.mag_sent = max(self.mag_sent, k + 1)
        self.guidance.publish(k, t, guidance)
        utime = time.time_ns() // 1000
        data = state_bytes(utime, k, self.session, t, x)
        self.inbox.published(k, utime, time.monotonic_ns())
        self.lc.publish(self._ch_state, data)
        if self.pace is not None:
            self.pace.sent += 1
        self.drain()  # our own guidance and state come back (loopback): handled while the controller works

    def sense(self, i: int, t: float, x: np.ndarray, row: int) -> None:
        """The sensors at plant step i (a control instant, row ``row``) when
        one is due; the gyro's true bias of the row either way."""
        if i == self.sensors.next_tick:
            self.sensors.tick(i, t, x)
        c, j = self.ring.slot(row)
        c["bias_true"][j] = self.sensors.gyro_bias

    def drain(self) -> None:
        """Handle what is already in the socket, without waiting."""
        fd = self.lc.fileno()
        while select.select([fd], [], [], 0)[0]:
            self.lc.handle()

    def truth(self, k, t, cmd_seq, u_cmd, accel, delta2, stale, act, rod_fields=NO_RODS,
              fault_seqs=(-1, -1)) -> None:
        """Row k's truth, with the faults ``act`` it was applied with, the
        rods' fields ``rod_fields`` (``PlantTwin.rod_fields`` of the row: the
        commands held, each rod's dipole, the body dipole, the fault states)
        and the seqs of the newest fault commands applied and refused by then
        (``fault_seqs``); its wheels' fault fields go into the run's row too."""
        fault_y, eff_bias_stuck = self.twin.fault_fields(act, t)
        row, j = self.ring.slot(k)
        bias = (0.0, 0.0, 0.0) if self.sensors is None else row["bias_true"][j]
        self.lc.publish(self._ch_truth, truth_bytes(time.time_ns() // 1000, k, t, cmd_seq, u_cmd, accel, delta2,
                                                    self.twin.disturbance(t), fault_y, eff_bias_stuck, stale,
                                                    bias, rod_fields, fault_seqs))
        row["fault_Y"][j] = fault_y
        row["fault_effectiveness"][j] = eff_bias_stuck[0:4]
        row["fault_bias"][j] = eff_bias_stuck[4:8]
        row["fault_stuck"][j] = eff_bias_stuck[8:12]
