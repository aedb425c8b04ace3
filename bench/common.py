"""Shared helpers of the benchmarks: timing statistics, machine info, JSON.

Every benchmark has a smoke mode (``--smoke``): tiny sizes, a few seconds,
the same structure of results; it checks that the benchmark still runs
(tests/test_bench_smoke.py), never how fast. ``SC_RT_BENCH_RESULTS`` names
another directory for the results (the tests' temporary one): a smoke run
does not overwrite the measured bench/results/.
"""

from __future__ import annotations

import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

#: the environment variable naming the results directory (default bench/results)
RESULTS_ENV = "SC_RT_BENCH_RESULTS"

#: ``sc-rt hil`` options of a benchmark's run: a real-time run that misses
#: deadlines or uses stale states is what the benchmark measures and reports,
#: not an invalid run (sc-rt hil's default --rt-limits would fail it, exit 1)
HIL_MEASURE = ["--rt-limits", "misses=1,skipped=1,dropped=1,stale=1"]


def hil_timing(returncode: int, run_dir: Path, what: str, stderr: str = "") -> dict:
    """timing.json of a finished ``sc-rt hil`` run in run_dir. A real-time
    run that did not keep real time (exit 1, ``kept_real_time`` false) is a
    measurement here, not a failure: its numbers say by how much it missed,
    and ``kept_real_time`` is in what the benchmark reports. Any other
    non-zero exit raises, naming ``what``."""
    timing = Path(run_dir) / "timing.json"
    missed = returncode == 1 and timing.is_file() and \
        json.loads(timing.read_text()).get("kept_real_time") is False
    if returncode != 0 and not missed:
        raise RuntimeError(f"{what}: sc-rt hil exited {returncode}: {stderr[-2000:]}")
    return json.loads(timing.read_text())


def results_dir() -> Path:
    return Path(os.environ.get(RESULTS_ENV) or ROOT / "bench" / "results")


def mode(argv: list[str] | None = None) -> str:
    """The run's size from the command line: "smoke", "quick" or "full" (--smoke wins)."""
    argv = sys.argv if argv is None else argv
    return "smoke" if "--smoke" in argv else "quick" if "--quick" in argv else "full"


def machine() -> dict:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cores": os.cpu_count(), "cpu": cpu, "kernel": platform.release(),
            "python": platform.python_version()}


def summary(samples, unit: str) -> dict:
    v = np.asarray(samples, float)
    return {"unit": unit, "n": int(v.size), "median": float(np.median(v)),
            "p99": float(np.percentile(v, 99)), "min": float(v.min()), "max": float(v.max())}


def repeat(fn, runs: int, warmup: int = 1) -> list[float]:
    """Wall time [s] of fn() over runs, after warm-up calls."""
    for _ in range(warmup):
        fn()
    out = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def alternate(fns: dict, runs: int, warmup: int = 1) -> dict[str, list[float]]:
    """Time several functions alternately in one invocation (the machine is
    shared and drifts: a ratio of interleaved runs is what can be trusted)."""
    for f in fns.values():
        for _ in range(warmup):
            f()
    out = {k: [] for k in fns}
    for _ in range(runs):
        for k, f in fns.items():
            t0 = time.perf_counter()
            f()
            out[k].append(time.perf_counter() - t0)
    return out


def _not_judged(d: dict) -> None:
    """Every target_* verdict, at any depth, replaced by "not judged"."""
    for k, v in d.items():
        if isinstance(v, dict):
            _not_judged(v)
        elif k.startswith("target_") and v in ("pass", "miss"):
            d[k] = "not judged (smoke run)"


def write(name: str, result: dict) -> None:
    """The results as results_dir()/NAME.json, and printed; with the mode
    they were measured in. A smoke run's figures are no measurement: its
    verdicts on the targets ("pass"/"miss") are replaced by "not judged"."""
    result.setdefault("mode", mode())
    if result["mode"] == "smoke":
        _not_judged(result)
    path = results_dir() / f"{name}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


def median(v) -> float:
    return statistics.median(v)
