"""Run every benchmark and write bench/results.json and bench/results.md.

    make bench            (or .venv/bin/python bench/run_all.py [--quick])
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
BENCHES = ["bench_core.py", "bench_sim.py", "bench_montecarlo.py", "bench_hil.py", "bench_timing.py", "bench_external.py", "bench_report.py", "bench_mcap.py",
           "bench_sensors.py"]


def main() -> int:
    quick = "--quick" in sys.argv
    results = {}
    for b in BENCHES:
        print(f"== {b}", flush=True)
        r = subprocess.run([sys.executable, str(HERE / b)] + (["--quick"] if quick else []), cwd=HERE)
        if r.returncode != 0:
            print(f"{b} failed with exit code {r.returncode}", file=sys.stderr)
            continue
        name = b.removeprefix("bench_").removesuffix(".py")
        results[name] = json.loads((HERE / "results" / f"{name}.json").read_text())
    (HERE / "results.json").write_text(json.dumps(results, indent=2) + "\n")
    lines = ["| benchmark | figure | value | target |", "|---|---|---|---|"]
    for name, r in results.items():
        for k, v in r.items():
            if k == "machine" or isinstance(v, (dict, list)):
                continue
            if k.startswith("target_"):
                lines.append(f"| {name} | {k.removeprefix('target_')} | | {v} |")
            elif isinstance(v, float):
                lines.append(f"| {name} | {k} | {v:.4g} | |")
    (HERE / "results.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
