"""Bench isolation: a second bench on the same LCM URL and channel prefix.

Two ``sc-rt hil`` runs started with the same ``--lcm-url`` (and prefix) hear
each other's plant states and controller commands. Hostile or stray single
messages are counted (``foreign_session``) and never applied; a *second
bench* is a foreign session that keeps publishing well-formed, in-order
messages: ``COLLISION_MESSAGES`` of them in a row from one session.

- another plant (``plant_state_t`` of a session that is not ours on our
  state channel): always a collision (the emulator is the only plant of its
  bench, and it never adopts another);
- another controller (``wheel_cmd_t`` / ``controller_status_t`` of a session
  that is not the adopted one) while ours is alive (it sent something within
  ``alive_s``): a collision. Once ours is lost the emulator adopts the new
  session instead (a crashed and restarted controller, docs/HIL.md), and a
  restarted controller that answers the states re-sent before that (at most
  one per second) never comes near the threshold.

Policy only (no I/O): the emulator feeds it and stops the run, marked
invalid, when it returns a reason.
"""

from __future__ import annotations

__all__ = ["COLLISION_MESSAGES", "CollisionGuard"]

#: in-order messages of one foreign session that make a second bench (a fuzzer
#: draws a new session per message; a replay reuses the genuine one)
COLLISION_MESSAGES = 20


class CollisionGuard:
    def __init__(self, url: str, prefix: str, plant_session: int, alive_s: float,
                 threshold: int = COLLISION_MESSAGES):
        self.url, self.prefix, self.plant_session = url, prefix, plant_session
        self.alive_ns = int(alive_s * 1e9)
        self.threshold = threshold
        self.reason: str | None = None
        self.foreign: dict[str, int] = {}  # "plant" / "controller" -> the session seen
        self._runs: dict[tuple[str, int], tuple[int, int]] = {}  # (kind, session) -> (last seq, run length)

    def _count(self, kind: str, session: int, seq: int) -> bool:
        """One more message of a foreign session; True once it is a run of threshold in order."""
        last, n = self._runs.get((kind, session), (None, 0))
        n = n + 1 if last is None or seq > last else 1
        if len(self._runs) > 10_000:  # a fuzzer's sessions: one message each
            self._runs.clear()
        self._runs[(kind, session)] = (seq, n)
        return n >= self.threshold

    def plant_state(self, session: int, seq: int, controller_session: int | None) -> str | None:
        """A well-formed plant_state_t heard on our state channel."""
        if session == self.plant_session or self.reason is not None:
            return self.reason
        if self._count("plant", session, seq):
            self.foreign["plant"] = session
            self.reason = self._message(f"another plant (session {session:#x}) publishes on "
                                        f"{self.prefix}SCRT_STATE", controller_session)
        return self.reason

    def controller_msg(self, session: int, seq: int, ours: int | None, ours_last_ns: int,
                       now_ns: int, kind: str = "cmd") -> str | None:
        """A well-formed command (kind "cmd") or status ("status", its cmd_seq)
        of a session that is not the adopted one."""
        if self.reason is not None or ours is None or now_ns - ours_last_ns > self.alive_ns:
            return self.reason
        if self._count(kind, session, seq):
            self.foreign["controller"] = session
            self.reason = self._message(f"another controller (session {session:#x}) answers on "
                                        f"{self.prefix}SCRT_CMD while ours is alive", ours)
        return self.reason

    def _message(self, what: str, controller_session: int | None) -> str:
        ctl = "none yet" if controller_session is None else f"{controller_session:#x}"
        return (f"bench collision on {self.url}" + (f" (prefix {self.prefix!r})" if self.prefix else "")
                + f": {what}; this bench is plant session {self.plant_session:#x}, controller session "
                f"{ctl}. Another bench runs on the same URL and prefix: give each its own "
                "(sc-rt hil picks a free port unless --lcm-url is given). The run is invalid")
