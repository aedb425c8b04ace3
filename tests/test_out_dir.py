"""Outputs belong to their run (issue #25, case 4): a rerun into the same
--out keeps nothing of the run before (with --no-plots, no figure of it, and
report.html embeds none), a directory a live run holds is refused, a stale
claim is taken over, and files that are not a run's are left alone and
never embedded. metrics.json carries the run's id, as the manifest does."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from sc_rt.results.present.output import LOCK, MANIFEST

ARGS = ["sim", "paper_fault_free", "--engine", "cpp", "--duration", "2"]


def _sim(out: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "sc_rt.cli", *ARGS, "--out", str(out), *extra],
                          capture_output=True, text=True, timeout=300)


def test_a_rerun_without_plots_keeps_no_figure_of_the_run_before(tmp_path):
    out = tmp_path / "o"
    assert _sim(out).returncode == 0
    first = json.loads((out / "metrics.json").read_text())["run_id"]
    assert list(out.glob("*.png")) and "<img" in (out / "report.html").read_text()
    (out / "mine.png").write_bytes(b"not a run's figure")  # yours: kept, never embedded
    r = _sim(out, "--no-plots")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in out.glob("*.png")) == ["mine.png"]
    html = (out / "report.html").read_text()
    assert "<img" not in html  # before: the previous run's PNGs under the new run's title
    second = json.loads((out / "metrics.json").read_text())["run_id"]
    man = json.loads((out / MANIFEST).read_text())
    assert second != first and man["run_id"] == second and man["done"] is True
    assert "mine.png" in man["foreign"] and "metrics.json" in man["files"]
    assert not (out / LOCK).exists()


def test_an_out_held_by_a_live_run_is_refused_and_a_stale_claim_taken_over(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    (out / LOCK).write_text(f"{os.getpid()} someone\n")  # this test process: alive
    r = _sim(out)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "in use by a live run" in lines[0] and str(os.getpid()) in lines[0]
    assert not (out / "metrics.json").exists()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (out / LOCK).write_text(f"{dead.pid} gone\n")  # a run that died holding it
    r = _sim(out, "--no-plots")
    assert r.returncode == 0, r.stderr
    assert (out / "metrics.json").exists() and not (out / LOCK).exists()
