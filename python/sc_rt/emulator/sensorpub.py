"""The emulator's sensors (a scenario with ``[sensors]``): the core's
``SensorSuite`` sampled on the plant's grid, each new sample published at
once on its channel (``gyro_t`` on SCRT_GYRO, ``star_tracker_t`` on
SCRT_STAR at its delivery, ``tachometer_t`` on SCRT_TACH, with
``[sensors.magnetometer]`` ``magnetometer_t`` on SCRT_MAG, a sample in the
sensor frame of the plant's true field at its tick (source SOURCE_SENSOR,
frame FRAME_SENSOR); docs/PROTOCOL.md, "Sensors"), packed with struct exactly as the generated encoders do
(tests/test_hil_sensors.py) and numbered per sensor from 0.

The emulator calls :meth:`SensorPublisher.tick` at the plant steps
``next_tick`` names (a step with nothing due changes nothing), before the
sub-step integrated from it and before the state of a control instant, in
the offline loop's order (sim/sensed.py): so the controller's filter gets
the same samples at the same times as the offline one.
"""

from __future__ import annotations

import struct
import time
from typing import Callable

import numpy as np
import sc_rt_lcm

from sc_rt import _core
from sc_rt.wire.lcmio import channel
from sc_rt.scenario.tables.sensors import nav_config

__all__ = ["SensorPublisher", "SENT_COUNTERS", "gyro_bytes", "star_bytes", "tach_bytes", "mag_bytes"]

#: channel -> the emulator counter of the samples sent on it (``SensorPublisher.counters``)
SENT_COUNTERS = {"SCRT_GYRO": "gyro_sent", "SCRT_STAR": "star_sent", "SCRT_TACH": "tach_sent",
                 "SCRT_MAG": "mag_sent"}

# gyro_t: utime, seq, session, tick, t, omega[3], output
_GYRO = (sc_rt_lcm.gyro_t._get_packed_fingerprint(), struct.Struct(">qqqqd3db"))
# star_tracker_t: utime, seq, session, tick, t_exposure, t_delivery, sigma_BN[3], lost, blacked_out
_STAR = (sc_rt_lcm.star_tracker_t._get_packed_fingerprint(), struct.Struct(">qqqqdd3dqq"))
# tachometer_t: utime, seq, session, tick, t, wheel_speed[4]
_TACH = (sc_rt_lcm.tachometer_t._get_packed_fingerprint(), struct.Struct(">qqqqd4d"))
# magnetometer_t: utime, seq, session, tick, t, B[3], source, frame
_MAG = (sc_rt_lcm.magnetometer_t._get_packed_fingerprint(), struct.Struct(">qqqqd3dbb"))
#: magnetometer_t's (source, frame) of a magnetometer's sample: SOURCE_SENSOR in FRAME_SENSOR
MAG_SENSOR = (sc_rt_lcm.magnetometer_t.SOURCE_SENSOR, sc_rt_lcm.magnetometer_t.FRAME_SENSOR)
for _cls, (_fp, _lay) in ((sc_rt_lcm.gyro_t, _GYRO), (sc_rt_lcm.star_tracker_t, _STAR),
                          (sc_rt_lcm.tachometer_t, _TACH), (sc_rt_lcm.magnetometer_t, _MAG)):
    assert _lay.size + 8 == len(_cls().encode()), _cls


def gyro_bytes(utime: int, seq: int, session: int, tick: int, t: float, omega, output: int = 0) -> bytes:
    return _GYRO[0] + _GYRO[1].pack(utime, seq, session, tick, t, *omega, output)


def star_bytes(utime: int, seq: int, session: int, tick: int, t_exposure: float, t_delivery: float,
               sigma, lost: int, blacked_out: int) -> bytes:
    return _STAR[0] + _STAR[1].pack(utime, seq, session, tick, t_exposure, t_delivery, *sigma, lost,
                                    blacked_out)


def mag_bytes(utime: int, seq: int, session: int, tick: int, t: float, B, source: int = 0, frame: int = 0) -> bytes:
    """magnetometer_t: the field B [T] (source 0, frame 0: the ideal magnetometer's true field in B;
    ``MAG_SENSOR``: a magnetometer's sample in its sensor frame)."""
    return _MAG[0] + _MAG[1].pack(utime, seq, session, tick, t, *B, source, frame)


def tach_bytes(utime: int, seq: int, session: int, tick: int, t: float, wheel_speed) -> bytes:
    return _TACH[0] + _TACH[1].pack(utime, seq, session, tick, t, *wheel_speed)


class SensorPublisher:
    """The scenario's sensors, publishing through ``publish(channel, bytes)``."""

    def __init__(self, scn, session: int, publish: Callable[[str, bytes], None], prefix: str = ""):
        self.nav = nav_config(scn.sensors, scn.run.plant_step, f"{scn.path}")
        self.suite = _core.SensorSuite(self.nav.sensors)
        self.session = session
        self._publish = publish
        self._ch = tuple(channel(c, prefix) for c in SENT_COUNTERS)  # gyro, star tracker, tachometer, mag
        self.sent = [0, 0, 0, 0]  #: samples published per sensor (gyro, star tracker, tachometer, magnetometer)
        #: the plant's true field in B of (t, x) [T] (None: no field) for the magnetometer's
        #: samples (emulator/twin.py ``PlantTwin.field_B``); evaluated only where it is due
        self.field: Callable[[float, np.ndarray], tuple | None] | None = None
        self.first: list[tuple[str, bytes]] = []  #: the messages of tick 0 (re-sent with a re-sent state 0)
        self._next = 0
        self.suite.reset()

    @property
    def next_tick(self) -> int:
        """The next plant step at which a sensor samples or delivers."""
        return self._next

    @property
    def gyro_bias(self) -> np.ndarray:
        """[rad/s] the gyro's true bias now (after the last tick)."""
        return np.asarray(self.suite.gyro_bias)

    def tick(self, i: int, t: float, x: np.ndarray) -> None:
        """Plant step i at time t with the state x: sample what is due, publish it."""
        s = self.suite
        # the magnetometer samples the plant's true field at the tick (sim/sensed.py nav_tick)
        B = self.field(t, x) if self.field is not None and s.magnetometer_due(i) else None
        s.tick(i, t, x, B)
        self._next = s.next_tick(i)
        out = []
        utime = time.time_ns() // 1000
        if s.gyro_new:
            tg, w, kind = s.gyro
            out.append((self._ch[0], gyro_bytes(utime, self.sent[0], self.session, i, tg, w, kind)))
            self.sent[0] += 1
        if s.star_new:
            te, td, sig = s.star
            out.append((self._ch[1], star_bytes(utime, self.sent[1], self.session, i, te, td, sig, s.lost,
                                                s.blacked_out)))
            self.sent[1] += 1
        if s.tach_new:
            tt, ws = s.tach
            out.append((self._ch[2], tach_bytes(utime, self.sent[2], self.session, i, tt, ws)))
            self.sent[2] += 1
        if s.mag_new:  # last, as the suite samples it (docs/MODEL.md section 10)
            tm, B_S = s.mag
            out.append((self._ch[3], mag_bytes(utime, self.sent[3], self.session, i, tm, B_S, *MAG_SENSOR)))
            self.sent[3] += 1
        if i == 0:
            self.first = out
        for ch, data in out:
            self._publish(ch, data)

    def resend_first(self) -> None:
        """The samples of tick 0 again (a state 0 re-sent to a controller still starting)."""
        for ch, data in self.first:
            self._publish(ch, data)

    def counters(self) -> dict[str, int]:
        s = self.suite
        return {**dict(zip(SENT_COUNTERS.values(), self.sent)),
                "star_lost": int(s.lost), "star_blacked_out": int(s.blacked_out)}
