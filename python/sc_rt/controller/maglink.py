"""The Python controller process's magnetic link (a scenario with
``[momentum]`` or ``[bdot]``; docs/PROTOCOL.md, "Magnetic control"): the
field of each state from SCRT_MAG (``magnetometer_t``: an ideal
magnetometer's true field in B, or with ``[sensors.magnetometer]`` the
magnetometer's samples in its sensor frame, handed to the sensor intake,
whose ``field_B`` is the offline loop's ``Navigation.field_B``) and the
rods' commands out on SCRT_ROD_CMD
(``rod_cmd_t``), the twin of sc-rt-controller's (cpp/app/controller_shell.cpp
``handle_mag``, ``field_for``, ``publish_rod``)."""

from __future__ import annotations

import math
import time
from collections import Counter

import sc_rt_lcm

from sc_rt.wire.codec import decode_as

__all__ = ["MagLink"]

_NAN3 = (math.nan, math.nan, math.nan)
_M = sc_rt_lcm.magnetometer_t
_SENSOR, _IDEAL = (_M.SOURCE_SENSOR, _M.FRAME_SENSOR), (_M.SOURCE_TRUE_FIELD, _M.FRAME_BODY)  # (source, frame)
#: the counters the process's summary reports under "magnetic"
COUNTS = ("field_received", "field_rejected", "field_used", "field_missing")


class MagLink:
    """The newest field message and the rods' command message of ``n_rods`` rods
    (counters in ``cnt``: the process's); ``intake``: the process's
    ``_core.SensorIntake``, whose mounted magnetometer's samples give the field."""

    def __init__(self, n_rods: int, cnt: Counter, intake=None):
        self.n_rods, self.cnt = n_rods, cnt
        self.intake = intake if intake is not None and intake.magnetometer_mounted else None
        self._field: tuple | None = None  # (session, t [s], B_B [T]) of the newest field

    def on_mag(self, _ch: str, data: bytes) -> None:
        """An ideal magnetometer's field, the newest kept (with a magnetometer: its
        sample, into the intake); anything else counted and dropped
        (translate.cpp ``field_from_lcm``, ``mag_sample_from_lcm``)."""
        m = decode_as(sc_rt_lcm.magnetometer_t, data, self.cnt)
        want = _SENSOR if self.intake is not None else _IDEAL
        if (m is None or (m.source, m.frame) != want or not all(map(math.isfinite, m.B))
                or not math.isfinite(m.t)):
            self.cnt["field_rejected"] += 1
            return
        self.cnt["field_received"] += 1
        if self.intake is not None:
            self.intake.offer_mag(m.session, m.seq, m.t, list(m.B))
            return
        self._field = (m.session, m.t, tuple(m.B))

    def field_for(self, session: int, t: float) -> tuple:
        """[T] the field at a state's time ``t`` [s] of its plant ``session``, else NaN
        (none known: the magnetic part commands the rods zero)."""
        if self.intake is not None:  # the latest sample up to t, rotated to B (intake.use applied them)
            B = tuple(self.intake.field_B) if self.intake.session == session else _NAN3
            self.cnt["field_used" if all(map(math.isfinite, B)) else "field_missing"] += 1
            return B
        f = self._field
        if f is not None and f[0] == session and f[1] == t:
            self.cnt["field_used"] += 1
            return f[2]
        self.cnt["field_missing"] += 1
        return _NAN3

    def rod_msg(self, cmd, seq: int, session: int, state_seq: int) -> sc_rt_lcm.rod_cmd_t:
        """The rods' command of the core's Command ``cmd`` with the seq of the wheel
        command it goes with (translate.cpp ``fill_rod_cmd``: no decision, NaN, is 0)."""
        r = sc_rt_lcm.rod_cmd_t()
        r.utime, r.seq, r.session, r.state_seq = time.time_ns() // 1000, seq, session, state_seq
        r.t, r.n_rods = cmd.t, self.n_rods
        d = [float(v) for v in cmd.rod_dipole_cmd]
        r.dipole = [v if i < self.n_rods and math.isfinite(v) else 0.0 for i, v in enumerate(d)]
        return r

    def summary(self) -> dict:
        return {"rods": self.n_rods, **{k: self.cnt[k] for k in COUNTS}}
