"""What an LCM channel is, for the MCAP export and the live server alike:
its type (by its name, else by the fingerprint of a message of ours), its
JSON schema and channel metadata, and its messages as JSON rows.

One code path for both consumers (``mcap_export`` writes the rows to a
file, ``sc_rt.live`` to a Foxglove WebSocket server), so that a layout
made for a recording works live: same topics, schemas and values.
"""

from __future__ import annotations

import base64
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from sc_rt.wire.codec import TYPES, decode_any, identify, numpy_dtype
from sc_rt.wire.legacy import decode_current
from sc_rt.wire.lcmdefs import LcmStruct, json_schema
from sc_rt.wire.lcmio import CHANNELS
from sc_rt.wire.lcmjson import RowEncoder, count_none, dumps, json_value

__all__ = ["RAW_SCHEMA", "named_type", "typed_by_content", "channel_schema", "channel_metadata", "raw_row",
           "JsonRows", "Decoded", "MAX_UTIME"]

#: [us] a utime above this is no plausible clock (its ns overflow MCAP's uint64)
MAX_UTIME = (1 << 63) // 1000

RAW_SCHEMA = {
    "title": "sc_rt.lcm_raw_event",
    "description": "An LCM log event carried as its raw bytes (not one well-formed message of its channel's type)",
    "type": "object",
    "properties": {
        "lcm_channel": {"type": "string", "description": "LCM channel (bytes that are not UTF-8 as \\x escapes)"},
        "reason": {"type": "string",
                   "description": "foreign_channel, unknown_type, malformed, trailing_bytes, channel_not_utf8"},
        "size": {"type": "integer", "minimum": 0, "description": "[bytes]"},
        "data": {"type": "string", "contentEncoding": "base64", "description": "the event's bytes"},
    },
    "required": ["lcm_channel", "reason", "size", "data"], "additionalProperties": False,
}

_BY_BASE = {base: TYPES[tn] for base, (tn, _w, _r) in CHANNELS.items() if tn in TYPES}


def named_type(name: str) -> tuple[type | None, str | None]:
    """(class, prefix) of a channel named ``[prefix]SCRT_...`` (lcmio.CHANNELS), else (None, None)."""
    for base, cls in _BY_BASE.items():
        if name.endswith(base):
            return cls, name[: -len(base)]
    return None, None


def typed_by_content(data: bytes) -> type | None:
    """The class of a channel of no known name, from one of its messages: one
    well-formed message of ours, else None."""
    cls = identify(data)
    return cls if cls is not None and decode_any(data)[0] is cls else None


def channel_schema(cls: type, defs: dict[str, LcmStruct], torque_command: bool = False) -> tuple[str, dict]:
    """(schema name, JSON schema) of the channel of type ``cls``. With
    ``torque_command`` (the bench's wheels take motor torques: its
    controller_config_t's ``wheel_torque_command``) the wheel-command fields
    (the "command" unit rule of sc_rt.results.record.fields: u_cmd, u_sat;
    not the "law" rule's, the law's own states in the law's unit) say
    [N m], not the .lcm comment's [rad/s^2]."""
    s = defs[cls.__name__]
    schema = json_schema(s, defs)
    if torque_command:
        from sc_rt.results.record.fields import FIELD

        for name, prop in schema.get("properties", {}).items():
            f = FIELD.get(name)
            if f is not None and f.unit_rule == "command" and "description" in prop:
                prop["description"] = (prop["description"].replace("[rad/s^2]", "[N m]")
                                       .replace("wheel acceleration", "motor torque")
                                       + " (this bench's wheels take motor torques)")
    return s.full_name, schema


def channel_metadata(name: str, schema_name: str) -> dict[str, str]:
    """The metadata of the JSON channel of LCM channel ``name``."""
    return {"lcm_channel": name, "lcm_type": schema_name}


def raw_row(name: str, data: bytes, reason: str) -> bytes:
    """One event carried raw (RAW_SCHEMA)."""
    return dumps({"lcm_channel": name, "reason": reason, "size": len(data),
                  "data": base64.b64encode(data).decode()})


@dataclass
class Decoded:
    """The JSON rows of a batch of messages of one channel.

    Attributes
    ----------
    pos : list of int
        The positions (in the batch) of the well-formed messages.
    rows : list of bytes
        Their JSON rows, in the order of ``pos``.
    utime : list of int
        Their ``utime`` fields [us] (0: none).
    rec : numpy.ndarray or None
        Their decoded records (fixed-size types), for the derived channels.
    bad : dict
        Position -> why that message is not one of the type (raw_row's reason).
    """

    pos: list[int] = field(default_factory=list)
    rows: list[bytes] = field(default_factory=list)
    utime: list[int] = field(default_factory=list)
    rec: np.ndarray | None = None
    bad: dict[int, str] = field(default_factory=dict)


def _kind(cls, d: bytes, dt) -> str:
    """Why ``d`` is not one message of fixed-size ``cls`` (as decode_array counts)."""
    if d[:8] != cls._get_packed_fingerprint():
        return "unknown_type"
    return "malformed" if dt is None or len(d) < dt.itemsize else "trailing_bytes"


class JsonRows:
    """Messages of one LCM type as JSON rows: the fixed-size types decoded
    many at once (numpy records, ``RowEncoder``), the others one by one
    under guard (``decode_any``, ``json_value``).

    Parameters
    ----------
    cls : type
        The generated ``sc_rt_lcm`` class.
    """

    def __init__(self, cls: type):
        self.cls = cls
        self.dt = numpy_dtype(cls)
        self.enc = RowEncoder(cls) if self.dt is not None else None

    def decode(self, datas: list[bytes], kinds: Counter, non_finite: list[int]) -> Decoded:
        """The rows of ``datas``; undecodable ones counted by kind in
        ``kinds``, non-finite values (written null) in ``non_finite[0]``."""
        out = Decoded()
        cls = self.cls
        if self.enc is not None and self.enc.ok:
            rec, pos = decode_current(cls, datas, kinds)  # an older layout (wire/legacy.py) too
            out.rec, out.pos = rec, pos.tolist()
            out.rows = self.enc.rows(rec, non_finite)
            out.utime = (rec["utime"].astype(np.int64).tolist() if "utime" in (rec.dtype.names or ())
                         else [0] * len(out.pos))
            good = set(out.pos)
            out.bad = {j: _kind(cls, d, self.dt) for j, d in enumerate(datas) if j not in good}
            return out
        for j, d in enumerate(datas):
            before = Counter(kinds)
            got, msg = decode_any(d, kinds)
            if got is not cls:
                if got is not None:  # a valid message of another of our types
                    kinds["unknown_type"] += 1
                out.bad[j] = next(iter(kinds - before), "unknown_type")
                continue
            obj = json_value(msg)
            non_finite[0] += count_none(obj)
            u = getattr(msg, "utime", 0)
            out.pos.append(j)
            out.rows.append(dumps(obj))
            out.utime.append(u if isinstance(u, int) else 0)
        return out
