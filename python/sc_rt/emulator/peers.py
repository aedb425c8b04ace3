"""The emulator's side of the optional parts of the protocol (docs/PROTOCOL.md):

- ``GuidancePublisher``: the guidance reference on SCRT_GUIDANCE
  (``guidance_t``), one per plant state and just before it, computed with
  the core's ``_core.Guidance`` as sc-rt-controller does (RK4 steps of at
  most one control period along the run's time line from t = 0), so an
  external law gets the reference the built-in laws use;
- ``ControllerPeers``: what the emulator knows of the controllers on the bus:
  the ``controller_info_t`` each session announced (law name, whether it
  sends ``controller_status_t``) and which sessions have sent a status. A
  lockstep emulator waits for a state's status only from a controller that
  said it sends them, or, without an announcement, once it has seen one
  from that session: a controller that sends commands only is never waited
  for.
"""

from __future__ import annotations

import struct
import time
from collections import Counter
from typing import Any

import sc_rt_lcm

from sc_rt import _core
from sc_rt.wire.codec import decode_as, to_plain

__all__ = ["GuidancePublisher", "ControllerPeers", "GUIDANCE_FP", "GUIDANCE_LAYOUT"]

# guidance_t: utime, seq, session, t, sigma_DN[3], omega_DN_D[3], omega_dot_DN_D[3]
GUIDANCE_FP = sc_rt_lcm.guidance_t._get_packed_fingerprint()
GUIDANCE_LAYOUT = struct.Struct(">qqqd3d3d3d")
assert GUIDANCE_LAYOUT.size + 8 == len(sc_rt_lcm.guidance_t().encode())


class GuidancePublisher:
    """guidance_t for each state, from the scenario's guidance parameters."""

    def __init__(self, lc, channel: str, params, control_rate_hz: float, session: int):
        self.lc, self.channel, self.params, self.session = lc, channel, params, session
        self.guidance = _core.Guidance(params, 1.0 / control_rate_hz)
        self.guidance.reset(0.0)

    def values(self, t: float) -> tuple:
        """(sigma_DN, omega_DN_D, omega_dot_DN_D) at t (the guidance moves forward only)."""
        self.guidance.advance(t)
        return (tuple(self.guidance.sigma_DN), tuple(_core.omega_d(self.params, t)),
                tuple(_core.omega_d_dot(self.params, t)))

    def publish(self, seq: int, t: float, values: tuple | None = None) -> None:
        """guidance_t for the state ``seq`` at ``t``; ``values``: ``values(t)``
        computed ahead (the real-time emulator does it while it waits, so that
        only the publish stands between its tick and the state)."""
        sd, wd, wdd = self.values(t) if values is None else values
        self.lc.publish(self.channel, GUIDANCE_FP + GUIDANCE_LAYOUT.pack(
            time.time_ns() // 1000, seq, self.session, t, *sd, *wd, *wdd))


class ControllerPeers:
    """Announcements and status senders, by controller session."""

    def __init__(self, wait_status: bool | None = None):
        #: True: always wait for a state's status in lockstep; False: never;
        #: None: as the controller announced, else once it has sent one
        self.wait_status = wait_status
        self.info: dict[int, dict[str, Any]] = {}
        self.status_sessions: set[int] = set()

    def on_info(self, data: bytes, counters: Counter) -> None:
        msg = decode_as(sc_rt_lcm.controller_info_t, data, counters)
        if msg is None:
            return
        counters["ctrl_info"] += 1
        self.info[msg.session] = to_plain(msg)

    def saw_status(self, session: int) -> None:
        self.status_sessions.add(session)

    def wants_status(self, session: int) -> bool:
        if self.wait_status is not None:
            return self.wait_status
        info = self.info.get(session)
        if info is not None:
            return bool(info["sends_status"])
        return session in self.status_sessions

    def label(self, session: int | None) -> str | None:
        """The law's name the controller of ``session`` announced; "external"
        for a session that sent commands only (not sc-rt-controller, no name
        announced); None: no controller."""
        info = self.info.get(session) if session is not None else None
        if info and info["law"]:
            return info["law"]
        return "external" if session is not None and session not in self.status_sessions else None
