"""Shared helpers of the benchmarks: timing statistics, machine info, JSON."""

from __future__ import annotations

import json
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


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


def write(name: str, result: dict) -> None:
    path = ROOT / "bench" / "results" / f"{name}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


def median(v) -> float:
    return statistics.median(v)
