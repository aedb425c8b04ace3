"""The emulator's per-state-seq inbox (emulator/inbox.py): two chunks of
rows live in the emulator's record, allocated and touched at start, the
older rows written to disk, so nothing grows as a run of 25 times as many
rows fills; seqs outside the run or the live rows counted and ignored; what
it keeps per row is what the disk estimate of a bench run counts
(cli/validate.py)."""

from __future__ import annotations

import subprocess
import sys
from collections import Counter
from pathlib import Path

import sc_rt_lcm

from sc_rt.emulator import process as emulator
from sc_rt.emulator.inbox import _CMD_LAYOUT, _STATUS_SIZE, Inbox, _cmd_of
from sc_rt.cli.validate import bus_bytes_per_row


def _rss_kb() -> int:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS:"))


def _cmd(seq: int, state_seq: int) -> bytes:
    m = sc_rt_lcm.wheel_cmd_t()
    m.utime, m.seq, m.session, m.state_seq = 1_000 + seq, seq, 77, state_seq
    m.u_cmd, m.u_sat, m.mode, m.flags = [0.1 * seq, -2.0, 3.5, 1e-9], [0.1, -0.2, 0.3, -0.4], 2, 1 << 11
    return m.encode()


def _status(state_seq: int) -> bytes:
    s = sc_rt_lcm.controller_status_t()
    s.cmd_seq, s.session, s.state_seq, s.steps = state_seq, 77, state_seq, state_seq + 1
    return s.encode()


def _put(inbox: Inbox, k: int, now: int = 5) -> None:
    data = _cmd(k, k)
    v = _CMD_LAYOUT.unpack_from(data, 8)
    inbox.put_cmd(k, data, _cmd_of(v), now, v[0])


_MEASURE = """
import sys
import time
from collections import Counter
from pathlib import Path
import test_inbox as T
from sc_rt.emulator.inbox import INBOX_COLUMNS
from sc_rt.results.record.store import ChunkFile, ChunkReader, RowRing
n, chunk = 100_000, 2_000
before = T._rss_kb()
f = ChunkFile(Path(sys.argv[1]) / "inbox.arrow", INBOX_COLUMNS)
ring = RowRing(INBOX_COLUMNS, chunk, lambda cols, base, rows: f.write(cols, rows))
inbox = T.Inbox(n, Counter(), ring)
allocated = T._rss_kb() - before
status = T._status(0)
for k in range(4 * chunk):  # warm up: the writer's buffers
    ring.reach(k + 1)
    T._put(inbox, k, time.monotonic_ns())
    inbox.put_status(k, status)
    inbox.published(k, 1_000 + k, time.monotonic_ns())
before = T._rss_kb()
for k in range(4 * chunk, n):
    ring.reach(k + 1)
    T._put(inbox, k, time.monotonic_ns())
    inbox.put_status(k, status)
    inbox.published(k, 1_000 + k, time.monotonic_ns())
grown = T._rss_kb() - before
ring.finish(n)
f.close()
r = ChunkReader(f.path)
print(r.rows, int((r.column("status_len") > 0).sum()), int((r.column("pub_wall_us") - 1_000 == range(n)).all()),
      allocated, grown)
"""


def test_two_chunks_live_then_flat_while_25_times_as_many_rows_fill(tmp_path):
    # a fresh interpreter: in this one, pages freed by earlier tests would
    # be resident already and hide the allocation
    r = subprocess.run([sys.executable, "-c", _MEASURE, str(tmp_path)], capture_output=True, text=True,
                       timeout=120, cwd=Path(__file__).parent)
    assert r.returncode == 0, r.stderr
    rows, statuses, times_ok, allocated_kb, grown_kb = map(int, r.stdout.split())
    assert (rows, statuses, times_ok) == (100_000, 100_000, 1)  # every row written, none lost
    assert allocated_kb * 1024 >= 0.9 * 2 * 2_000 * Inbox.BYTES_PER_ROW, allocated_kb  # resident from the start
    # 92,000 rows (85 MB of inbox) after the warm-up: the resident memory does not follow
    # them (it moves by 0-4 MB, the same for 40,000 or 400,000 rows: the allocators' own pools)
    assert grown_kb <= 8192, grown_kb


def test_commands_come_back_as_received_and_the_first_one_counts():
    inbox = Inbox(10, Counter())
    _put(inbox, 3, now=11)
    later = _cmd(9, 3)
    inbox.put_cmd(3, later, _cmd_of(_CMD_LAYOUT.unpack_from(later, 8)), 12, 0)
    c = inbox.cmd(3)
    assert c == _cmd_of(_CMD_LAYOUT.unpack_from(_cmd(3, 3), 8)) and c.seq == 3 and c.u_cmd[3] == 1e-9
    assert inbox.cmd_session(3) == 77 and inbox.cmd_times(3) == (11, 1_003)
    assert inbox.cmd(4) is None and not inbox.has_cmd(4) and not inbox.has_cmd(-1) and not inbox.has_cmd(10)
    inbox.published(3, 100, 200)
    inbox.published(3, 101, 201)  # a re-sent state: its first utime, its last monotonic time
    assert inbox.pub_times(3) == (100, 201)


def test_seqs_outside_the_run_are_counted_and_ignored():
    counters = Counter()
    inbox = Inbox(10, counters)
    for k in (10, 11, 2**62, -1, -5):
        data = _cmd(1, k)
        inbox.put_cmd(k, data, _cmd_of(_CMD_LAYOUT.unpack_from(data, 8)), 1, 1)
        inbox.put_status(k, _status(0))
    assert counters == Counter(state_seq_out_of_range=6)  # -1 and below answer no state: not counted
    assert not any(inbox.has_cmd(k) or inbox.has_status(k) for k in range(10))


def test_status_kept_as_bytes_and_decoded_after():
    counters = Counter()
    inbox = Inbox(4, counters)
    inbox.put_status(2, _status(2))
    inbox.put_status(2, _status(3))  # not the first: not kept
    assert inbox.has_status(2) and inbox.status(2).steps == 3 and inbox.status(1) is None
    inbox.put_status(1, b"\0" * (_STATUS_SIZE + 1))  # possible only for a type with variable fields
    assert inbox.has_status(1) and inbox.status(1) is None and counters["status_not_kept"] == 1


def test_the_memory_estimate_counts_what_the_bench_keeps_per_row():
    assert bus_bytes_per_row() == emulator.BYTES_PER_ROW == Inbox.BYTES_PER_ROW + 5 * 8
    # the rod command as received and its receipt time (magnetic control) too
    assert Inbox.BYTES_PER_ROW == (len(sc_rt_lcm.wheel_cmd_t().encode())
                                   + len(sc_rt_lcm.controller_status_t().encode()) + 4 * 8 + 4
                                   + len(sc_rt_lcm.rod_cmd_t().encode()) + 8)
