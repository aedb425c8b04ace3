"""The run's start record on SCRT_HIL_START: JSON (UTF-8) with
``"sc_rt_start": 1`` and what the run is (scenario, mode, trigger, rate,
duration, time scale, the law's identity, run id, sc-rt's version).
``sc-rt hil`` publishes it before anything else, so it is the log's first
message; ``sc-rt report``, the MCAP export and ``sc-rt spy`` read it instead
of guessing. An older log carries the scenario name as raw bytes there."""

from __future__ import annotations

import json
from typing import Any

__all__ = ["encode_start", "decode_start", "start_record"]


def encode_start(record: dict[str, Any]) -> bytes:
    """The payload of a start record (``record`` without the marker)."""
    return json.dumps({"sc_rt_start": 1, **record}, separators=(",", ":")).encode()


def decode_start(data: bytes) -> dict[str, Any] | None:
    """The start record in ``data``, None when it is not one."""
    try:
        d = json.loads(bytes(data).decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return None
    return d if isinstance(d, dict) and d.get("sc_rt_start") == 1 else None


def start_record(events: list) -> dict[str, Any] | None:
    """The first of log ``events`` (``(n, t, channel, data)``) that is a start
    record; None when there is none (an older log)."""
    for e in events:
        d = decode_start(e[3])
        if d is not None:
            return d
    return None
