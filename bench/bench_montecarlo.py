"""Monte Carlo throughput (runs/s) of `sc-rt montecarlo` on all cores and on
one, paper fault scenario, DSC+PPC, 300 s at 10 Hz per run (C++ engine).

    .venv/bin/python bench/bench_montecarlo.py [--quick]
"""

from __future__ import annotations

import os
import sys

from common import ROOT, machine, write

from sc_rt.studies.montecarlo import run_montecarlo
from sc_rt.scenario.model import load_scenario


def main(quick: bool = False) -> None:
    scn = load_scenario(ROOT / "scenarios" / "paper_faults.toml")
    runs = 40 if quick else 200
    res = {"machine": machine(), "runs": runs}
    for workers in (1, os.cpu_count() or 1):
        r = run_montecarlo(scn, runs, workers=workers, seed=0, progress=False)
        res[f"runs_per_s_{workers}_workers"] = r["runs_per_s"]
    n = os.cpu_count() or 1
    res["scaling_all_cores_over_one"] = res[f"runs_per_s_{n}_workers"] / res["runs_per_s_1_workers"]
    write("montecarlo", res)


if __name__ == "__main__":
    main("--quick" in sys.argv)
