"""Throughput of ``sc-rt export LOG --mcap OUT`` on a 1-million-event log.

The log is the one of bench_report.py (250 000 control steps of a 100 Hz
run: plant_state_t, plant_truth_t, wheel_cmd_t, controller_status_t each,
plus the config and a foreign event). Figures: the whole conversion (read,
decode, JSON, derived channels, zstd-compressed MCAP, rename), events/s,
and the MCAP's size; the issue asks for a million events "in seconds".

    .venv/bin/python bench/bench_mcap.py [--quick | --smoke]

(--quick: 25 000 steps; --smoke: 2 000 steps, a check that it runs.)
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from bench_report import STEPS, make_log
from common import machine, mode, write

from sc_rt.export.mcap_export import export_mcap  # noqa: E402


def main() -> None:
    size = mode()
    steps = STEPS[size]
    res = {"machine": machine()}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.lcmlog"
        t0 = time.perf_counter()
        n = make_log(path, steps)
        res["events"] = n
        res["log_mb"] = path.stat().st_size / 1e6
        res["generate_s"] = time.perf_counter() - t0
        runs = []
        for _ in range(2 if size == "full" else 1):
            out = Path(tmp) / "bench.mcap"
            s = export_mcap(path, out)
            assert s.events == n and s.undecodable == 0, (s.events, s.undecodable)
            runs.append(s.seconds)
            res["mcap_mb"] = out.stat().st_size / 1e6
            res["messages"] = s.messages
            res["derived"] = s.derived
        res["export_s_runs"] = runs
        res["export_s"] = min(runs)
        res["events_per_s"] = n / res["export_s"]
    res["target_1e6_events_in_seconds"] = (("pass" if res["export_s"] < 60 else "miss") if size == "full"
                                           else f"not measured ({size}: {n} events)")
    write("mcap", res)


if __name__ == "__main__":
    main()
