"""Campaigns across processes: a real Dask cluster (scheduler + two workers
started here, on 127.0.0.1) gives bitwise the rows of the local pool; a
campaign killed with SIGKILL keeps every finished batch and --resume
completes it to the rows of an uninterrupted one."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import with_overrides
from sc_rt.studies.campaign import plan_campaign, Dispersion, RunStore, run_campaign

ROOT = Path(__file__).resolve().parent.parent
FEASIBLE = ROOT / "scenarios/ppc_feasible_10hz.toml"

pytestmark = pytest.mark.slow


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait(timeout=10)


def _wait(predicate, timeout: float, what: str, procs=()):
    deadline = time.monotonic() + timeout
    while not predicate():
        for p in procs:
            assert p.poll() is None, f"{p.args} exited with {p.returncode} while waiting for {what}"
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.05)


def test_a_dask_cluster_gives_the_local_pools_rows_bitwise(tmp_path):
    from distributed import Client

    scn = with_overrides(load_scenario(FEASIBLE), duration=60)
    c = plan_campaign(scn, Dispersion(), seed=21)
    run_campaign(c, 24, tmp_path / "pool", workers=2, progress=False)
    pool = RunStore(tmp_path / "pool", c.columns()).read().to_pylist()

    sched_file = tmp_path / "scheduler.json"
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
    common = dict(cwd=tmp_path, env=env, start_new_session=True,
                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host",
                               "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(sched_file)], **common)]
    try:
        _wait(sched_file.exists, 60, "the scheduler file", procs)
        for _ in range(2):
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file", str(sched_file),
                 "--nthreads", "1", "--nworkers", "1", "--no-dashboard", "--host", "127.0.0.1"], **common))
        address = json.loads(sched_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        with Client(address, timeout="30s") as client:  # readiness: poll the client, no sleep
            client.wait_for_workers(2, timeout=60)
        res = run_campaign(c, 24, tmp_path / "dask", scheduler=address, batch_size=1, progress=False)
        assert res["backend"] == "dask" and res["workers"] == 2
        dask_rows = RunStore(tmp_path / "dask", c.columns()).read().to_pylist()
        assert repr(dask_rows) == repr(pool)
        # and through the scheduler file, with other batches (another finishing order)
        run_campaign(c, 24, tmp_path / "file", scheduler_file=str(sched_file), batch_size=5,
                     progress=False)
        assert repr(RunStore(tmp_path / "file", c.columns()).read().to_pylist()) == repr(pool)
    finally:
        _stop(procs)


def test_sigkill_loses_only_runs_in_flight_and_resume_completes(tmp_path):
    text = FEASIBLE.read_text().replace("duration = 300.0", "duration = 30.0")
    assert "duration = 30.0" in text
    scn_path = tmp_path / "short.toml"
    scn_path.write_text(text)
    out = tmp_path / "mc"
    runs = 600
    cmd = [sys.executable, "-m", "sc_rt.cli", "montecarlo", str(scn_path), "--runs", str(runs),
           "--workers", "2", "--batch", "5", "--seed", "4", "--out", str(out)]
    p = subprocess.Popen(cmd, cwd=ROOT, start_new_session=True, stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL)
    try:
        runs_dir = out / "runs"
        _wait(lambda: runs_dir.exists() and len(list(runs_dir.glob("*.parquet"))) >= 4, 120,
              "four batch files", [p])
        os.killpg(p.pid, signal.SIGKILL)  # the CLI and its pool workers, mid-campaign
        p.wait(timeout=10)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait(timeout=10)
    assert p.returncode == -signal.SIGKILL
    scn = load_scenario(scn_path)
    c = plan_campaign(scn, Dispersion(), seed=4)
    store = RunStore(out, c.columns())
    kept = store.read().to_pylist()  # every file that exists is whole
    assert 20 <= len(kept) < runs  # killed in the middle; no batch lost before it
    ids = [r["run"] for r in kept]
    assert len(ids) == len(set(ids))

    r = subprocess.run(cmd + ["--resume"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert f"{runs - len(kept)} runs now" in r.stdout
    resumed = store.read().to_pylist()
    assert [x["run"] for x in resumed] == list(range(runs))
    assert not list((out / "runs").glob("*.tmp"))

    run_campaign(c, runs, tmp_path / "whole", workers=2, progress=False)
    whole = RunStore(tmp_path / "whole", c.columns()).read().to_pylist()
    assert repr(resumed) == repr(whole)
    summary = json.loads((out / "montecarlo.json").read_text())
    assert summary["runs"] == runs and summary["complete"]


def test_a_dask_localcluster_gives_the_same_rows(tmp_path):
    scn = with_overrides(load_scenario(FEASIBLE), duration=30)
    c = plan_campaign(scn, Dispersion(), seed=8)
    run_campaign(c, 8, tmp_path / "serial", workers=1, progress=False)
    res = run_campaign(c, 8, tmp_path / "dask", backend="dask", workers=2, batch_size=3, progress=False)
    assert res["backend"] == "dask" and res["scheduler"] == "LocalCluster" and res["workers"] == 2
    assert repr(RunStore(tmp_path / "dask", c.columns()).read().to_pylist()) == \
        repr(RunStore(tmp_path / "serial", c.columns()).read().to_pylist())
