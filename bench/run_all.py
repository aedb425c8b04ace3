"""Run every benchmark and write bench/results.json and bench/results.md.

    make bench            (or .venv/bin/python bench/run_all.py [--quick | --smoke] [BENCH ...])

BENCH: a script of bench/ (``bench_core.py``) or a path; default: BENCHES.
Each benchmark runs even when an earlier one failed; run_all then exits 1
and names every one that failed (a non-zero exit, or no fresh
results/NAME.json), so ``make bench`` fails. ``--smoke`` runs each in its
smoke mode (tiny sizes, a few seconds: a check that it runs, not a
measurement; tests/test_bench_smoke.py). With ``SC_RT_BENCH_RESULTS`` set
(bench/common.py), the results and results.json/.md go to that directory.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import RESULTS_ENV, results_dir  # noqa: E402

#: the benchmarks ``make bench`` runs, in order
BENCHES = ["bench_core.py", "bench_sim.py", "bench_montecarlo.py", "bench_hil.py", "bench_timing.py",
           "bench_external.py", "bench_report.py", "bench_mcap.py", "bench_sensors.py", "bench_live.py",
           "bench_env.py", "bench_day.py"]
#: benchmarks run on their own, not by ``make bench`` (each has --smoke, and tests/test_bench_smoke.py runs it)
OTHER_BENCHES = {
    "bench_format.py": "the run record's format (Arrow IPC, Parquet, npz) on a 10 min 1 kHz run: a one-off choice",
    "bench_netem.py": "needs root (network namespaces, nftables or tc netem); 12 cases of 30 s",
    "soak.py": "a 30-minute real-time run",
    "bench_day_lockstep.py": "day_hold in lockstep, bitwise against sim (24 h: as long as the lockstep loop takes)",
}
#: modules of bench/ that are no benchmark: shared code, and the delay line bench_netem runs
HELPERS = {"common.py", "netem_lab.py", "nfq_delay.py", "run_all.py"}


def result_name(script: str) -> str:
    """results/NAME.json of a benchmark script."""
    return Path(script).name.removeprefix("bench_").removesuffix(".py")


def run(script: str, flags: list[str]) -> tuple[dict | None, str | None]:
    """Run one benchmark: (its results, None) or (None, why it failed)."""
    path = Path(script) if os.sep in script else HERE / script
    if not path.is_file():
        return None, "not found"
    out = results_dir() / f"{result_name(script)}.json"
    t0 = time.time()
    r = subprocess.run([sys.executable, str(path), *flags], cwd=HERE)
    if r.returncode != 0:
        return None, f"exit code {r.returncode}"
    if not out.is_file() or out.stat().st_mtime < t0 - 1:
        return None, f"exited 0 but wrote no {out}"
    try:
        return json.loads(out.read_text()), None
    except ValueError as e:
        return None, f"{out}: {e}"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    flags = [a for a in argv if a in ("--quick", "--smoke")]
    unknown = [a for a in argv if a.startswith("-") and a not in flags]
    if unknown:
        print(f"run_all: unknown option {' '.join(unknown)}\n{__doc__}", file=sys.stderr)
        return 2
    benches = [a for a in argv if not a.startswith("-")] or BENCHES
    results, failed = {}, {}
    for b in benches:
        print(f"== {b}", flush=True)
        res, why = run(b, flags)
        if why is not None:
            print(f"{b} failed: {why}", file=sys.stderr, flush=True)
            failed[b] = why
        else:
            results[result_name(b)] = res
    where = results_dir() if os.environ.get(RESULTS_ENV) else HERE
    where.mkdir(parents=True, exist_ok=True)
    (where / "results.json").write_text(json.dumps(results, indent=2) + "\n")
    lines = ["| benchmark | figure | value | target |", "|---|---|---|---|"]
    for name, r in results.items():
        for k, v in r.items():
            if k == "machine" or isinstance(v, (dict, list)):
                continue
            if k.startswith("target_"):
                lines.append(f"| {name} | {k.removeprefix('target_')} | | {v} |")
            elif isinstance(v, float):
                lines.append(f"| {name} | {k} | {v:.4g} | |")
    (where / "results.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    if failed:
        print(f"run_all: {len(failed)} of {len(benches)} benchmarks failed: "
              + "; ".join(f"{b} ({why})" for b, why in failed.items()), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
