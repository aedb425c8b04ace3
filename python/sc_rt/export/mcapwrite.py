"""A chunked, indexed MCAP writer for many small messages, added in batches.

The ``mcap`` package's ``Writer`` builds every message as an object and
writes it field by field (about half of an export's time); here a batch's
message records are packed with one ``struct`` call each and joined, and
the message indexes are numpy arrays. Everything else (header, schemas,
channels, statistics, chunk and metadata indexes, summary offsets, footer)
is written with the ``mcap`` package's own record classes. Layout as the
package's writer: schemas and channels in the data section before the
chunks that use them and repeated in the summary; per chunk its message
indexes; a summary with statistics, chunk and metadata indexes and summary
offsets. ``tests/test_mcap.py`` reads the files back with ``mcap.reader``.
"""

from __future__ import annotations

import struct
import zlib
from collections import Counter
from typing import IO

import numpy as np
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (Channel, ChunkIndex, DataEnd, Footer, Header, Metadata, MetadataIndex, Schema,
                          Statistics, SummaryOffset)

__all__ = ["BatchWriter", "MAGIC"]

MAGIC = b"\x89MCAP0\r\n"
_MSG = struct.Struct("<BQHIQQ")  # opcode, record length, channel, sequence, log_time, publish_time
_MSG_FIXED = 2 + 4 + 8 + 8


class BatchWriter:
    def __init__(self, stream: IO[bytes], *, compression: str = "zstd", chunk_size: int = 1 << 20):
        if compression == "zstd":
            import zstandard

            self._compress = zstandard.ZstdCompressor().compress
        elif compression == "":
            self._compress = None
        else:
            raise ValueError(f"compression must be 'zstd' or '', got {compression!r}")
        self.compression = compression
        self.out = stream
        self.chunk_size = chunk_size
        self.schemas: list[Schema] = []
        self.channels: list[Channel] = []
        self.chunk_indexes: list[ChunkIndex] = []
        self.metadata_indexes: list[MetadataIndex] = []
        self.counts: Counter = Counter()
        self.n_messages = 0
        self.t_min: int | None = None
        self.t_max = 0
        self._parts: list[bytes] = []
        self._ch: list[np.ndarray] = []
        self._lt: list[np.ndarray] = []
        self._sizes: list[np.ndarray] = []
        self._pending = 0

    def _record(self, rec) -> int:
        """Write one record of the mcap package; returns its offset."""
        b = RecordBuilder()
        rec.write(b)
        pos = self.out.tell()
        self.out.write(b.end())
        return pos

    def start(self, profile: str = "", library: str = "sc-rt") -> None:
        self.out.write(MAGIC)
        self._record(Header(profile, library))

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        s = Schema(id=len(self.schemas) + 1, name=name, encoding=encoding, data=data)
        self.schemas.append(s)
        self._record(s)
        return s.id

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: dict[str, str] | None = None) -> int:
        if len(self.channels) >= 0xFFFF:
            raise ValueError("an MCAP file holds at most 65535 channels")
        c = Channel(id=len(self.channels) + 1, topic=topic, message_encoding=message_encoding,
                    schema_id=schema_id, metadata=dict(metadata or {}))
        self.channels.append(c)
        self._record(c)
        return c.id

    def add_messages(self, channel: list[int], log_time: list[int], publish_time: list[int],
                     sequence: list[int], data: list[bytes]) -> None:
        """Messages in this order (times [ns] >= 0, sequence < 2^32)."""
        n = len(data)
        if n == 0:
            return
        pack = _MSG.pack
        parts = self._parts
        for c, lt, pt, sq, d in zip(channel, log_time, publish_time, sequence, data):
            parts.append(pack(5, _MSG_FIXED + len(d), c, sq, lt, pt))
            parts.append(d)
        ch = np.asarray(channel, np.uint16)
        lt = np.asarray(log_time, np.uint64)
        sizes = np.fromiter(map(len, data), np.int64, n) + _MSG.size
        self._ch.append(ch)
        self._lt.append(lt)
        self._sizes.append(sizes)
        self.counts.update(dict(zip(*np.unique(ch, return_counts=True))))
        self.n_messages += n
        lo, hi = int(lt.min()), int(lt.max())
        self.t_min = lo if self.t_min is None else min(self.t_min, lo)
        self.t_max = max(self.t_max, hi)
        self._pending += int(sizes.sum())
        if self._pending >= self.chunk_size:
            self._chunk()

    def _chunk(self) -> None:
        if not self._parts:
            return
        body = b"".join(self._parts)
        ch, lt, sizes = (np.concatenate(v) for v in (self._ch, self._lt, self._sizes))
        self._parts, self._ch, self._lt, self._sizes, self._pending = [], [], [], [], 0
        data = self._compress(body) if self._compress else body
        comp = self.compression.encode()
        head = struct.pack("<BQQQQI", Opcode.CHUNK, 8 + 8 + 8 + 4 + 4 + len(comp) + 8 + len(data),
                           int(lt.min()), int(lt.max()), len(body), zlib.crc32(body))
        start = self.out.tell()
        self.out.write(head + struct.pack("<I", len(comp)) + comp + struct.pack("<Q", len(data)))
        self.out.write(data)
        chunk_len = self.out.tell() - start
        offsets = np.concatenate(([0], np.cumsum(sizes)[:-1])).astype(np.uint64)
        index_start = self.out.tell()
        index_offsets = {}
        order = np.argsort(ch, kind="stable")
        ids, first = np.unique(ch[order], return_index=True)
        bounds = list(first) + [len(order)]
        for j, cid in enumerate(ids.tolist()):
            sel = order[bounds[j]:bounds[j + 1]]
            entries = np.empty(len(sel), dtype=[("t", "<u8"), ("o", "<u8")])
            entries["t"], entries["o"] = lt[sel], offsets[sel]
            raw = entries.tobytes()
            index_offsets[cid] = self.out.tell()
            self.out.write(struct.pack("<BQHI", Opcode.MESSAGE_INDEX, 2 + 4 + len(raw), cid, len(raw)) + raw)
        self.chunk_indexes.append(ChunkIndex(
            message_start_time=int(lt.min()), message_end_time=int(lt.max()), chunk_start_offset=start,
            chunk_length=chunk_len, message_index_offsets=index_offsets,
            message_index_length=self.out.tell() - index_start, compression=self.compression,
            compressed_size=len(data), uncompressed_size=len(body)))

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        self._chunk()
        b = RecordBuilder()
        Metadata(name=name, metadata=data).write(b)
        raw = b.end()
        pos = self.out.tell()
        self.out.write(raw)
        self.metadata_indexes.append(MetadataIndex(offset=pos, length=len(raw), name=name))

    def finish(self) -> None:
        self._chunk()
        self._record(DataEnd(0))
        summary_start = self.out.tell()
        b = RecordBuilder()
        offsets = []
        stats = Statistics(message_count=self.n_messages, schema_count=len(self.schemas),
                           channel_count=len(self.channels), attachment_count=0,
                           metadata_count=len(self.metadata_indexes), chunk_count=len(self.chunk_indexes),
                           message_start_time=self.t_min or 0, message_end_time=self.t_max,
                           channel_message_counts={int(k): int(v) for k, v in sorted(self.counts.items())})
        for op, recs in ((Opcode.SCHEMA, self.schemas), (Opcode.CHANNEL, self.channels),
                         (Opcode.STATISTICS, [stats]), (Opcode.CHUNK_INDEX, self.chunk_indexes),
                         (Opcode.METADATA_INDEX, self.metadata_indexes)):
            g = b.count
            for r in recs:
                r.write(b)
            offsets.append(SummaryOffset(group_opcode=op, group_start=summary_start + g, group_length=b.count - g))
        summary_offset_start = summary_start + b.count
        for o in offsets:
            o.write(b)
        summary = b.end()
        crc = zlib.crc32(summary)
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, summary_offset_start), crc)
        self.out.write(summary)
        self._record(Footer(summary_start=summary_start, summary_offset_start=summary_offset_start,
                            summary_crc=crc))
        self.out.write(MAGIC)
