"""Optional message authentication on a shared lab network (``--auth-key FILE``).

With a key, every message a bench process publishes is the LCM message's
bytes followed by a 32-byte trailer, HMAC-SHA256(key, channel || 0x00 ||
payload); a receiver checks and strips the trailer *before* it decodes (the
guarded decoders count trailing bytes as malformed), and drops and counts
(``auth_failed``) anything that does not verify: no tag, a wrong key, a
message moved to another channel, a flipped bit. The C++ controller does the
same with its own SHA-256 (cpp/shell/hmac.hpp). Without a key nothing
changes: the plain ``lcm.LCM`` is used, bit for bit as before.

There is no replay protection beyond the sessions and sequence numbers
(a recorded, genuine message replayed is a duplicate or out of order).
"""

from __future__ import annotations

import hashlib
import hmac
from collections import Counter
from pathlib import Path
from typing import Any, Callable

from sc_rt.wire.lcmio import open_lcm

__all__ = ["unauthenticated", "TAG_SIZE", "load_key", "message_tag", "verified_payload", "AuthLCM", "open_bus"]

TAG_SIZE = 32


def load_key(path: str | Path | None) -> bytes | None:
    """The key's bytes (the whole file, as the C++ controller reads it); None: no key."""
    if path is None:
        return None
    try:
        key = Path(path).read_bytes()
    except OSError as e:
        raise ValueError(f"--auth-key {path}: cannot read the key: {e.strerror}") from e
    if not key:
        raise ValueError(f"--auth-key {path}: the key file is empty")
    return key


def message_tag(key: bytes, channel: str, payload: bytes) -> bytes:
    return hmac.new(key, channel.encode() + b"\0" + bytes(payload), hashlib.sha256).digest()


def verified_payload(key: bytes, channel: str, data: bytes) -> bytes | None:
    """The message without its trailer when the trailer verifies, else None."""
    if len(data) < TAG_SIZE:
        return None
    body, tag = bytes(data[:-TAG_SIZE]), bytes(data[-TAG_SIZE:])
    return body if hmac.compare_digest(message_tag(key, channel, body), tag) else None


class AuthLCM:
    """An ``lcm.LCM`` whose publish appends the tag and whose handlers get
    verified payloads only; what fails is counted in ``counters["auth_failed"]``."""

    def __init__(self, lc: Any, key: bytes, counters: Counter | None = None):
        self._lc, self._key = lc, key
        self.counters = counters if counters is not None else Counter()

    def publish(self, channel: str, data: bytes) -> None:
        self._lc.publish(channel, bytes(data) + message_tag(self._key, channel, data))

    def subscribe(self, channel: str, handler: Callable[[str, bytes], None]) -> Any:
        def checked(ch: str, data: bytes) -> None:
            body = verified_payload(self._key, ch, data)
            if body is None:
                self.counters["auth_failed"] += 1
                return
            handler(ch, body)

        return self._lc.subscribe(channel, checked)

    def __getattr__(self, name: str) -> Any:  # fileno, handle, handle_timeout, unsubscribe
        return getattr(self._lc, name)


def unauthenticated(bus: Any) -> Any:
    """The plain LCM under ``bus`` (itself when it has no key): for a channel
    whose messages carry no tag (sc-rt-logger's SCRT_LOG_ACK, which only paces
    the bench)."""
    return bus._lc if isinstance(bus, AuthLCM) else bus


def open_bus(url: str, key: bytes | None = None, counters: Counter | None = None) -> Any:
    """LCM on url; with a key, authenticated (AuthLCM)."""
    lc = open_lcm(url)
    return lc if key is None else AuthLCM(lc, key, counters)
