"""Your own controller on the bench, lockstep throughput (steps/s, target for
the external example >= 1000): sc-rt-controller (C++, status per step), a
Python law in `sc-rt controller` (status per step) and the plain-Python
external example (sc_rt_lcm only, no status), each on paper_faults through
`sc-rt hil`, alternately, twice (the machine drifts); and the Python law in
real time at 10 and 100 Hz (lateness, misses, latency). Runs in a private
network namespace when root.

    .venv/bin/python bench/bench_external.py [--quick | --smoke]

(--quick: 60 s lockstep, 5 s real time, once; --smoke: 5 s lockstep, 1 s
real time, once: a check that it runs.)
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

from common import HIL_MEASURE, ROOT, hil_timing, machine, mode, write

sys.path.insert(0, str(ROOT / "tests"))
import lcmnet  # noqa: E402

EXAMPLE = ROOT / "examples" / "external_controller" / "qfb_controller.py"
PY_LAW = str(ROOT / "examples" / "python_laws" / "pd.py") + ":PythonPD"
CONTROLLERS = {
    "cpp_pd": ["--law", "pd"],
    "python_law_pd": ["--law", PY_LAW],
    "external_example": ["--external", f"{{python}} {EXAMPLE}"],
}


def hil(args: list[str]) -> dict:
    with tempfile.TemporaryDirectory() as d:
        cmd = lcmnet.wrap([sys.executable, "-m", "sc_rt.cli", "hil", "paper_faults", "--no-plots",
                           "--out", d, *HIL_MEASURE, *args])
        r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=900)
        t = hil_timing(r.returncode, Path(d), " ".join(args), r.stderr)
        t["law"] = json.loads((Path(d) / "metrics.json").read_text())["controller"]
        return t


def main(size: str = "full") -> None:
    quick = size != "full"
    smoke = size == "smoke"
    res: dict = {"machine": machine(), "scenario": "paper_faults", "netns": lcmnet.can_unshare(),
                 "lockstep_duration_s": 5 if smoke else 60 if quick else 300}
    runs: dict[str, list[float]] = {k: [] for k in CONTROLLERS}
    for _ in range(1 if quick else 2):
        for name, args in CONTROLLERS.items():
            t = hil(["--mode", "lockstep", "--duration", str(res["lockstep_duration_s"]), *args])
            runs[name].append(t["steps_per_s"])
            res[f"{name}_law"] = t["law"]
            res[f"{name}_latency_us"] = t["state_to_cmd_latency_us"]
    for name, v in runs.items():
        res[f"{name}_steps_per_s_runs"] = v
        res[f"{name}_steps_per_s"] = min(v)
    res["target_external_ge_1000"] = "pass" if res["external_example_steps_per_s"] >= 1000 else "miss"
    rt_duration = "1" if smoke else "5" if quick else "20"
    for rate in (10, 100):
        t = hil(["--mode", "realtime", "--control-rate", str(rate), "--duration", rt_duration, "--law", PY_LAW])
        res[f"python_law_realtime_{rate}hz"] = {
            k: t[k] for k in ("steps", "deadline_misses", "wake_lateness_us", "compute_us",
                              "state_to_cmd_latency_us", "state_age_us", "stale_states", "dropped")}
    write("external", res)


if __name__ == "__main__":
    main(mode())
