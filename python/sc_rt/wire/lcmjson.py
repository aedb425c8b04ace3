"""JSON encoding of LCM messages (as ``lcmdefs`` describes it): the
generic path (a decoded message to JSON) and a fast one for the fixed-size
types (rows of their numpy structured records through a %-template)."""

from __future__ import annotations

import json
import math

import numpy as np

__all__ = ["json_value", "dumps", "count_none", "RowEncoder"]


def json_value(v):
    """A decoded value as JSON data: non-finite floats None, bytes a list."""
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, (list, tuple)):
        return [json_value(x) for x in v]
    if isinstance(v, (bytes, bytearray)):
        return list(v)
    if hasattr(v, "__slots__") and hasattr(v, "_get_packed_fingerprint"):
        return {k: json_value(getattr(v, k)) for k in v.__slots__}
    return v


def dumps(obj) -> bytes:
    """Compact JSON; raises ValueError on NaN (use json_value first)."""
    return json.dumps(obj, separators=(",", ":"), allow_nan=False).encode()


class RowEncoder:
    """JSON rows of one fixed-size type from its structured records, with a
    %-template (str of a finite float is its shortest repr, valid JSON);
    rows with a non-finite value go through the generic path."""

    def __init__(self, cls):
        self.cls = cls
        self.names = list(cls.__slots__)
        self.bools = {n for n, tn in zip(cls.__slots__, cls.__typenames__) if tn == "boolean"}
        dims = dict(zip(cls.__slots__, cls.__dimensions__))
        self.ok = not any(dims[n] for n in self.bools)
        self.template = "{" + ",".join(f'"{n}":%s' for n in self.names) + "}"

    def rows(self, rec: np.ndarray, counter: list[int]) -> list[bytes]:
        n = len(rec)
        if n == 0:
            return []
        finite = np.ones(n, bool)
        cols = []
        for name in self.names:
            col = rec[name]
            if col.dtype.kind == "f":
                finite &= np.isfinite(col).reshape(n, -1).all(axis=1)
                cols.append(col.astype(float).tolist())
            elif name in self.bools:
                cols.append(np.where(col != 0, "true", "false").tolist())
            else:
                cols.append(col.astype(np.int64).tolist())
        t = self.template
        out = [(t % row).encode() for row in zip(*cols)]
        for i in np.nonzero(~finite)[0]:
            d = {}
            for name, c in zip(self.names, cols):
                v = c[i]
                d[name] = (v == "true") if name in self.bools else json_value(v)
            counter[0] += count_none(d)
            out[i] = dumps(d)
        return out


def count_none(v) -> int:
    """How many values of a JSON value are null."""
    if v is None:
        return 1
    if isinstance(v, dict):
        return sum(count_none(x) for x in v.values())
    if isinstance(v, list):
        return sum(count_none(x) for x in v)
    return 0
