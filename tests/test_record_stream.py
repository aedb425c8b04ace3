"""Runs on disk (issue #31, item 2): the rows of a long run go to an Arrow
IPC file a chunk at a time (results/record/store.py), and everything after the run
reads them back a chunk at a time.

Checked against what does not share the chunked code: the same run held
whole in memory (one chunk) and the offline simulator, bit for bit; the
file read by pyarrow's own Feather reader; a lost-message count against
sets of seqs."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt.results.judge.metrics import finish_run
from sc_rt.results.record.run import FIELDS, Run
from sc_rt.results.record.store import ChunkFile, ChunkReader, RowRing
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate

import lcmnet
from trajcmp import compared_fields, load_traj

ROOT = Path(__file__).resolve().parent.parent


def _on_disk(run: Run, path: Path, batch: int) -> Run:
    """``run``'s rows written in batches of ``batch`` rows, opened on disk."""
    w = ChunkFile(path, [(f.name, f.shape, f.dtype, f.fill) for f in FIELDS],
                  {"sc-rt:meta": json.dumps(run.meta.to_json())})  # as the emulator writes it
    for k in range(0, len(run), batch):
        w.write({f.name: run[f.name][k:k + batch] for f in FIELDS}, min(batch, len(run) - k))
    w.close()
    return Run.stored(run.meta, path)


def test_the_file_is_arrow_that_pyarrow_reads_without_sc_rt(tmp_path, rng):
    import pyarrow.feather as feather

    cols = [("t", (), "f8", np.nan), ("v", (3,), "f8", np.nan), ("ok", (3,), "?", False), ("k", (), "i8", -1)]
    n = 1_000
    data = {"t": rng.standard_normal(n), "v": rng.standard_normal((n, 3)), "ok": rng.random((n, 3)) < 0.5,
            "k": rng.integers(-5, 5, n)}
    w = ChunkFile(tmp_path / "x.arrow", cols, {"note": "hello"})
    for s in range(0, n, 300):
        w.write({k: v[s:s + 300] for k, v in data.items()}, min(300, n - s))
    w.close()
    r = ChunkReader(tmp_path / "x.arrow")
    assert (r.rows, r.n_batches, r.metadata["note"]) == (n, 4, "hello")
    for k, v in data.items():
        assert np.array_equal(r.column(k), v)
    table = feather.read_table(tmp_path / "x.arrow")  # Feather v2 is the Arrow IPC file format
    assert table.num_rows == n
    assert np.array_equal(np.stack(table.column("v").to_pylist()), data["v"])
    assert table.column("ok").to_pylist()[7] == list(data["ok"][7])


def test_a_ring_hands_over_every_row_once_in_order():
    got: list[tuple[int, int]] = []
    seen = []
    def on_full(cols, base, n):  # None: the ring resets and reuses the chunk
        got.append((base, n))
        seen.extend(cols["k"][:n])

    ring = RowRing([("k", (), "i8", -1)], 5, on_full)
    for k in range(23):
        ring.reach(k + 1)
        c, j = ring.slot(k)
        c["k"][j] = k
        assert ring.slot(k - 11) is None  # written already
        assert ring.slot(k + 11) is None  # not live yet
    ring.finish(23)
    assert seen == list(range(23))
    assert got == [(0, 5), (5, 5), (10, 5), (15, 5), (20, 3)]


def test_the_record_writer_writes_every_chunk_off_the_loops_thread(tmp_path):
    """emulator/record.py: the chunks a long run spills are written by the
    writer's thread, never the loop's, each row once and in order, and the
    spare chunk the loop gets back is at the fill values (a column the loop
    leaves unfilled reads as its fill in every row)."""
    import threading

    from sc_rt.emulator import record as rec

    threads = []
    write = rec.ChunkFile.write

    def spy(self, cols, rows):  # the real write, with the thread that made it noted
        threads.append(threading.get_ident())
        return write(self, cols, rows)

    rec.ChunkFile.write = spy
    try:
        r = rec.Record(n_rows=1000, chunk=64, directory=tmp_path)
        warm = len(threads)  # the writer's warm-up before the run, in the caller's thread
        for k in range(1000):
            r.ring.reach(k + 1)
            c, j = r.ring.slot(k)
            c["t"][j] = k * 0.01
            if k % 2 == 0:  # every other row leaves the command unfilled
                c["u_cmd"][j] = k
        r.ring.finish(1000)
        r._writer.close()
        raw = r._raw.close()
    finally:
        rec.ChunkFile.write = write
    loop = threading.get_ident()
    assert len(threads) - warm == 16 and loop not in threads[warm:]  # 1000 rows in 64-row chunks
    back = ChunkReader(raw)
    t = np.concatenate([back.batch(i)["t"] for i in range(back.n_batches)])
    u = np.concatenate([back.batch(i)["u_cmd"] for i in range(back.n_batches)])
    np.testing.assert_array_equal(t, np.arange(1000) * 0.01)
    fill = dict((n, f) for n, _s, _d, f in rec.RECORD_COLUMNS)["u_cmd"]
    np.testing.assert_array_equal(u[0::2], np.repeat(np.arange(0, 1000, 2)[:, None], 4, axis=1))
    assert np.all((u[1::2] == fill) | (np.isnan(u[1::2]) & np.isnan(fill)))


@pytest.mark.parametrize("scenario, batch", [("paper_faults", 97), ("ppc_feasible_1khz", 1_000)])
def test_metrics_of_a_run_on_disk_equal_those_of_the_run_held_whole(scenario, batch, tmp_path):
    scn = load_scenario(ROOT / "scenarios" / f"{scenario}.toml")
    whole = simulate(scn, engine="cpp", duration=40.0)
    disk = _on_disk(whole, tmp_path / "trajectory.arrow", batch)
    assert disk.is_stored and len(disk) == len(whole)
    disk.metrics = {}
    finish_run(disk)  # rewrites the derived fields a batch at a time, then reads them
    held = {k: v for k, v in whole.metrics.items() if k != "law_failures"}  # simulate adds it after finish_run
    assert json.dumps(disk.metrics, sort_keys=True) == json.dumps(held, sort_keys=True)
    for f in FIELDS:
        assert np.array_equal(disk[f.name], whole[f.name], equal_nan=f.dtype == "f8"), f.name
    # figures of a run on disk draw a decimated copy that keeps the peaks
    drawn = disk.decimated(200)
    assert len(drawn) < len(whole) // 3
    s = np.linalg.norm(whole["sigma_BD"], axis=1)
    assert np.linalg.norm(drawn["sigma_BD"], axis=1).max() == s.max()
    assert drawn["t"][0] == 0.0 and np.all(np.diff(drawn["t"]) > 0)


def test_log_missing_counts_each_seq_once_and_ignores_foreign_ones(tmp_path):
    from sc_rt.logs.timing import log_missing

    lcm = pytest.importorskip("lcm")
    path = tmp_path / "x.lcmlog"
    log = lcm.EventLog(str(path), "w", overwrite=True)

    def msg(seq: int) -> bytes:
        return b"\0" * 16 + int(seq).to_bytes(8, "big", signed=True) + b"\0" * 8

    for seq in (0, 1, 1, 3, 4, 2**40, -7):  # 2 lost; a duplicate and two seqs of no row
        log.write_event(0, "P_SCRT_STATE", msg(seq))
    for seq in range(5):
        log.write_event(0, "P_SCRT_TRUTH", msg(seq))
    log.close()
    expected_sets = {"SCRT_STATE": {0, 1, 3, 4}, "SCRT_TRUTH": set(range(5)), "SCRT_GUIDANCE": set()}
    want = {c: (5 - len(s) if s or c != "SCRT_GUIDANCE" else 0) for c, s in expected_sets.items()}
    assert log_missing(path, "P_", 5) == want == {"SCRT_STATE": 1, "SCRT_TRUTH": 0, "SCRT_GUIDANCE": 0}


def test_lockstep_run_written_as_it_runs_is_bit_identical_to_offline_sim(tmp_path):
    lcmnet.require()
    out = tmp_path / "hil"
    code = (f"from pathlib import Path; from sc_rt.hil.runner import run_hil; "
            f"from sc_rt.plan import Outputs, plan_run; "
            f"r = run_hil(plan_run('paper_faults', engine='bench', duration=30.0, "
            f"outputs=Outputs(out=Path({str(out)!r}))), record_chunk=64); print(r.run.is_stored, len(r.run))")
    r = lcmnet.run([sys.executable, "-c", code], timeout=300)
    assert r.returncode == 0, r.stderr + r.stdout
    assert r.stdout.split()[-2:] == ["True", "301"]
    assert not (out / "record.raw.arrow").exists()
    hil = Run.load(out)
    assert hil.is_stored and len(hil) == 301
    sim = simulate(load_scenario(ROOT / "scenarios" / "paper_faults.toml"), engine="python", duration=30.0)

    compared_fields(load_traj(out), sim)
    m = json.loads((out / "metrics.json").read_text())
    for k in ("first_bound_violation_s", "sigma_e_norm", "omega_e_norm", "max_abs_u_cmd", "saturated_fraction",
              "final_wheel_speed", "requirements"):
        assert m[k] == json.loads(json.dumps(sim.metrics[k])), k
    assert m["valid"] is True
    timing = json.loads((out / "timing.json").read_text())
    assert set(timing["log_missing"].values()) == {0}
    lat = hil["latency_us"]
    assert np.all(np.isfinite(lat)) and np.all(lat > 0)  # every status and answer kept across the chunks
    assert np.all(np.isfinite(hil["compute_us"]))
    assert timing["emulator_breakdown_us"]["rows"] == 301
    assert (out / "pointing_error.png").stat().st_size > 0
    # what the bench wrote per row is within the disk estimate a run is refused by (cli/validate.py)
    from sc_rt.cli.validate import disk_bytes_per_row

    written = (out / "trajectory.arrow").stat().st_size + (out / "run.lcmlog").stat().st_size
    assert written / 301 <= disk_bytes_per_row(), (written / 301, disk_bytes_per_row())


def test_the_report_of_a_run_on_disk_draws_the_timeline_of_the_run_held_whole(tmp_path):
    import re

    from sc_rt.results.present.html_report import render_html
    from sc_rt.results.present.output import write_run

    scn = load_scenario(ROOT / "scenarios" / "paper_faults.toml")
    whole = simulate(scn, engine="cpp", duration=60.0)  # faults, SAFE-free, bound left on one axis
    disk = _on_disk(whole, tmp_path / "rows.arrow", 50)
    disk.metrics = dict(whole.metrics)
    write_run(whole, tmp_path / "whole", figures=False)
    write_run(disk, tmp_path / "disk", figures=False)
    assert (tmp_path / "disk" / "trajectory.arrow").exists()

    def svg(d: Path) -> str:
        return re.search(r'<svg viewBox=.*?id="timeline-svg">.*?</svg>', render_html(d), re.S).group(0)

    a, b = svg(tmp_path / "whole"), svg(tmp_path / "disk")
    assert a == b and "wheel 1 fault" in a and "outside bound" in a


def test_a_long_cpp_run_goes_to_disk_as_it_runs_bit_identical_to_the_run_held_whole(tmp_path, monkeypatch):
    from sc_rt.sim import engines

    scn = load_scenario(ROOT / "scenarios" / "paper_faults.toml")
    whole = simulate(scn, engine="cpp", duration=100.0)  # 1001 rows in one call of the C++ loop
    assert not whole.is_stored
    monkeypatch.setattr(engines, "OFFLINE_CHUNK_ROWS", 64)  # 16 chunks, the last one short
    disk = simulate(scn, engine="cpp", duration=100.0, record_dir=tmp_path)
    assert disk.is_stored and disk.path == tmp_path / "trajectory.arrow" and len(disk) == 1001
    for f in FIELDS:
        assert np.array_equal(disk[f.name], whole[f.name], equal_nan=f.dtype == "f8"), f.name
    a = {k: v for k, v in disk.metrics.items() if k != "wall_s"}
    b = {k: v for k, v in whole.metrics.items() if k != "wall_s"}
    assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)
    # a run on disk crosses a process boundary by its path (a contained plugin's child)
    import pickle

    again = pickle.loads(pickle.dumps(disk))
    assert again.is_stored and np.array_equal(again["sigma_BD"], whole["sigma_BD"])


@pytest.mark.parametrize("stored", [False, True])
def test_record_every_keeps_every_nth_row_and_judges_every_row(tmp_path, monkeypatch, stored):
    from sc_rt.results.present.output import write_run
    from sc_rt.sim import engines

    text = (ROOT / "scenarios" / "paper_faults.toml").read_text()
    (tmp_path / "thin.toml").write_text(text + "\n[record]\nevery = 7\n")
    thin_scn = load_scenario(tmp_path / "thin.toml")
    assert thin_scn.record.every == 7
    if stored:
        monkeypatch.setattr(engines, "OFFLINE_CHUNK_ROWS", 50)
    full = simulate(load_scenario(ROOT / "scenarios" / "paper_faults.toml"), engine="cpp", duration=60.0)
    run = simulate(thin_scn, engine="cpp", duration=60.0, record_dir=tmp_path / "rec")
    assert run.is_stored == stored
    write_run(run, tmp_path / "out", figures=False)
    saved = Run.load(tmp_path / "out")
    k = np.r_[np.arange(0, 601, 7), 600]  # every 7th control instant and the last
    assert len(saved) == len(k) and np.array_equal(saved["t"], full["t"][k])
    assert np.array_equal(saved["sigma_BD"], full["sigma_BD"][k])
    m = json.loads((tmp_path / "out" / "metrics.json").read_text())
    for key in ("first_bound_violation_s", "sigma_e_norm", "max_abs_u_cmd", "saturated_fraction", "steps"):
        assert m[key] == json.loads(json.dumps(full.metrics[key])), key  # judged on all 601 rows
    assert saved.meta.record_every == 7


def test_a_bad_record_every_names_the_key_and_its_line(tmp_path):
    from sc_rt.scenario.schema import ScenarioError

    text = (ROOT / "scenarios" / "paper_faults.toml").read_text()
    (tmp_path / "bad.toml").write_text(text + "\n[record]\nevery = 0\n")
    with pytest.raises(ScenarioError) as e:
        load_scenario(tmp_path / "bad.toml")
    line = len(text.splitlines()) + 3
    assert "record.every" in str(e.value) and f":{line}" in str(e.value), str(e.value)


_LOCKED = """
import ctypes, sys
import numpy as np
from sc_rt.results.record.run import FIELDS
from sc_rt.results.record.store import ChunkFile
def rss():
    return next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmRSS"))
cols = [(f.name, f.shape, f.dtype, f.fill) for f in FIELDS]
buf = {n: np.full((4096, *s), 1, d) for n, s, d, _ in cols}
assert ctypes.CDLL("libc.so.6").mlockall(3) == 0  # MCL_CURRENT | MCL_FUTURE, as a real-time emulator
w = ChunkFile(sys.argv[1], cols)
before = rss()
for _ in range(30):
    w.write(buf, 4096)
w.close()
print(rss() - before)
"""


def test_writing_rows_under_mlockall_stays_small(tmp_path):
    """A real-time emulator locks its memory (mlockall): Arrow's default
    allocator, mimalloc, then makes its 1 GiB arena resident at the first
    batch (+1.04 GB measured); with malloc it is the batch's buffers."""
    import os
    import subprocess

    if os.geteuid() != 0:
        pytest.skip("mlockall of a process's future pages needs root (CI is root)")
    r = subprocess.run([sys.executable, "-c", _LOCKED, str(tmp_path / "x.arrow")], capture_output=True, text=True,
                       timeout=120, env={k: v for k, v in os.environ.items() if k != "ARROW_DEFAULT_MEMORY_POOL"})
    assert r.returncode == 0, r.stderr
    grown_kb = int(r.stdout.split()[-1])
    assert grown_kb < 150_000, grown_kb  # 30 batches of 3.5 MB written; mimalloc: ~1,066,000
