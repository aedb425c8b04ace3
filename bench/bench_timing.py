"""The bench's timing targets (issue #16), each the median of 3 runs:

  100 Hz real time  : >= 99.99 % of control steps use a state of the current
                      period; latency p99 <= 250 us
  1 kHz real time   : >= 99.9 % fresh; latency p50 <= 100 us, p99 <= 250 us;
                      deadline misses <= 0.1 %; emulator tick lateness p99 <= 100 us,
                      also in the 256 rows after each record spill (spill_lateness)
  lockstep + logger : >= 5,000 steps/s; latency p99 <= 2 x the LCM floor's p99
  lockstep 1 kHz    : >= 6,000 steps/s with the logger (ppc_feasible_1khz, 60 s; issue 42 item 5)
                      (sc-rt-lcm-pingpong, measured before each run)

Defaults rows: `sc-rt hil --mode realtime` at 10 and 100 Hz without any
timing flag (issue #31: >= 99.99 % fresh). Real-time rows: 60 s runs
(--quick: 10 s), the event-triggered controller,
SCHED_FIFO + mlockall for the controller and the emulator when permitted
(--no-priority: without), each run with its bench floor (sc-rt hil --floor
auto). The timer-triggered controller is run once per rate for the trade-off.
Lockstep: 30,001 steps (--quick: 3,001). --smoke: one 1 s run per row, a
501-step lockstep and a 300-message floor, the timer and the CPU placement
at 1 kHz once each, no profile: a check that it runs. Each row prints
target / measured / miss-by and the breakdown (the emulator's stamps, the
controller's status, the LCM floor); a missed row is profiled (cProfile of
the emulator process, a 5 s run: the top functions by own time). The load
average is recorded next to every run.

    .venv/bin/python bench/bench_timing.py [--quick | --smoke] [--no-priority]
        [--rows defaults,100hz,1khz,lockstep,lockstep1k,timer,pin]

Exits 1 when a row failed to run (the others are still run and written).
"""

from __future__ import annotations

import json
import os
import pstats
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from common import HIL_MEASURE, ROOT, hil_timing, machine, mode, write

sys.path.insert(0, str(ROOT / "tests"))
import lcmnet  # noqa: E402

SCENARIO = "scenarios/paper_faults.toml"


def hil(args: list[str], profile: Path | None = None, scenario: str = SCENARIO) -> dict:
    with tempfile.TemporaryDirectory() as d:
        pre = [sys.executable] + (["-m", "cProfile", "-o", str(profile)] if profile else []) + ["-m", "sc_rt.cli"]
        cmd = lcmnet.wrap(pre + ["hil", scenario, "--no-plots", "--out", d, *HIL_MEASURE, *args])
        load = os.getloadavg()
        r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=1800)
        t = hil_timing(r.returncode, Path(d), " ".join(args), r.stderr)
        t["load_avg_before"] = list(load)
        if t.get("mode") == "realtime":
            t["spill"] = spill_lateness(Path(d))
        return t


#: [rows] the rows after each hand-over of a record chunk to the writer thread
#: judged as "around a spill" (0.256 s at 1 kHz: an LZ4 compression of a
#: chunk took 2-22 ms inside the tick before the writer thread)
SPILL_WINDOW = 256


def spill_lateness(run_dir: Path) -> dict:
    """The emulator's tick lateness [us] in the SPILL_WINDOW rows after each
    hand-over of a record chunk (rows 2 CHUNK_ROWS, 3 CHUNK_ROWS, ...:
    emulator/record.py) against the other rows, and the times the tick
    waited for the writer: the effect of a spill on the tick (issue 42 item 4)."""
    import numpy as np

    from sc_rt.logs.timing import percentiles
    from sc_rt.results.record.run import Run
    from sc_rt.results.record.store import CHUNK_ROWS

    run = Run.load(run_dir)
    lat = np.concatenate([np.asarray(c["tick_lateness_us"], float) for c in run.chunks()])
    idx = np.arange(lat.size)
    near = (idx >= 2 * CHUNK_ROWS) & (idx % CHUNK_ROWS < SPILL_WINDOW)
    spills = max(0, (lat.size - 1) // CHUNK_ROWS - 1)
    return {"spills": spills, "window_rows": SPILL_WINDOW, "chunk_rows": CHUNK_ROWS,
            "around_spills_us": percentiles(lat[near]), "elsewhere_us": percentiles(lat[~near]),
            "record_writer_waits": (run.timing or {}).get("record_writer_waits")}


def lcm_floor(count: int, fifo: bool) -> dict:
    """The C++ LCM round trip (sc-rt-lcm-pingpong), in the same namespace as
    the runs, at the controller's scheduler."""
    code = ("import json; from sc_rt.hil.floor import lcm_round_trip; "
            f"print(json.dumps(lcm_round_trip({count}, 'udpm://239.255.76.67:7721?ttl=0', fifo={fifo})))")
    r = subprocess.run(lcmnet.wrap([sys.executable, "-c", code]), capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        raise RuntimeError(r.stderr)
    return json.loads(r.stdout.strip().splitlines()[-1])


def med(runs: list[dict], *path: str):
    vals = []
    for r in runs:
        v = r
        for p in path:
            v = (v or {}).get(p) if isinstance(v, dict) else None
        if v is not None:
            vals.append(v)
    return statistics.median(vals) if vals else None


def check(name: str, measured, op: str, target: float, unit: str) -> dict:
    ok = measured is not None and (measured >= target if op == ">=" else measured <= target)
    if measured is None:
        miss = "not measured"
    elif ok:
        miss = ""
    elif op == ">=":
        miss = f"short by {target - measured:.4g} {unit}".strip()
    else:
        miss = f"over by {measured - target:.4g} {unit} ({measured / target:.2f}x)".strip()
    return {"figure": name, "target": f"{op} {target:g} {unit}".strip(), "measured": measured,
            "unit": unit, "pass": ok, "miss_by": miss}


def breakdown(runs: list[dict]) -> dict:
    """Medians over the runs of the p50 / p99 of each part [us]."""
    out = {}
    for part in ("integrate", "publish_state", "truth_record", "wait_answer", "state_to_controller_publish",
                 "controller_publish_to_handled"):
        p50, p99 = med(runs, "emulator_breakdown_us", part, "p50"), med(runs, "emulator_breakdown_us", part, "p99")
        if p50 is not None:
            out[f"emulator {part}"] = {"p50": p50, "p99": p99}
    for key, name in (("compute_us", "controller compute"), ("state_age_us", "controller state age"),
                      ("wake_lateness_us", "controller wake lateness"),
                      ("emulator_tick_lateness_us", "emulator tick lateness")):
        p50 = med(runs, key, "p50")
        if p50 is not None:
            out[name] = {"p50": p50, "p99": med(runs, key, "p99")}
    f50 = med(runs, "floor", "latency_us", "p50")
    if f50 is not None:
        out["floor latency (null controller)"] = {"p50": f50, "p99": med(runs, "floor", "latency_us", "p99")}
        out["floor LCM round trip"] = {"p50": med(runs, "floor", "lcm_rtt_us", "p50"),
                                       "p99": med(runs, "floor", "lcm_rtt_us", "p99")}
    return out


def profile_row(args: list[str]) -> list[dict]:
    """cProfile of the sc-rt hil process (the emulator's loop) for a 5 s run:
    the top functions by own time, per call [us]."""
    with tempfile.TemporaryDirectory() as d:
        prof = Path(d) / "emu.prof"
        hil(args, profile=prof)
        st = pstats.Stats(str(prof))
        rows = []
        for (file, line, fn), (_cc, nc, tt, ct, _callers) in st.stats.items():
            rows.append({"function": f"{Path(file).name}:{line}({fn})", "calls": nc, "own_s": tt, "cum_s": ct,
                         "own_us_per_call": 1e6 * tt / nc if nc else None})
        rows.sort(key=lambda r: -r["own_s"])
        return rows[:15]


def why(row: str, runs: list[dict], checks: list[dict]) -> str:
    """The measured reason of a miss, from the breakdown."""
    b = breakdown(runs)
    missed = [c["figure"] for c in checks if not c["pass"]]
    if not missed:
        return ""
    parts = []
    for k in ("emulator state_to_controller_publish", "emulator controller_publish_to_handled",
              "emulator publish_state", "emulator truth_record", "emulator wait_answer", "emulator tick lateness",
              "floor latency (null controller)"):
        if k in b:
            parts.append(f"{k} p50/p99 {b[k]['p50']:.0f}/{b[k]['p99']:.0f} us")
    late = [r.get("emulator_breakdown_us", {}).get("late_answers") for r in runs]
    late = [x for x in late if x and x.get("count")]
    if late:
        n = sum(x["count"] for x in late)
        of = sum(x["of"] for x in late)
        s = statistics.median(x["state_to_controller_publish"]["p50"] for x in late)
        b_ = statistics.median(x["controller_publish_to_handled"]["p50"] for x in late)
        parts.append(f"{n} of {of} answers came after the tick that needed them; in those, state to the "
                     f"controller's publish p50 {s:.0f} us, back to the emulator p50 {b_:.0f} us")
    return f"missed {', '.join(missed)}; measured: " + "; ".join(parts)


def realtime_row(rate: int, runs_n: int, dur: float, prio: list[str] | None, trigger: str | None = "event",
                 extra: tuple[str, ...] = ()) -> dict:
    """prio None and trigger None: sc-rt hil's defaults (no timing flag at all)."""
    args = ["--mode", "realtime", "--control-rate", str(rate), "--duration", f"{dur:g}", "--floor", "auto",
            *(["--trigger", trigger] if trigger else []), *(prio or []), *extra]
    runs = [hil(args) for _ in range(runs_n)]
    lat50, lat99 = med(runs, "state_to_cmd_latency_us", "p50"), med(runs, "state_to_cmd_latency_us", "p99")
    fresh = med(runs, "fresh_fraction")
    miss = statistics.median([r["deadline_misses"] / max(1, r["steps"]) for r in runs])
    checks = [check("fresh (plant applied the answer to the period's state)",
                    None if fresh is None else 100 * fresh, ">=", 99.9 if rate == 1000 else 99.99, "%")]
    if rate == 1000:
        checks.append(check("latency p50", lat50, "<=", 100, "us"))
    checks.append(check("latency p99", lat99, "<=", 250, "us"))
    if rate == 1000:
        checks.append(check("deadline misses", 100 * miss, "<=", 0.1, "%"))
        checks.append(check("emulator tick lateness p99", med(runs, "emulator_tick_lateness_us", "p99"), "<=", 100,
                            "us"))
        checks.append(check(f"tick lateness p99, {SPILL_WINDOW} rows after a spill",
                            med(runs, "spill", "around_spills_us", "p99"), "<=", 100, "us"))
    return {"args": args, "runs": len(runs), "duration_s": dur, "trigger": runs[-1].get("trigger"),
            "scheduler": runs[-1]["scheduler"], "emulator_scheduler": runs[-1].get("emulator_scheduler"),
            "load_avg": [r["load_avg_before"] for r in runs],
            "controller_fresh_pct": None if med(runs, "controller_fresh_fraction") is None
            else 100 * med(runs, "controller_fresh_fraction"),
            "latency_us": {"p50": lat50, "p99": lat99}, "deadline_miss_fraction": miss,
            "floor_line": [r.get("over_floor", {}).get("line") for r in runs],
            "checks": checks, "breakdown_us": breakdown(runs), "why": why(f"{rate} Hz", runs, checks),
            "per_run": [{k: r.get(k) for k in ("steps", "deadline_misses", "fresh_fraction",
                                                "controller_fresh_fraction", "state_to_cmd_latency_us",
                                                "emulator_tick_lateness_us", "spill", "kept_real_time",
                                                "load_avg_before")}
                        for r in runs]}


def lockstep_row(runs_n: int, dur: float, prio: list[str], floor_count: int = 5000, scenario: str = SCENARIO,
                 target: float = 5000) -> dict:
    """Lockstep with the logger: steps/s against ``target`` (5,000 at 10 Hz on
    paper_faults, issue #16; 6,000 at 1 kHz on ppc_feasible_1khz, issue 42
    item 5: a 1 h run at 1 kHz in <= 10 min)."""
    args = ["--mode", "lockstep", "--duration", f"{dur:g}", *prio]
    runs, floors = [], []
    for _ in range(runs_n):  # the floor and the loop alternately: the machine drifts
        floors.append(lcm_floor(floor_count, "--no-realtime-priority" not in prio))
        runs.append(hil(args, scenario=scenario))
    sps = med(runs, "steps_per_s")
    lat99 = med(runs, "state_to_cmd_latency_us", "p99")
    ratios = [r["state_to_cmd_latency_us"]["p99"] / f["rtt_us"]["p99"] for r, f in zip(runs, floors)]
    checks = [check("steps/s with sc-rt-logger", sps, ">=", target, "steps/s"),
              check("latency p99 / LCM floor p99 (same run)", statistics.median(ratios), "<=", 2.0, "x")]
    b = breakdown(runs)
    b["LCM floor round trip"] = {"p50": statistics.median(f["rtt_us"]["p50"] for f in floors),
                                 "p99": statistics.median(f["rtt_us"]["p99"] for f in floors)}
    return {"scenario": scenario, "args": args, "runs": len(runs), "steps": runs[-1]["rows"],
            "scheduler": runs[-1]["scheduler"], "emulator_scheduler": runs[-1].get("emulator_scheduler"),
            "load_avg": [r["load_avg_before"] for r in runs],
            "steps_per_s_runs": [r["steps_per_s"] for r in runs],
            "latency_us": {"p50": med(runs, "state_to_cmd_latency_us", "p50"), "p99": lat99},
            "lcm_floor_rtt_us": [f["rtt_us"] for f in floors], "latency_p99_over_floor_p99": ratios,
            "checks": checks, "breakdown_us": b, "why": why("lockstep", runs, checks)}


def table(res: dict) -> str:
    lines = [f"{'row':<26} {'figure':<52} {'target':>14} {'measured':>12}  result",
             "-" * 120]
    for name, row in res["rows"].items():
        for c in row["checks"]:
            m = "-" if c["measured"] is None else f"{c['measured']:.4g}"
            lines.append(f"{name:<26} {c['figure']:<52} {c['target']:>14} {m:>12}  "
                         + ("pass" if c["pass"] else f"MISS: {c['miss_by']}"))
        lines.append(f"{'':<26} load {' | '.join(' '.join(f'{x:.1f}' for x in la) for la in row['load_avg'])}; "
                     f"controller {row['scheduler']}; emulator {row.get('emulator_scheduler')}")
        for part, v in row["breakdown_us"].items():
            lines.append(f"{'':<26}   {part:<48} p50 {v['p50']:8.1f}  p99 {v['p99'] or 0:8.1f} us")
        if row.get("why"):
            lines.append(f"{'':<26} why: {row['why']}")
        for p in row.get("profile_top", [])[:6]:
            lines.append(f"{'':<26}   profile {p['function']:<60} {p['calls']:>8} calls "
                         f"{p['own_us_per_call'] or 0:8.1f} us own/call")
    return "\n".join(lines)


def main() -> int:
    size = mode()
    quick = size != "full"
    smoke = size == "smoke"
    no_prio = "--no-priority" in sys.argv
    prio = ["--no-realtime-priority"] if no_prio else ["--realtime-priority"]
    want = "defaults,100hz,1khz,lockstep,lockstep1k,timer,pin"
    if "--rows" in sys.argv:
        want = sys.argv[sys.argv.index("--rows") + 1]
    want = want.split(",")
    n, dur = (1, 1.0) if smoke else (1, 10.0) if quick else (3, 60.0)
    lock_dur = 5.0 if smoke else 300.0 if quick else 3000.0
    res = {"machine": machine(), "scenario": "paper_faults", "netns": lcmnet.can_unshare(), "quick": quick,
           "priority": not no_prio, "rows": {}}
    sched = "OTHER" if no_prio else "FIFO"
    jobs = []
    if "defaults" in want:  # `sc-rt hil --mode realtime` without a timing flag (issue #31, item 6)
        for rate in (100,) if smoke else (10, 100):
            jobs.append((f"{rate:g} Hz, hil's defaults", lambda rate=rate: realtime_row(rate, n, dur, None, None)))
    if "100hz" in want:
        jobs.append((f"100 Hz, event, {sched}", lambda: realtime_row(100, n, dur, prio)))
    if "1khz" in want:
        jobs.append((f"1 kHz, event, {sched}", lambda: realtime_row(1000, n, dur, prio)))
    if "lockstep" in want:
        jobs.append(("lockstep + sc-rt-logger", lambda: lockstep_row(n, lock_dur, prio, 300 if smoke else 5000)))
    if "lockstep1k" in want:  # issue 42 item 5: 1 kHz lockstep with the logger, >= 6,000 steps/s
        jobs.append(("lockstep 1 kHz + sc-rt-logger",
                     lambda: lockstep_row(n, 1.0 if smoke else 10.0 if quick else 60.0, prio, 300 if smoke else 5000,
                                          scenario="ppc_feasible_1khz", target=6000)))
    if "timer" in want:  # the trade-off: the own-clock controller, one run per rate
        for rate in (1000,) if smoke else (100, 1000):
            jobs.append((f"{rate:g} Hz, timer, {sched}",
                         lambda rate=rate: realtime_row(rate, 1, dur, prio, trigger="timer")))
    if "pin" in want:  # CPU placement, one run each: both on CPU 0, or the controller on CPU 1
        placements = [("same CPU 0", ("--controller-cpu", "0", "--emulator-cpu", "0")),
                      ("controller CPU 1, emulator CPU 0", ("--controller-cpu", "1", "--emulator-cpu", "0"))]
        for label, extra in placements[-1:] if smoke else placements:
            jobs.append((f"1 kHz, event, {sched}, {label}",
                         lambda extra=extra: realtime_row(1000, 1, dur, prio, extra=extra)))
    for name, job in jobs:
        try:
            res["rows"][name] = job()
        except RuntimeError as e:  # one row failing (a broken tree, a crash) keeps the others
            res.setdefault("failed", {})[name] = str(e)[-1500:]
            print(f"{name}: failed: {str(e)[-300:]}", file=sys.stderr)
        write("timing", res)  # after every row: a late failure loses nothing
    if not smoke and ("--profile" in sys.argv or not quick):
        for row in res["rows"].values():
            if any(not c["pass"] for c in row["checks"]):
                args = list(row["args"])
                args[args.index("--duration") + 1] = "5" if "realtime" in args else "300"
                if "--floor" in args:
                    args[args.index("--floor") + 1] = "off"
                row["profile_top"] = profile_row(args)
    write("timing", res)
    print(table(res))
    if res.get("failed"):
        print(f"bench_timing: {len(res['failed'])} row(s) failed: {', '.join(res['failed'])}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
