"""Monte Carlo campaign throughput (``sc-rt montecarlo``): runs/s at 1 and 2
workers for the local process pool and a Dask LocalCluster, the per-run
overhead of each, the seeding cost at run ids 0 and 10^6, the dataset's
bytes per row, and the extrapolated wall time of a 10^5-run campaign.
scenarios/ppc_feasible_10hz.toml, DSC+PPC, 300 s at 10 Hz per run, C++
engine, the default shortcut dispersions; whole campaigns (rows written to
the Parquet dataset as they complete), timed alternately (the machine is
shared: pool and Dask see the same load).

    .venv/bin/python bench/bench_montecarlo.py [--quick | --smoke]

(--smoke: campaigns of 8 runs, one repetition, few in-process runs: a check
that it runs, pool and Dask included.)
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
from common import ROOT, machine, mode, write

from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate
from sc_rt.studies.campaign import (Campaign, Dispersion, RunStore, plan_campaign, run_campaign, run_one,
                                   run_seed_sequence)
from sc_rt.studies.campaign.backends import DaskBackend, PoolBackend


def seeding_cost(seed: int, run: int, n: int = 2000) -> float:
    """[s] building run ``run``'s generator (what a worker does per run)."""
    t0 = time.perf_counter()
    for _ in range(n):
        np.random.default_rng(run_seed_sequence(seed, run))
    return (time.perf_counter() - t0) / n


def old_seeding_cost(seed: int, run: int) -> float:
    """[s] the former seeding, the run-th child of SeedSequence(seed).spawn(run + 1): O(run)."""
    t0 = time.perf_counter()
    np.random.default_rng(np.random.SeedSequence(seed).spawn(run + 1)[run])
    return time.perf_counter() - t0


def campaign_rate(c: Campaign, runs: int, backend, tmp: Path, tag: str) -> tuple[float, int]:
    out = tmp / tag
    t0 = time.perf_counter()
    run_campaign(c, runs, out, overwrite=True, progress=False, backend_obj=backend)
    wall = time.perf_counter() - t0
    return runs / wall, RunStore(out, c.columns()).bytes()


def dataset_sizes(c: Campaign, out: Path) -> dict:
    """Bytes per row of the dataset: in files of 64 rows (the batch size of a
    large campaign) and in one file (compacted), extrapolated to 10^5 runs."""
    import pyarrow.parquet as pq

    t = RunStore(out, c.columns()).read()
    sizes = {}
    for label, per_file in (("batch_64", 64), ("one_file", t.num_rows)):
        total = 0
        for k in range(0, t.num_rows, per_file):
            p = out / f"size-{label}-{k}.parquet"
            pq.write_table(t.slice(k, per_file), p, compression="zstd")
            total += p.stat().st_size
        sizes[f"dataset_bytes_per_row_{label}"] = total / t.num_rows
        sizes[f"dataset_mb_1e5_runs_{label}"] = total / t.num_rows * 1e5 / 1e6
    sizes["dataset_columns"] = t.num_columns
    return sizes


def main(size: str = "full") -> None:
    scn = load_scenario(ROOT / "scenarios" / "ppc_feasible_10hz.toml")
    c = plan_campaign(scn, Dispersion(), seed=0)
    smoke = size == "smoke"
    runs = {"full": 600, "quick": 200, "smoke": 8}[size]
    reps = 1 if smoke else 2
    inproc = 5 if smoke else 100  # in-process runs timed
    res: dict = {"machine": machine(), "scenario": "ppc_feasible_10hz", "runs_per_campaign": runs,
                 "repetitions": reps, "statistic": "best of the repetitions (least disturbed)"}
    # in-process cost of one run: the bare C++ simulation, and a campaign run (draw + simulate + row)
    for _ in range(inproc // 5):
        simulate(scn, engine="cpp")
    t0 = time.perf_counter()
    for _ in range(inproc):
        simulate(scn, engine="cpp")
    res["simulate_s"] = (time.perf_counter() - t0) / inproc
    t0 = time.perf_counter()
    for i in range(inproc):
        run_one(c, i)
    res["run_one_s"] = (time.perf_counter() - t0) / inproc

    n_seed = 100 if smoke else 2000
    res["seeding_s_id_0"] = seeding_cost(0, 0, n_seed)
    res["seeding_s_id_1e6"] = seeding_cost(0, 10**6, n_seed)
    res["seeding_ratio_1e6_over_0"] = res["seeding_s_id_1e6"] / res["seeding_s_id_0"]
    res["old_seeding_s_id_1e4"] = old_seeding_cost(0, 10**4)
    res["old_seeding_s_id_1e5"] = old_seeding_cost(0, 10**5)

    rates: dict[str, list[float]] = {}
    bytes_ = 0
    with tempfile.TemporaryDirectory(prefix="bench-mc-") as tmpdir:
        tmp = Path(tmpdir)
        backends = {}
        try:
            for w in (1, 2):
                backends[f"pool_{w}"] = PoolBackend(w)
                backends[f"dask_{w}"] = DaskBackend(w)  # cluster start-up is not timed
            for name, b in backends.items():  # warm-up: worker start, imports
                campaign_rate(c, 4 * b.workers, b, tmp, name)
            for _ in range(reps):
                for name, b in backends.items():
                    rate, nbytes = campaign_rate(c, runs, b, tmp, name)
                    rates.setdefault(name, []).append(rate)
                    bytes_ = max(bytes_, nbytes)
            res.update(dataset_sizes(c, tmp / "pool_2"))
        finally:
            for b in backends.values():
                b.close()
    for name, v in rates.items():
        best = max(v)
        w = int(name.rsplit("_", 1)[1])
        res[f"runs_per_s_{name}"] = best
        res[f"all_runs_per_s_{name}"] = v
        # per-run overhead: what a worker spends per run beyond the in-process campaign run
        res[f"overhead_s_per_run_{name}"] = w / best - res["run_one_s"]
    for kind in ("pool", "dask"):
        res[f"scaling_{kind}_2_over_1"] = res[f"runs_per_s_{kind}_2"] / res[f"runs_per_s_{kind}_1"]
        res[f"efficiency_{kind}_2"] = res[f"scaling_{kind}_2_over_1"] / 2
    res["dask_efficiency_over_pool_2"] = res["efficiency_dask_2"] / res["efficiency_pool_2"]
    res["dask_throughput_over_pool_2"] = res["runs_per_s_dask_2"] / res["runs_per_s_pool_2"]
    res["target_dask_efficiency_over_pool_2"] = 0.9
    res["dataset_bytes_per_row_as_run"] = bytes_ / runs
    for kind in ("pool", "dask"):
        res[f"wall_s_1e5_runs_{kind}_2"] = 1e5 / res[f"runs_per_s_{kind}_2"]
    write("montecarlo", res)


if __name__ == "__main__":
    main(mode())
