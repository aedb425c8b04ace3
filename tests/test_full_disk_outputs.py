"""A full disk leaves no truncated output presented as a result (issue 40
item 5): every file a run writes (the figures, trajectory.arrow,
metrics.json, report.html) is written whole under a temporary name and
renamed, or removed when the write fails. A run's outputs are written onto
tmpfs file systems of several sizes (in a private mount namespace), so that
the disk fills in the middle of a different file each time; afterwards
every file there is complete (a PNG ends with its IEND chunk, the JSON
parses, the Arrow file opens with its rows) and no temporary is left.
Before, a figure was left with 0 bytes (seen with ``sc-rt sim`` on a full
tmpfs)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pyarrow as pa
import pytest

import lcmnet

ROOT = Path(__file__).resolve().parent.parent

WRITE = '''
import errno, json, sys
from pathlib import Path
from sc_rt import load_scenario, simulate
from sc_rt.results.present.output import write_run
from sc_rt.results.present.html_report import write_html_report

out, keep = Path(sys.argv[1]), Path(sys.argv[2])
run = simulate(load_scenario("paper_fault_free"), engine="cpp", duration=30.0)
try:
    write_run(run, out, figures=True)
    write_html_report(out)
    print("WROTE")
except OSError as e:
    print("ENOSPC" if e.errno == errno.ENOSPC else f"OTHER {e!r}")
keep.mkdir()
for f in out.iterdir():  # what the full disk holds, copied out of the namespace's tmpfs
    (keep / f.name).write_bytes(f.read_bytes())
'''


def _complete(f: Path) -> bool:
    data = f.read_bytes()
    if f.suffix == ".png":
        return data.startswith(b"\x89PNG") and data.endswith(b"IEND\xaeB`\x82")
    if f.suffix == ".json":
        json.loads(data)
        return True
    if f.suffix == ".arrow":
        return pa.ipc.open_file(pa.py_buffer(data)).num_record_batches > 0
    if f.suffix == ".html":
        return data.rstrip().endswith(b"</html>")
    return len(data) > 0


@pytest.mark.parametrize("size", ["24k", "96k", "200k", "400k", "4m"])
def test_a_full_disk_leaves_every_output_whole_or_absent(tmp_path, size):
    if not lcmnet.can_unshare():
        pytest.skip("needs root for a private mount namespace")
    out = tmp_path / "full"
    (tmp_path / "write.py").write_text(WRITE)
    keep = tmp_path / "kept"
    inner = (f"mkdir -p {out} && mount -t tmpfs -o size={size} tmpfs {out} && "
             f"{sys.executable} {tmp_path / 'write.py'} {out} {keep}")
    r = subprocess.run(["unshare", "-m", "sh", "-c", inner], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 0 and ("ENOSPC" in r.stdout or "WROTE" in r.stdout), r.stdout + r.stderr
    copies = sorted(keep.iterdir())
    names = [c.name for c in copies]
    assert not [n for n in names if n.endswith(".part") or n.startswith(".")], names
    for c in copies:
        assert c.stat().st_size > 0 and _complete(c), (size, c.name, c.stat().st_size)
    if "WROTE" in r.stdout:
        assert {"trajectory.arrow", "metrics.json", "report.html"} <= set(names), names
