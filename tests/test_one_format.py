"""One on-disk run format whatever the engine, mode or length (issue 39 item 6).

Every run's rows are written as ``trajectory.arrow`` (docs/RECORD.md): the
same file name and schema from ``sc-rt sim`` (every engine) and ``sc-rt hil``;
pyarrow, pandas and polars read it in a process that cannot import sc_rt,
and give the values ``sc_rt.Run.load`` gives; the docs' reading examples run
as written; nothing in the package writes npz any more, and a run written
as npz by an older version is still read."""

from __future__ import annotations

import json
import pickle
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest

from sc_rt.results.record.fields import FIELD, FIELDS
from sc_rt.results.record.run import Run
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate

import lcmnet

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "python" / "sc_rt"
SCENARIO, DURATION = "paper_faults", 3.0

#: Prepended to every reader run here: any import of sc_rt fails, so the
#: reader reads the file with its own library or not at all.
NO_SC_RT = '''
import sys
class _NoScRt:
    def find_spec(self, name, path=None, target=None):
        if name == "sc_rt" or name.startswith("sc_rt."):
            raise ImportError("this reader must not import sc_rt")
sys.meta_path.insert(0, _NoScRt())
'''

#: Reads a run's trajectory.arrow with pyarrow, pandas and polars; pickles
#: {library: {field: 2-D numpy array (rows, row width)}} and the metadata.
READER = NO_SC_RT + '''
import json, pickle
import numpy as np, pandas as pd, polars as pl, pyarrow as pa
path, dump = sys.argv[1], sys.argv[2]
with pa.OSFile(path, "rb") as f:
    table = pa.ipc.open_file(f).read_all()
out = {"pyarrow": {}, "pandas": {}, "polars": {},
       "meta": json.loads(table.schema.metadata[b"sc-rt:meta"]),
       "shapes": json.loads(table.schema.metadata[b"sc-rt:shapes"])}
for name in table.column_names:
    col = table.column(name).combine_chunks()
    v = col.flatten().to_numpy(zero_copy_only=False) if pa.types.is_fixed_size_list(col.type) else col.to_numpy(
        zero_copy_only=False)
    out["pyarrow"][name] = v.reshape(len(col), -1)
df = pd.read_feather(path)
for name in df.columns:
    s = df[name]
    v = np.stack(s.to_numpy()) if s.dtype == object else s.to_numpy()
    out["pandas"][name] = v.reshape(len(s), -1)
pf = pl.read_ipc(path)
for name in pf.columns:
    v = pf[name].to_numpy()
    out["polars"][name] = v.reshape(len(v), -1)
assert not [m for m in sys.modules if m == "sc_rt" or m.startswith("sc_rt.")]
with open(dump, "wb") as f:
    pickle.dump(out, f)
'''


def _schema(run_dir: Path) -> pa.Schema:
    with pa.OSFile(str(run_dir / "trajectory.arrow"), "rb") as f:
        return pa.ipc.open_file(f).schema


def _sim(out: Path, engine: str = "python", duration: float = DURATION) -> None:
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", SCENARIO, "--engine", engine, "--duration",
                        str(duration), "--out", str(out), "--no-plots"], capture_output=True, text=True, cwd=ROOT,
                       timeout=300)
    assert r.returncode == 0, r.stderr + r.stdout


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    """The same scenario by ``sc-rt sim`` and by ``sc-rt hil --mode lockstep``."""
    lcmnet.require()
    d = tmp_path_factory.mktemp("one-format")
    _sim(d / "sim")
    r = lcmnet.run_cli(["hil", SCENARIO, "--mode", "lockstep", "--duration", str(DURATION), "--out",
                        str(d / "hil"), "--no-plots"])
    assert r.returncode == 0, r.stderr + r.stdout
    return {"sim": d / "sim", "hil": d / "hil"}


@pytest.mark.lcm
def test_sim_and_lockstep_hil_write_one_file_of_one_schema(runs):
    files = {k: sorted(p.name for p in v.iterdir() if p.name.startswith("trajectory")) for k, v in runs.items()}
    assert files == {"sim": ["trajectory.arrow"], "hil": ["trajectory.arrow"]}, files
    a, b = _schema(runs["sim"]), _schema(runs["hil"])
    assert a.names == b.names == [f.name for f in FIELDS]  # every declared field, in the table's order
    assert [str(t) for t in a.types] == [str(t) for t in b.types]
    assert set(a.metadata) == set(b.metadata) == {b"sc-rt:meta", b"sc-rt:shapes"}
    assert a.metadata[b"sc-rt:shapes"] == b.metadata[b"sc-rt:shapes"]
    ma, mb = (json.loads(s.metadata[b"sc-rt:meta"]) for s in (a, b))
    assert set(ma) == set(mb) and ma["scenario"] == mb["scenario"] == SCENARIO
    # a vector field is a fixed-size list of its row's width, a scalar one a primitive column
    for f in FIELDS:
        t = a.field(f.name).type
        if f.shape:
            assert pa.types.is_fixed_size_list(t) and t.list_size == int(np.prod(f.shape)), (f.name, t)
        else:
            assert not pa.types.is_nested(t), (f.name, t)
    # the lockstep run stays bitwise the offline run, read back through the one format
    from trajcmp import compared_fields, load_traj

    sim = simulate(load_scenario(ROOT / "scenarios" / f"{SCENARIO}.toml"), engine="python", duration=DURATION)
    compared_fields(load_traj(runs["hil"]), sim)
    compared_fields(load_traj(runs["sim"]), sim)


@pytest.mark.lcm
@pytest.mark.parametrize("which", ["sim", "hil"])
def test_pyarrow_pandas_and_polars_read_a_run_without_sc_rt_as_run_load_does(runs, which, tmp_path):
    dump = tmp_path / "read.pkl"
    r = subprocess.run([sys.executable, "-I", "-c", READER, str(runs[which] / "trajectory.arrow"), str(dump)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    got = pickle.loads(dump.read_bytes())
    run = Run.load(runs[which])
    assert got["meta"] == run.meta.to_json()
    assert {k: tuple(v[0]) for k, v in got["shapes"].items()} == {f.name: f.shape for f in FIELDS}
    for lib in ("pyarrow", "pandas", "polars"):
        assert list(got[lib]) == [f.name for f in FIELDS], lib
        for f in FIELDS:
            want = run[f.name].reshape(len(run), -1)
            v = got[lib][f.name]
            assert v.shape == want.shape and v.dtype == want.dtype, (lib, f.name, v.shape, v.dtype)
            assert np.array_equal(v, want, equal_nan=f.dtype == "f8"), (lib, f.name)


def _doc_examples() -> list[str]:
    """The python blocks of docs/RECORD.md that read a trajectory.arrow."""
    text = (ROOT / "docs" / "RECORD.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    return [b for b in blocks if "trajectory.arrow" in b and "import sc_rt" not in b]


def test_the_docs_pandas_and_polars_examples_run_as_written_without_sc_rt(tmp_path):
    examples = _doc_examples()
    assert len(examples) == 2 and "pandas" in examples[0] and "polars" in examples[1], examples
    run = simulate(load_scenario(ROOT / "scenarios" / f"{SCENARIO}.toml"), engine="cpp", duration=DURATION)
    from sc_rt.results.present.output import write_run

    write_run(run, tmp_path / "out" / "run", figures=False)
    last = run["sigma_BD"][-1]
    for code in examples:
        r = subprocess.run([sys.executable, "-I", "-c", NO_SC_RT + code], capture_output=True, text=True,
                           cwd=tmp_path, timeout=120)
        assert r.returncode == 0, r.stderr
        # each prints the rows, the last row's sigma_BD and the scenario (read from the schema's metadata)
        assert r.stdout.split("\n")[0] == f"{len(run)} {last.tolist()} {SCENARIO}", r.stdout


def test_nothing_in_the_package_writes_npz():
    writers = re.compile(r"savez|save_npz|\.npz\b[\"']?\s*,\s*[\"']w")
    found = [f"{p.relative_to(ROOT)}:{i}" for p in PKG.rglob("*.py")
             for i, line in enumerate(p.read_text().splitlines(), 1) if writers.search(line)]
    assert not found, found
    assert not hasattr(Run, "save_npz")


@pytest.mark.parametrize("engine", ["python", "cpp", "unsampled"])
def test_every_sim_engine_writes_trajectory_arrow_and_no_npz(engine, tmp_path):
    _sim(tmp_path / engine, engine, 1.0)
    names = {p.name for p in (tmp_path / engine).iterdir()}
    assert "trajectory.arrow" in names and not [n for n in names if n.endswith(".npz")], names
    run = Run.load(tmp_path / engine)
    assert run.meta.engine == engine and len(run) == 11  # 1 s at paper_faults' 10 Hz, both ends


def _write_old_npz(run: Run, path: Path, drop: str) -> None:
    """A run as sc-rt wrote short runs before trajectory.arrow (every field
    by name, and the meta as JSON in ``meta_json``), written here with numpy alone and
    without field ``drop`` (a field declared after the file was written)."""
    arrays = {f.name: run[f.name] for f in FIELDS if f.name != drop}
    np.savez_compressed(path, **arrays, meta_json=np.array(json.dumps(run.meta.to_json())))


def test_a_run_written_by_an_older_version_stays_readable(tmp_path):
    import pyarrow.ipc

    run = simulate(load_scenario(ROOT / "scenarios" / f"{SCENARIO}.toml"), engine="cpp", duration=DURATION)
    drop = "telemetry"
    # npz: what short runs were written as
    (tmp_path / "npz").mkdir()
    _write_old_npz(run, tmp_path / "npz" / "trajectory.npz", drop)
    (tmp_path / "npz" / "metrics.json").write_text(json.dumps({"steps": len(run)}))
    old = Run.load(tmp_path / "npz")
    assert old.metrics == {"steps": len(run)} and old.meta.to_json() == run.meta.to_json()
    # an Arrow file without a field declared since: the field reads as its fill value
    (tmp_path / "arrow").mkdir()
    schema = pa.schema([pa.field(f.name, pa.list_(pa.from_numpy_dtype(np.dtype(f.dtype)), int(np.prod(f.shape)))
                                 if f.shape else pa.from_numpy_dtype(np.dtype(f.dtype))) for f in FIELDS
                        if f.name != drop],
                       metadata={"sc-rt:meta": json.dumps(run.meta.to_json()),
                                 "sc-rt:shapes": json.dumps({f.name: [list(f.shape), f.dtype] for f in FIELDS
                                                             if f.name != drop})})
    cols = [pa.FixedSizeListArray.from_arrays(pa.array(run[n].reshape(-1)), schema.field(n).type.list_size)
            if pa.types.is_fixed_size_list(schema.field(n).type) else pa.array(run[n]) for n in schema.names]
    with pa.OSFile(str(tmp_path / "arrow" / "trajectory.arrow"), "wb") as sink:
        with pyarrow.ipc.new_file(sink, schema) as w:
            w.write_batch(pa.RecordBatch.from_arrays(cols, schema=schema))
    stored = Run.load(tmp_path / "arrow")
    for back in (old, stored):
        for f in FIELDS:
            want = np.full((len(run), *f.shape), f.fill, f.dtype) if f.name == drop else run[f.name]
            assert np.array_equal(back[f.name], want, equal_nan=f.dtype == "f8"), f.name
    assert [len(c) for c in stored.chunks()] == [len(run)] and FIELD[drop].shape


def test_a_short_run_is_written_in_batches_a_reader_takes_one_at_a_time(tmp_path, monkeypatch):
    from sc_rt.results.present.output import write_run
    from sc_rt.results.record import store

    monkeypatch.setattr(store, "CHUNK_ROWS", 7)
    run = simulate(load_scenario(ROOT / "scenarios" / f"{SCENARIO}.toml"), engine="cpp", duration=DURATION)
    write_run(run, tmp_path, figures=False)
    with pa.OSFile(str(tmp_path / "trajectory.arrow"), "rb") as f:
        r = pa.ipc.open_file(f)
        sizes = [r.get_batch(i).num_rows for i in range(r.num_record_batches)]
    assert sizes == [7, 7, 7, 7, 3]  # 31 rows
