"""``sc-rt export LOG --mcap OUT``: every event of an ``lcm-logger`` log into
an MCAP file for Foxglove and PlotJuggler.

- One MCAP channel per LCM channel (topic = the LCM channel name), message
  encoding ``json``, schema encoding ``jsonschema`` with the schema
  generated from the ``.lcm`` definitions (``lcmdefs``). log_time is the
  logger's receive time of the event, publish_time the message's ``utime``
  (the publisher's clock) where it has a plausible one, else log_time;
  sequence is the log's event number (mod 2^32).
- The type of a channel: by its name (``[prefix]SCRT_STATE`` ... as in
  ``lcmio.CHANNELS``), else by the fingerprint of its first message of one
  of our types.
- Events that are not one well-formed message of their channel's type are
  counted by kind and carried as raw bytes (base64, schema
  ``sc_rt.lcm_raw_event``) on ``<channel>/undecodable``; channels of no
  type of ours are carried raw under their own name. Nothing is dropped.
- Derived channels (``mcap_derived``): ``/tf`` (``foxglove.FrameTransform``:
  frames B and D relative to N, from ``plant_state_t.sigma_BN`` and
  ``guidance_t.sigma_DN``, or ``controller_status_t.sigma_DN`` in a log
  without guidance), ``/derived/pointing`` (pointing errors
  4 atan|sigma_BD|, named: the true error from ``plant_state_t.sigma_BN``
  of the status's state against its ``sigma_DN``, the law's from the
  status, the knowledge error against its estimate; and the PPC bound
  chi(t) of the logged ``controller_config_t``, in arcsec) and
  ``/derived/wheels`` (wheel speeds).

The file is written under a temporary name next to OUT and renamed at the
end: OUT is either complete or untouched.
"""

from __future__ import annotations

import json
import os
import time
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sc_rt.wire.lcmdefs import load_definitions
from sc_rt.wire.lcmjson import dumps
from sc_rt.export.channels import (MAX_UTIME, RAW_SCHEMA, JsonRows, channel_metadata, channel_schema, named_type,
                                   raw_row, typed_by_content)
from sc_rt.export.mcap_derived import Deriver, derive_order
from sc_rt.logs.lcmlog import LogDamaged, LogScan, read_events
from sc_rt.wire.startrec import start_record

__all__ = ["ExportError", "ExportSummary", "export_mcap", "check_output", "RAW_SCHEMA"]

BATCH = 1 << 15
#: MCAP channel ids are 16 bit: further raw channels share one overflow channel
MAX_CHANNELS = 60000
_MAX_LOG_US = ((1 << 64) - 1) // 1000


class ExportError(ValueError):
    """Bad input or output of an export (one line, names the option)."""


@dataclass
class ExportSummary:
    log: str
    out: str
    events: int = 0
    messages: int = 0
    seconds: float = 0.0
    channels: dict[str, dict[str, Any]] = field(default_factory=dict)
    undecodable: int = 0
    undecodable_kinds: dict[str, int] = field(default_factory=dict)
    foreign_events: int = 0
    derived: dict[str, int] = field(default_factory=dict)
    non_finite_as_null: int = 0
    timestamps_clamped: int = 0
    skipped_bytes: int = 0
    torn_tail_bytes: int = 0
    damaged_at: list[int] = field(default_factory=list)

    @property
    def events_per_s(self) -> float | None:
        return self.events / self.seconds if self.seconds > 0 else None

    def as_dict(self) -> dict[str, Any]:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        d["events_per_s"] = self.events_per_s
        return d


class _Chan:
    __slots__ = ("name", "utf8", "cls", "json_id", "raw_id", "prefix", "count", "json", "raw", "kinds")

    def __init__(self, name: str, utf8: bool, cls):
        self.name, self.utf8, self.cls = name, utf8, cls
        self.json_id = self.raw_id = 0
        self.prefix = None
        self.count = self.json = self.raw = 0
        self.kinds: Counter = Counter()


class _Exporter:
    def __init__(self, writer, log_name: str):
        self.w = writer
        self.defs = load_definitions()
        self.schemas: dict[str, int] = {}
        self.chans: dict[bytes, _Chan] = {}
        self.derived_ids: dict[str, int] = {}
        self.deriver = Deriver()
        self.derived: Counter = Counter()
        self.non_finite = [0]
        self.clamped = 0  # log timestamps outside the uint64 ns range of MCAP
        self.n_channels = 0
        self.encoders: dict[type, JsonRows] = {}
        self.log_name = log_name

    # --- registration ------------------------------------------------------
    def _schema(self, name: str, schema: dict) -> int:
        if name not in self.schemas:
            self.schemas[name] = self.w.register_schema(name, "jsonschema", dumps(schema))
        return self.schemas[name]

    def _channel(self, topic: str, schema_name: str, schema: dict, meta: dict[str, str]) -> int:
        if self.n_channels >= MAX_CHANNELS:
            topic, meta = "lcm_raw_overflow", {"content": "raw events of channels beyond the MCAP channel limit"}
            if "overflow" in self.derived_ids:
                return self.derived_ids["overflow"]
        self.n_channels += 1
        cid = self.w.register_channel(topic, "json", self._schema(schema_name, schema), meta)
        if topic == "lcm_raw_overflow":
            self.derived_ids["overflow"] = cid
        return cid

    def _derived(self, topic: str, schema_name: str, schema: dict) -> int:
        if topic not in self.derived_ids:
            self.derived_ids[topic] = self._channel(topic, schema_name, schema, {"derived": "sc-rt export"})
        return self.derived_ids[topic]

    def _chan(self, ch: bytes, data: bytes) -> _Chan:
        c = self.chans.get(ch)
        if c is None:
            try:
                name, utf8 = ch.decode("utf-8"), True
                cls, prefix = named_type(name)
            except UnicodeDecodeError:
                name, utf8, cls, prefix = ch.decode("utf-8", "backslashreplace"), False, None, None
            c = self.chans[ch] = _Chan(name, utf8, cls)
            c.prefix = prefix
        if c.cls is None and c.utf8 and not c.raw_id:
            c.cls = typed_by_content(data)  # an unnamed channel: typed by its first message of ours
        if c.cls is not None and not c.json_id:
            # the bench's wheel-command unit: its config comes first in a batch (derive_order)
            schema_name, schema = channel_schema(c.cls, self.defs, self.deriver.torque.get(c.prefix, False))
            c.json_id = self._channel(c.name, schema_name, schema, channel_metadata(c.name, schema_name))
        return c

    def _raw(self, c: _Chan, data: bytes, reason: str) -> bytes:
        if not c.raw_id:
            topic = c.name if c.cls is None else c.name + "/undecodable"
            c.raw_id = self._channel(topic, RAW_SCHEMA["title"], RAW_SCHEMA,
                                     {"lcm_channel": c.name, "content": "raw LCM events"})
        c.raw += 1
        return raw_row(c.name, data, reason)

    # --- one batch of events, written in log order --------------------------
    def batch(self, events: list) -> int:
        n = len(events)
        out: list = [None] * n  # (channel id, bytes, publish_ns or None)
        extra: dict[int, list] = defaultdict(list)  # event index -> derived (channel id, bytes)
        groups: dict[bytes, list[int]] = defaultdict(list)
        for i, e in enumerate(events):
            groups[e[2]].append(i)
        # configs first (the bound of this batch's statuses), then guidance (frame D), then the states
        # (the statuses' truth): mcap_derived.derive_order
        order = sorted(groups, key=derive_order)
        for ch in order:
            idx = groups[ch]
            c = self._chan(ch, events[idx[0]][3])
            c.count += len(idx)
            if c.cls is None:
                reason = "foreign_channel" if c.utf8 else "channel_not_utf8"
                for i in idx:
                    raw = self._raw(c, events[i][3], reason)
                    out[i] = (c.raw_id, raw, None)
                continue
            self._typed(c, [events[i] for i in idx], idx, out, extra)
        chans, logs, pubs, seqs, datas = [], [], [], [], []
        for i, e in enumerate(events):
            ts = e[1]
            if 0 <= ts <= _MAX_LOG_US:
                log_ns = ts * 1000
            else:  # MCAP times are uint64 ns: clamp, and count
                log_ns = 0 if ts < 0 else _MAX_LOG_US * 1000
                self.clamped += 1
            cid, data, pub = out[i]
            chans.append(cid)
            logs.append(log_ns)
            pubs.append(log_ns if pub is None else pub)
            seqs.append(e[0] & 0xFFFFFFFF)
            datas.append(data)
            more = extra.get(i)
            if more:
                for cid2, data2 in more:
                    chans.append(cid2)
                    logs.append(log_ns)
                    pubs.append(log_ns)
                    seqs.append(0)
                    datas.append(data2)
        self.w.add_messages(chans, logs, pubs, seqs, datas)
        return len(datas)

    def _typed(self, c: _Chan, evs: list, idx: list[int], out: list, extra) -> None:
        rows = self.encoders.get(c.cls)
        if rows is None:
            rows = self.encoders[c.cls] = JsonRows(c.cls)
        datas = [e[3] for e in evs]
        kinds: Counter = Counter()
        d = rows.decode(datas, kinds, self.non_finite)
        for p, row, u in zip(d.pos, d.rows, d.utime):
            out[idx[p]] = (c.json_id, row, u * 1000 if 0 < u < MAX_UTIME else None)
        if d.rec is not None:
            self._derive(c, d.rec, [idx[p] for p in d.pos], [evs[p][1] for p in d.pos], extra)
        elif c.cls.__name__ == "controller_config_t" and c.prefix is not None:
            for p in d.pos:
                self.deriver.config(c.prefix, datas[p])
        c.json += len(d.pos)
        c.kinds.update(kinds)
        for j in sorted(d.bad):
            raw = self._raw(c, datas[j], d.bad[j])
            out[idx[j]] = (c.raw_id, raw, None)

    # --- derived channels (mcap_derived.Deriver says which) ------------------
    def _derive(self, c: _Chan, rec, where: list[int], stamps: list[int], extra) -> None:
        for counter, topic, schema, msgs in self.deriver.messages(c.cls.__name__, c.prefix, rec, stamps):
            cid = self._derived(topic, schema["title"], schema)
            for i, m in zip(where, msgs):
                if m is None:
                    self.derived["skipped_non_finite"] += 1
                else:
                    extra[i].append((cid, m))
                    self.derived[counter] += 1


def check_output(out: Path) -> None:
    """Raise ExportError when ``out`` cannot be the MCAP file (checked before any work)."""
    if out.is_dir():
        raise ExportError(f"--mcap {out}: is a directory (give a file name, e.g. {out}/run.mcap)")
    probe = out.parent
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    if not probe.is_dir():
        raise ExportError(f"--mcap {out}: {probe} is not a directory")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ExportError(f"--mcap {out}: {probe} is not writable")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ExportError(f"--mcap {out}: cannot create its directory: {e.strerror or e}") from None


def export_mcap(log: str | Path, out: str | Path, *, partial: bool = False,
                compression: str = "zstd") -> ExportSummary:
    """Convert ``log`` into the MCAP file ``out`` (see the module's docstring).

    Raises FileNotFoundError (no log), ExportError (bad output path, or a
    damaged log without ``partial``)."""
    from sc_rt.export.mcapwrite import BatchWriter

    log, out = Path(log), Path(out)
    if not log.exists():
        raise FileNotFoundError(f"{log}: no such log")
    if log.is_dir():
        raise ExportError(f"{log}: is a directory, not an LCM log")
    check_output(out)
    if compression not in ("zstd", ""):
        raise ExportError(f"compression must be 'zstd' or '' (none), got {compression!r}")
    tmp = out.parent / f".{out.name}.{os.getpid()}.partial"
    t0 = time.perf_counter()
    scan = LogScan()
    summ = ExportSummary(str(log), str(out))
    try:
        with open(tmp, "wb") as f:
            w = BatchWriter(f, compression=compression)
            w.start(profile="", library="sc-rt export")
            ex = _Exporter(w, log.name)
            batch: list = []
            start = None  # the run's start record (sc-rt hil's SCRT_HIL_START), a metadata record below
            for ev in read_events(log, scan, partial):
                if start is None and ev[2].endswith(b"SCRT_HIL_START"):
                    start = start_record([ev])
                    # the law's telemetry names, for the bench of this prefix (its derived telemetry topic)
                    ex.deriver.start(ev[2][:-len(b"SCRT_HIL_START")].decode("utf-8", "replace"), start)
                batch.append(ev)
                if len(batch) >= BATCH:
                    summ.messages += ex.batch(batch)
                    batch = []
            if batch:
                summ.messages += ex.batch(batch)
            summ.events = scan.events
            _fill(summ, ex, scan)
            summ.seconds = time.perf_counter() - t0  # so far (the metadata's copy)
            w.add_metadata("sc_rt.export", {"source_log": log.name,
                                             "summary": json.dumps(summ.as_dict(), default=str)})
            if start is not None:  # what the run was (mode, trigger, rate, law identity), read, not guessed
                w.add_metadata("sc_rt.run", {k: v if isinstance(v, str) else json.dumps(v)
                                             for k, v in start.items()})
            w.finish()
        os.replace(tmp, out)
    except LogDamaged as e:
        hint = " (--partial exports the events that can be read)" if e.recoverable else ""
        raise ExportError(f"{e}{hint}") from None
    except OSError as e:
        if e.filename is not None and Path(e.filename) == log:
            raise ExportError(f"{log}: cannot read: {e.strerror or e}") from None
        raise ExportError(f"--mcap {out}: cannot write: {e.strerror or e}") from None
    finally:
        if tmp.exists():
            tmp.unlink()
    summ.seconds = time.perf_counter() - t0
    return summ


def _fill(summ: ExportSummary, ex: _Exporter, scan: LogScan) -> None:
    kinds: Counter = Counter()
    for c in ex.chans.values():
        summ.channels[c.name] = {"type": c.cls.__name__ if c.cls else None, "count": c.count,
                                 "json": c.json, "raw": c.raw, "undecodable_kinds": dict(c.kinds)}
        if c.cls is None:
            summ.foreign_events += c.count
        else:
            kinds.update(c.kinds)
    summ.undecodable_kinds = dict(kinds)
    summ.undecodable = int(sum(kinds.values()))
    summ.derived = dict(ex.derived)
    if ex.deriver.rejected_configs:  # a controller_config_t the core refused: no bound from it
        summ.derived["config_rejected"] = ex.deriver.rejected_configs
    summ.non_finite_as_null = ex.non_finite[0]
    summ.timestamps_clamped = ex.clamped
    summ.skipped_bytes, summ.torn_tail_bytes = scan.skipped_bytes, scan.torn_tail_bytes
    summ.damaged_at = list(scan.damaged_at)
