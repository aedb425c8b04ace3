"""The day in lockstep (issue 43's acceptance: "day_hold holds 24 h in
lockstep, bitwise = sim"): `sc-rt hil day_hold --mode lockstep` (the C++
controller process, the Python plant emulator and the logger over real LCM,
the rods commanded on SCRT_ROD_CMD and the field on SCRT_MAG), then
`sc-rt sim --engine cpp` of the same file and duration; every field both
runs produced compared bit for bit (tests/trajcmp.py compared_fields, the
rods' commands and the field included), the scenario's requirements as the
lockstep run judged them, and the lockstep loop's rate.

    .venv/bin/python bench/bench_day_lockstep.py [--quick | --smoke]

(full: 24 h, 864,001 rows; --quick: 1 h; --smoke: 60 s, a check that it runs.)
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import ROOT, machine, mode, write

sys.path.insert(0, str(ROOT / "tests"))
import lcmnet  # noqa: E402
from trajcmp import compared_fields, load_traj  # noqa: E402

from sc_rt.scenario.overrides import with_overrides  # noqa: E402
from sc_rt.scenario.reader import load_scenario  # noqa: E402
from sc_rt.sim.engines import simulate  # noqa: E402


def main(size: str = "full") -> None:
    duration = {"smoke": 60.0, "quick": 3600.0, "full": 86400.0}[size]
    res = {"machine": machine(), "scenario": "day_hold", "duration_s": duration, "netns": lcmnet.can_unshare()}
    with tempfile.TemporaryDirectory() as d:
        cmd = lcmnet.wrap([sys.executable, "-m", "sc_rt.cli", "hil", "day_hold", "--mode", "lockstep",
                           "--duration", f"{duration:g}", "--no-plots", "--out", d])
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=10 * 86400)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            raise RuntimeError(f"sc-rt hil day_hold exited {r.returncode}: {r.stderr[-2000:]}")
        hil = load_traj(d)
        metrics = json.loads((Path(d) / "metrics.json").read_text())
        timing = json.loads((Path(d) / "timing.json").read_text())
        t0 = time.perf_counter()
        scn = with_overrides(load_scenario("day_hold"), duration=duration)
        run = simulate(scn, engine="cpp")
        sim_wall = time.perf_counter() - t0
        every = scn.record.every  # the file keeps every `[record] every`-th row, the simulation all of them
        sim = {k: run[k][::every] for k in hil.files if k != "meta_json" and k in run}
        try:
            fields, why = compared_fields(hil, sim), None
        except AssertionError as e:  # the first field that differs, named
            fields, why = [], str(e)
    rows = len(run["t"])
    res.update({
        "rows": rows,
        "rows_compared": len(hil["t"]),
        "valid": metrics.get("valid"),
        "requirements": {q["name"]: q.get("status") for q in metrics.get("requirements", [])},
        "lockstep_wall_s": wall,  # the whole command: start-up, the loop, the record, the report
        "lockstep_steps_per_s": timing["steps_per_s"],  # the loop's own (timing.json)
        "sim_cpp_wall_s": sim_wall,
        "bitwise_equal_sim": why is None,
        "fields_compared": fields,
        "first_difference": why,
        "target_bitwise_equal_sim": "pass" if why is None else "miss",
    })
    write("day_lockstep", res)


if __name__ == "__main__":
    main(mode())
