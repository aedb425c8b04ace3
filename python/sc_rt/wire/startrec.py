"""The run's start and end records in its log.

The start record, on SCRT_HIL_START: JSON (UTF-8) with ``"sc_rt_start": 1``
and what the run is (scenario, mode, trigger, rate, duration, time scale,
the law's identity, run id, sc-rt's version). ``sc-rt hil`` publishes it
before anything else, so it is the log's first message; ``sc-rt report``,
the MCAP export and ``sc-rt spy`` read it instead of guessing. An older log
carries the scenario name as raw bytes there.

The end record, on SCRT_HIL_END (the end marker ``sc-rt hil`` waits to see
in the log): JSON with ``"sc_rt_end": 1`` and what the bench saw that no
message of the run shows: why it stopped early (``stopped``: a state left
unanswered, a controller that died or was killed over its memory limit, an
interrupt) and how the controller ended (``died``). ``sc-rt report`` takes
those reasons from it and says so; a log without one (older, or cut before
its end) is reported with "not in the log" instead of a guess."""

from __future__ import annotations

import json
from typing import Any

__all__ = ["encode_start", "decode_start", "start_record", "encode_end", "end_record"]


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


def encode_end(record: dict[str, Any]) -> bytes:
    """The payload of an end record (``record`` without the marker)."""
    return json.dumps({"sc_rt_end": 1, **record}, separators=(",", ":")).encode()


def end_record(events: list) -> dict[str, Any] | None:
    """The end record among log ``events`` (the marker is re-sent until the
    logger has it: the first copy); None when there is none (an older log,
    whose marker is the scenario's name, or a log cut before its end)."""
    for e in events:
        try:
            d = json.loads(bytes(e[3]).decode("utf-8"))
        except (UnicodeDecodeError, ValueError):
            continue
        if isinstance(d, dict) and d.get("sc_rt_end") == 1:
            return d
    return None
