"""The wire types as data: which ``sc_rt_lcm`` class a message is (by its
fingerprint), fast vectorised decoding of the fixed-size types (numpy
structured arrays over the raw big-endian bytes), and where the ``.lcm``
sources are (for ``sc-rt lcm-spy``'s Java types).

Everything is derived from the generated Python classes (``__slots__``,
``__typenames__``, ``__dimensions__``), so a change of a ``.lcm`` file needs
no edit here.
"""

from __future__ import annotations

import struct
from collections import Counter
from pathlib import Path

import numpy as np
import sc_rt_lcm

from sc_rt import _core

__all__ = ["TYPES", "BY_FINGERPRINT", "identify", "decode_any", "numpy_dtype", "decode_array",
           "lcm_sources", "to_plain", "decode_as", "DECODE_ERRORS", "STATUS_RUN_FIELDS", "STATUS_TIMING_FIELDS",
           "STATUS_NAV_FIELDS", "STATUS_FROM_COMMANDS"]


def _types() -> dict[str, type]:
    out = {}
    for name in dir(sc_rt_lcm):
        cls = getattr(sc_rt_lcm, name)
        if isinstance(cls, type) and hasattr(cls, "_get_packed_fingerprint"):
            out[name] = cls
    return out


#: type name -> generated class
TYPES: dict[str, type] = _types()
#: 8-byte packed fingerprint -> generated class
BY_FINGERPRINT: dict[bytes, type] = {c._get_packed_fingerprint(): c for c in TYPES.values()}

# LCM primitive -> numpy (big-endian, as on the wire)
_NP = {"int8_t": "i1", "int16_t": ">i2", "int32_t": ">i4", "int64_t": ">i8", "byte": "u1",
       "float": ">f4", "double": ">f8", "boolean": "i1"}

_DTYPES: dict[type, np.dtype | None] = {}

# The status-to-run mapping, read from the core's field table
# (_core.FIELD_TABLE, cpp/include/sc_rt/fields.hpp): a field with bus = true
# is in controller_status_t under its own name, because the status type's
# telemetry block is generated from the same table at build time.
#: Run fields a controller_status_t carries for the state it used, same name
#: on both sides (the command's own fields, u_cmd, u_sat, flags and mode,
#: come from wheel_cmd_t).
STATUS_RUN_FIELDS: tuple[str, ...] = tuple(r["name"] for r in _core.FIELD_TABLE if r["bus"] and r["group"] == "loop")
#: Run fields a status carries (its telemetry: the MCAP, the live view) that a
#: bench run's record takes from the command the plant applied instead, as
#: ``u_cmd`` from wheel_cmd_t: the rods' commands held over the row (rod_cmd_t;
#: in real time the newest, which may answer an earlier state than the status).
STATUS_FROM_COMMANDS: tuple[str, ...] = ("rod_dipole_cmd",)
#: The estimator's run fields in controller_status_t (a [sensors] run; its
#: nav_flags are OR-ed into the row's flags, as the offline loop does).
STATUS_NAV_FIELDS: tuple[str, ...] = tuple(r["name"] for r in _core.FIELD_TABLE if r["bus"] and r["group"] == "nav")
#: The controller's own timing measurements in controller_status_t.
STATUS_TIMING_FIELDS: tuple[str, ...] = ("wake_lateness_us", "compute_us", "state_age_us")
#: Controller-sourced run fields a status does NOT carry, and where they come
#: from instead.
STATUS_NOT_CARRIED: dict[str, str] = {
    "u_cmd": "wheel_cmd_t (the command itself)", "u_sat": "wheel_cmd_t", "flags": "wheel_cmd_t",
    "ctrl_mode": "wheel_cmd_t", "latency_us": "the emulator's receipt time of the command",
    "tick_lateness_us": "the emulator's own loop", "state_log_us": "lcm-logger's receive time of the state",
}


def identify(data: bytes) -> type | None:
    """The sc_rt_lcm class whose fingerprint starts ``data``, else None."""
    return BY_FINGERPRINT.get(bytes(data[:8]))


def decode_any(data: bytes, counts: Counter | None = None):
    """(class, message) for a message of any of our types, (None, None) for
    anything else; never raises. Kinds counted in ``counts``:
    ``unknown_type``, ``malformed`` (truncated or bad content),
    ``trailing_bytes`` (a valid message followed by extra bytes)."""
    counts = Counter() if counts is None else counts
    cls = identify(data)
    if cls is None:
        counts["unknown_type"] += 1
        return None, None
    msg = decode_as(cls, data, counts)
    return (cls, msg) if msg is not None else (None, None)


#: What lcm's generated Python decode raises on hostile bytes (ValueError on
#: a wrong fingerprint, struct.error on truncation, the rest on bad content).
DECODE_ERRORS = (ValueError, struct.error, IndexError, UnicodeDecodeError, TypeError, OverflowError)


def decode_as(cls, data: bytes, counts: Counter) -> object | None:
    """``data`` decoded as exactly one message of ``cls``, else None with
    the kind counted: ``trailing_bytes`` (a valid message followed by extra
    bytes: lcm's decode would accept it), ``malformed`` (anything else).
    The one guarded decoder of the project: never raises."""
    dt = numpy_dtype(cls)
    if dt is not None and len(data) != dt.itemsize:
        longer = len(data) > dt.itemsize and bytes(data[:8]) == cls._get_packed_fingerprint()
        counts["trailing_bytes" if longer else "malformed"] += 1
        return None
    try:
        msg = cls.decode(bytes(data))
    except DECODE_ERRORS:
        counts["malformed"] += 1
        return None
    if dt is None and len(msg.encode()) != len(data):
        counts["trailing_bytes"] += 1
        return None
    return msg


def numpy_dtype(cls) -> np.dtype | None:
    """The packed big-endian layout of a fixed-size type (fingerprint first,
    as field ``_fp``), None for a type with strings or variable arrays."""
    if cls in _DTYPES:
        return _DTYPES[cls]
    fields: list[tuple] = [("_fp", ">u8")]
    dt: np.dtype | None
    try:
        for name, tn, dims in zip(cls.__slots__, cls.__typenames__, cls.__dimensions__):
            if tn not in _NP or (dims is not None and not all(isinstance(d, int) for d in dims)):
                raise LookupError(name)
            fields.append((name, _NP[tn], tuple(dims)) if dims else (name, _NP[tn]))
        dt = np.dtype(fields)
        if dt.itemsize != len(cls().encode()):  # pragma: no cover - guards a new lcm-gen
            dt = None
    except LookupError:
        dt = None
    _DTYPES[cls] = dt
    return dt


def decode_array(cls, datas: list[bytes], counts: Counter | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Decode many messages of one fixed-size type at once.

    Returns (records, index): a structured array of the well-formed
    messages and their positions in ``datas``. The rest are counted in
    ``counts`` by kind (``unknown_type``: another fingerprint,
    ``malformed``: too short, ``trailing_bytes``: too long)."""
    counts = Counter() if counts is None else counts
    dt = numpy_dtype(cls)
    if dt is None:
        raise ValueError(f"{cls.__name__} has no fixed layout")
    size, fp = dt.itemsize, cls._get_packed_fingerprint()
    fp_int = int.from_bytes(fp, "big")
    n = len(datas)
    lens = np.fromiter(map(len, datas), np.int64, n)
    sized = np.nonzero(lens == size)[0]
    for i in np.nonzero(lens != size)[0]:  # the few odd ones, one by one
        d = datas[i]
        counts["unknown_type" if d[:8] != fp else
               "malformed" if len(d) < size else "trailing_bytes"] += 1
    buf = b"".join(datas) if sized.size == n else b"".join(datas[i] for i in sized)
    rec = np.frombuffer(buf, dtype=dt) if buf else np.zeros(0, dt)
    ok = rec["_fp"] == fp_int
    if not np.all(ok):
        counts["unknown_type"] += int(np.count_nonzero(~ok))
        rec, sized = rec[ok], sized[ok]
    return rec, sized.astype(np.int64)


def to_plain(msg) -> dict:
    """A decoded message as a JSON-ready dict (tuples to lists, bytes to str)."""
    out = {}
    for name in msg.__slots__:
        v = getattr(msg, name)
        if isinstance(v, (tuple, list)):
            v = [list(x) if isinstance(x, (tuple, list)) else x for x in v]
        elif isinstance(v, bytes):
            v = v.decode("utf-8", "replace")
        out[name] = v
    return out


def lcm_sources() -> list[Path]:
    """The ``.lcm`` files of the installed types: the copy installed with the
    package (``sc_rt/lcmtypes``, matching the built ``sc_rt_lcm``), else the
    source tree's ``lcmtypes/``."""
    import sc_rt

    for base in list(sc_rt.__path__):
        d = Path(base) / "lcmtypes"
        files = sorted(d.glob("*.lcm")) if d.is_dir() else []
        if files:
            return files
    d = Path(sc_rt.__file__).resolve().parents[2] / "lcmtypes"
    files = sorted(d.glob("*.lcm"))
    if not files:
        raise FileNotFoundError("the .lcm sources of sc_rt_lcm were not found (sc_rt/lcmtypes "
                                "in the installed package, or lcmtypes/ in the source tree)")
    return files
