"""ROS 2 twins of the JSON topics (``sc-rt live --ros2``), for PlotJuggler.

PlotJuggler's Foxglove Bridge client offers its topic list only the
channels it can hand to its ROS 2 parser: message encoding ``cdr`` with a
``ros2msg`` schema. A JSON channel is therefore repeated, under
``/ros2/<topic>``, in that form: the definition is derived from the
channel's JSON schema (the one the export writes), the message from its
JSON row, so the values are the same ones.

JSON schema -> ROS 2 field: an integer with the range of an LCM type ->
``int8`` .. ``int64`` (``byte``: ``uint8``), other integers ``int64``;
number -> ``float64`` (JSON null, a value that was not finite: NaN);
boolean -> ``bool``; string -> ``string``; an object -> a message type of
its own (``sc_rt_live/<Name>``); an array of fixed length -> ``T[N]``
(nested arrays flattened, row major), else ``T[]``. A property a message
lacks is written as zero (NaN for a number).

CDR: little-endian plain CDR with its 4-byte encapsulation header, every
primitive aligned to its size (8 at most) from the end of that header;
strings and sequences with a uint32 length first.
"""

from __future__ import annotations

import json
import math
import re
import struct
from typing import Any

__all__ = ["Ros2Type", "twin_topic", "ENCAPSULATION"]

#: plain CDR, little endian
ENCAPSULATION = b"\x00\x01\x00\x00"
_SEP = "=" * 80
#: (JSON minimum, maximum) -> ROS 2 integer type
_INTS = {(-(2 ** 7), 2 ** 7 - 1): "int8", (-(2 ** 15), 2 ** 15 - 1): "int16", (-(2 ** 31), 2 ** 31 - 1): "int32",
         (-(2 ** 63), 2 ** 63 - 1): "int64", (0, 255): "uint8"}
#: ROS 2 primitive -> struct format (little endian)
_FMT = {"int8": "b", "uint8": "B", "int16": "h", "int32": "i", "int64": "q", "float64": "d", "bool": "?"}


def twin_topic(topic: str) -> str:
    """The topic of the ROS 2 twin of ``topic``."""
    return "/ros2" + ("" if topic.startswith("/") else "/") + topic


def _ident(text: str) -> str:
    """A message type's name: letters, digits and underscores, a capital first (``time`` -> ``Time``)."""
    name = re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_")
    name = "T" + name if not name or not name[0].isalpha() else name
    return name[0].upper() + name[1:]


class Ros2Type:
    """The ROS 2 form of one JSON schema: its ``ros2msg`` definition and an encoder.

    Parameters
    ----------
    schema : dict
        A JSON schema of an object (``sc_rt.export`` channels).
    """

    def __init__(self, schema: dict):
        self.subtypes: dict[str, list[str]] = {}
        self.fields = self._object(schema)
        self.name = "sc_rt_live/msg/" + _ident(schema.get("title", "Message").split(".")[-1])
        lines = [self._line(f) for f in self.fields]
        for sub, sub_lines in self.subtypes.items():
            lines += [_SEP, f"MSG: {sub}", *sub_lines]
        self.definition = "\n".join(lines) + "\n"

    # --- the definition ------------------------------------------------------
    def _object(self, schema: dict) -> list[tuple]:
        """[(name, kind, detail, shape)]: kind "prim" (detail: ROS type), "object" (detail: (type name,
        fields)); shape: None (one value), a fixed length, or -1 (a sequence)."""
        out = []
        for name, prop in (schema.get("properties") or {}).items():
            shape: int | None = None
            node = prop
            if node.get("type") == "array":
                n, fixed = 1, True
                while node.get("type") == "array":
                    if node.get("minItems") is not None and node.get("minItems") == node.get("maxItems"):
                        n *= node["minItems"]
                    else:
                        fixed = False
                    node = node.get("items") or {}
                shape = n if fixed else -1
            if node.get("type") == "object":
                tname = "sc_rt_live/" + _ident(node.get("title") or name)
                sub = self._object(node)
                if tname not in self.subtypes:
                    self.subtypes[tname] = [self._line(f) for f in sub]
                out.append((name, "object", (tname, sub), shape))
            else:
                out.append((name, "prim", self._prim(node), shape))
        return out

    @staticmethod
    def _prim(node: dict) -> str:
        t = node.get("type")
        if t == "integer":
            return _INTS.get((node.get("minimum"), node.get("maximum")), "int64")
        return {"number": "float64", "boolean": "bool", "string": "string"}.get(t, "string")

    @staticmethod
    def _line(f: tuple) -> str:
        name, kind, detail, shape = f
        t = detail[0] if kind == "object" else detail
        return f"{t}{'' if shape is None else '[]' if shape < 0 else f'[{shape}]'} {name}"

    # --- a message -------------------------------------------------------------
    def encode(self, row: bytes | dict) -> bytes:
        """The CDR bytes (with the encapsulation header) of a JSON row."""
        obj = json.loads(row) if isinstance(row, (bytes, str)) else row
        buf = bytearray()
        self._write(buf, self.fields, obj if isinstance(obj, dict) else {})
        return ENCAPSULATION + bytes(buf)

    def _write(self, buf: bytearray, fields: list[tuple], obj: dict) -> None:
        for name, kind, detail, shape in fields:
            v = obj.get(name)
            if shape is None:
                self._one(buf, kind, detail, v)
                continue
            items = _flat(v) if v is not None else []
            if shape < 0:
                _align(buf, 4)
                buf += struct.pack("<I", len(items))
            else:
                items = (items + [None] * shape)[:shape]
            for x in items:
                self._one(buf, kind, detail, x)

    def _one(self, buf: bytearray, kind: str, detail: Any, v: Any) -> None:
        if kind == "object":
            self._write(buf, detail[1], v if isinstance(v, dict) else {})
            return
        if detail == "string":
            data = (v if isinstance(v, str) else "" if v is None else json.dumps(v)).encode() + b"\0"
            _align(buf, 4)
            buf += struct.pack("<I", len(data)) + data
            return
        fmt = _FMT[detail]
        if v is None or isinstance(v, (dict, list, str)):
            v = math.nan if detail == "float64" else 0
        _align(buf, struct.calcsize(fmt))
        buf += struct.pack("<" + fmt, float(v) if detail == "float64" else bool(v) if detail == "bool" else int(v))


def _flat(v) -> list:
    if isinstance(v, list):
        return [x for item in v for x in _flat(item)] if any(isinstance(i, list) for i in v) else list(v)
    return [v]


def _align(buf: bytearray, n: int) -> None:
    n = min(n, 8)
    pad = -len(buf) % n
    if pad:
        buf += b"\0" * pad
