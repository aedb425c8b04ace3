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


LOG = Path(__file__).resolve().parent / "data" / "v1_paper_faults_lockstep_3s.lcmlog"


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "sc_rt.cli", *args], capture_output=True, text=True, timeout=300)


def test_report_and_montecarlo_honour_a_live_runs_directory(tmp_path):
    """issue 40 item 6: before, both wrote into a directory a live run held
    (that run's report.html embedded another command's figures)."""
    out = tmp_path / "o"
    out.mkdir()
    (out / LOCK).write_text(f"{os.getpid()} someone\n")  # this test process: alive
    for args in (["report", str(LOG), "--out", str(out), "--no-plots"],
                 ["montecarlo", "paper_fault_free", "--runs", "2", "--out", str(out)]):
        r = _cli(*args)
        assert r.returncode == 2, (args[0], r.stderr)
        assert "in use by a live run" in r.stderr and str(os.getpid()) in r.stderr, (args[0], r.stderr)
    assert sorted(p.name for p in out.iterdir()) == [LOCK]  # nothing written


def test_a_report_leaves_nothing_in_a_later_runs_directory(tmp_path):
    """A report's report.json (and every other file of it) is gone when a
    sim takes the directory (before: it stayed, and appeared in the sim's
    report)."""
    out = tmp_path / "o"
    r = _cli("report", str(LOG), "--out", str(out), "--no-plots")
    assert r.returncode == 0, r.stderr
    assert (out / "report.json").exists()
    assert "report.json" in json.loads((out / MANIFEST).read_text())["files"]
    r = _sim(out, "--no-plots")
    assert r.returncode == 0, r.stderr
    assert not (out / "report.json").exists()
    assert json.loads((out / "metrics.json").read_text())["engine"] == "cpp"


def test_a_new_campaign_clears_the_previous_ones_files_and_a_resumed_one_keeps_them(tmp_path):
    out = tmp_path / "mc"
    base = ["montecarlo", "paper_fault_free", "--workers", "1", "--out", str(out)]
    assert _cli(*base, "--runs", "2").returncode == 0
    (out / "rerun-1").mkdir()  # as a --rerun of that campaign left it
    assert _cli(*base, "--runs", "2", "--rerun", "1").returncode == 0
    first = {str(p.relative_to(out)) for p in out.rglob("*") if p.is_file()}
    r = _cli(*base, "--runs", "3", "--resume")  # the same campaign, one run more: its dataset stays
    assert r.returncode == 0, r.stderr
    assert json.loads((out / "montecarlo.json").read_text())["runs"] == 3
    r = _cli(*base, "--runs", "2", "--seed", "7", "--overwrite")  # another campaign: the old one's files go
    assert r.returncode == 0, r.stderr
    now = {str(p.relative_to(out)) for p in out.rglob("*") if p.is_file()}
    assert json.loads((out / "montecarlo.json").read_text())["runs"] == 2
    assert not any(p.startswith("rerun-1/") for p in now) and any(p.startswith("rerun-1/") for p in first)
