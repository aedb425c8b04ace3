"""The run record's on-disk format: trajectory.arrow against npz and Parquet.

A run is written once and read many times (metrics, figures, report,
compare, a user's pandas): this measures, for a short run (the paper's
300 s at 10 Hz, 3,001 rows) and a long one (10 min at 1 kHz, 600,001 rows
of ``ppc_feasible_1khz``, written to disk as it ran), every field of
``sc_rt.FIELDS`` as

- ``arrow_lz4``: Arrow IPC file, batches of ``CHUNK_ROWS`` rows, LZ4 (what
  sc-rt writes: ``Run.save_arrow``, results/record/store.py);
- ``arrow_zstd``: the same with Zstandard;
- ``parquet``: a Parquet file, a row group per batch (pyarrow's default
  Snappy), appended by ``pyarrow.parquet.ParquetWriter``;
- ``npz``: ``numpy.savez_compressed`` of the whole run (what short runs
  wrote before), which needs every row in memory at once.

Figures per format: file size, write time (whole run), the median time to
append one batch of ``CHUNK_ROWS`` rows (the emulator's writer thread's
job), the time to read every column back into numpy, and to read one
column (``sigma_BD``).

    .venv/bin/python bench/bench_format.py [--quick | --smoke]

(--quick: 60 s at 1 kHz for the long run; --smoke: 10 s at 10 Hz and 2 s at
1 kHz, a check that it runs.) docs/PERFORMANCE.md, "The run record on disk".
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from common import ROOT, machine, mode, write

from sc_rt.results.record.fields import COLUMNS, FIELDS  # noqa: E402
from sc_rt.results.record.store import CHUNK_ROWS, ChunkFile, ChunkReader, _pa, _to_arrow  # noqa: E402
from sc_rt.scenario.reader import load_scenario  # noqa: E402
from sc_rt.sim.engines import simulate  # noqa: E402

NAMES = [f.name for f in FIELDS]


def _batches(run) -> list[dict[str, np.ndarray]]:
    """The run's rows as batches of CHUNK_ROWS rows (every field)."""
    out = []
    for c in run.chunks():
        n = len(c)
        for k in range(0, n, CHUNK_ROWS):
            out.append({name: c[name][k:k + CHUNK_ROWS] for name in NAMES})
    return out


def _arrow(path: Path, batches, compression: str) -> list[float]:
    pa = _pa()
    w = ChunkFile(path, COLUMNS, {"sc-rt:meta": "{}"})
    if compression != "lz4":  # the same writer with another codec
        w._w.close()
        w._sink.close()
        w._sink = pa.OSFile(str(path), "wb")
        w._w = pa.ipc.new_file(w._sink, w.schema,
                               options=pa.ipc.IpcWriteOptions(compression=compression, use_threads=False))
    per = []
    for b in batches:
        t0 = time.perf_counter()
        w.write(b, len(b["t"]))
        per.append(time.perf_counter() - t0)
    w.close()
    return per


def _to_numpy(table, names) -> int:
    """The table's columns ``names`` as numpy arrays (a vector field: rows x width); their bytes."""
    n = 0
    shapes = {name: (shape, dtype) for name, shape, dtype, _f in COLUMNS}
    for name in names:
        shape, dtype = shapes[name]
        col = table.column(name).combine_chunks()
        n += np.asarray((col.flatten() if shape else col).to_numpy(zero_copy_only=False), dtype).nbytes
    return n


def _read_arrow(path: Path, names=None) -> int:
    """pyarrow's read of the file (``names``: only those columns' buffers are decompressed)."""
    pa = _pa()
    with pa.OSFile(str(path), "rb") as src:
        if names is None:
            table = pa.ipc.open_file(src).read_all()
        else:
            schema = pa.ipc.open_file(src).schema
            opts = pa.ipc.IpcReadOptions(included_fields=[schema.get_field_index(n) for n in names],
                                         use_threads=False)
            table = pa.ipc.open_file(src, options=opts).read_all()
        return _to_numpy(table, names or NAMES)


def _read_sc_rt(path: Path, names=None) -> int:
    """sc-rt's reader (``Run.load``'s ChunkReader): every column, a column at a time."""
    r = ChunkReader(path)
    n = sum(r.column(name).nbytes for name in (names or NAMES))
    r.close()
    return n


def _parquet(path: Path, batches, schema) -> list[float]:
    pa = _pa()
    import pyarrow.parquet as pq

    per = []
    with pq.ParquetWriter(str(path), schema) as w:
        for b in batches:
            t0 = time.perf_counter()
            arrays = [_to_arrow(b[name]) for name in NAMES]
            w.write_batch(pa.RecordBatch.from_arrays(arrays, schema=schema))
            per.append(time.perf_counter() - t0)
    return per


def _read_parquet(path: Path, names=None) -> int:
    import pyarrow.parquet as pq

    return _to_numpy(pq.read_table(str(path), columns=names, use_threads=False), names or NAMES)


def _npz(path: Path, batches) -> None:
    whole = {name: np.concatenate([b[name] for b in batches]) for name in NAMES}
    np.savez_compressed(path, **whole, meta_json=np.array("{}"))


def _read_npz(path: Path, names=None) -> int:
    with np.load(path) as z:
        return sum(z[name].nbytes for name in (names or NAMES))


FORMATS = ("arrow_lz4", "arrow_zstd", "parquet", "npz")


def _once(fmt: str, path: Path, batches, schema) -> dict:
    """One write and the reads of one format: times [s], append times [s] per batch."""
    t0 = time.perf_counter()
    if fmt.startswith("arrow"):
        per = _arrow(path, batches, fmt.split("_")[1])
        read = _read_arrow
    elif fmt == "parquet":
        per = _parquet(path, batches, schema)
        read = _read_parquet
    else:
        _npz(path, batches)
        per = []
        read = _read_npz
    out = {"write_s": time.perf_counter() - t0, "per": per, "bytes": path.stat().st_size}
    t0 = time.perf_counter()
    out["numpy_bytes"] = read(path)
    out["read_all_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    read(path, ["sigma_BD"])
    out["read_one_column_s"] = time.perf_counter() - t0
    if fmt == "arrow_lz4":  # sc-rt's own reader of what it writes
        t0 = time.perf_counter()
        _read_sc_rt(path)
        out["sc_rt_read_all_s"] = time.perf_counter() - t0
    path.unlink()
    return out


def measure(run, work: Path, repeats: int) -> dict:
    """Every format's figures for one run: medians of ``repeats`` rounds, the formats alternating."""
    batches = _batches(run)
    schema = ChunkFile(None, COLUMNS).schema
    res: dict = {"rows": len(run), "batches": len(batches), "fields": len(NAMES), "repeats": repeats}
    rounds = {fmt: [] for fmt in FORMATS}
    for _ in range(repeats):
        for fmt in FORMATS:
            rounds[fmt].append(_once(fmt, work / f"rec.{fmt}", batches, schema))
    for fmt, rs in rounds.items():
        per = [x for r in rs for x in r["per"]]
        res[fmt] = {"bytes": rs[0]["bytes"], "bytes_per_row": rs[0]["bytes"] / len(run),
                    "numpy_bytes": rs[0]["numpy_bytes"],
                    "append_batch_ms_median": float(np.median(per)) * 1e3 if per else None,
                    **{k: float(np.median([r[k] for r in rs])) for k in rs[0] if k.endswith("_s")}}
    return res


def main() -> None:
    size = mode()
    short = (10.0 if size == "smoke" else 300.0)
    long = {"smoke": 2.0, "quick": 60.0, "full": 600.0}[size]
    res: dict = {"machine": machine(), "chunk_rows": CHUNK_ROWS}
    with tempfile.TemporaryDirectory(prefix="bench-format-") as d:
        work = Path(d)
        run = simulate(load_scenario(ROOT / "scenarios" / "paper_faults.toml"), engine="cpp", duration=short)
        measure(run, work, 1)  # warm-up: every codec and reader loaded once, not timed
        res["short"] = {"scenario": "paper_faults", "duration_s": short,
                        **measure(run, work, 1 if size == "smoke" else 5)}
        t0 = time.perf_counter()
        run = simulate(load_scenario(ROOT / "scenarios" / "ppc_feasible_1khz.toml"), engine="cpp", duration=long,
                       record_dir=work / "long")
        res["long_simulate_s"] = time.perf_counter() - t0
        res["long"] = {"scenario": "ppc_feasible_1khz", "duration_s": long,
                       **measure(run, work, 1 if size != "quick" else 2)}
    write("format", res)
    for which in ("short", "long"):
        r = res[which]
        print(f"{which}: {r['rows']} rows")
        for fmt in FORMATS:
            f = r[fmt]
            print(f"  {fmt:11s} {f['bytes'] / 1e6:9.2f} MB  write {f['write_s']:7.3f} s  "
                  f"read all {f['read_all_s']:7.3f} s  one column {f['read_one_column_s']:7.4f} s"
                  + (f"  append/batch {f['append_batch_ms_median']:6.2f} ms" if f["append_batch_ms_median"] else "")
                  + (f"  sc-rt's reader {f['sc_rt_read_all_s']:7.3f} s" if "sc_rt_read_all_s" in f else ""))


if __name__ == "__main__":
    main()
