"""Soak: a long HIL run, real time at 100 Hz by default (issues #20, #31).

    python bench/soak.py [--minutes 30] [--rate 100] [--mode realtime|lockstep] [--out DIR] [--json FILE] [--smoke]

(--smoke: a check that it runs: 6 s with a 1 s warm-up, RSS every 0.25 s,
unless --minutes or --sample say otherwise.)

Runs ``sc-rt hil`` in real time, or in lockstep for ``--minutes`` of
simulated time (its own network namespace when this process
may create one) and samples the resident memory (VmRSS) of both processes,
the emulator (the ``sc-rt hil`` process) and ``sc-rt-controller``, every
``--sample`` s. Then:

- memory: growth after the warm-up (the first 10 % of the run, at least
  20 s) until the run ends (not while the emulator writes its record),
  per process. The controller keeps fixed-size histograms for its exit
  percentiles (nothing per step): it must stay flat (<= 1 MB). The
  emulator keeps two chunks of rows and writes the older ones to disk as
  the run goes (docs/HIL.md, "Long runs"): it must stay flat too (<= 1 MB);
- timing: p50, p99 and max of the state-to-command latency, the
  controller's compute time and wake lateness and the emulator's tick
  lateness over the first and the last window (10 min, or a quarter of a
  shorter run): p50 within 20 %, the worst case (max) of the last window
  within 2x of the first's;
- the log: every message the emulator sent (states, guidance and truth,
  one per row) and every command and status the controller sent (one per
  step, seqs 0..steps-1) is in run.lcmlog: zero lost log events (a bit per
  seq: any length of run).

lcm-logger subscribes with LCM's default queue of 30 messages: when its
main loop is descheduled for more than about 60 ms (500 messages/s here),
LCM drops the excess silently, with no kernel drop (``RcvbufErrors`` 0):
this shared 2-core machine (load average ~5) lost a few events a minute
that way, in bursts of one message per channel. The soak therefore lifts
the logger's threads to SCHED_FIFO 10 when it may (root), else nice -10
(``--no-renice``: leave it as sc-rt hil starts it).
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from common import HIL_MEASURE, hil_timing, results_dir

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

#: the controller's per-step samples (lateness, compute, age: 3 doubles)
CONTROLLER_BYTES_PER_STEP = 0  # fixed-size histograms (cpp/shell/histogram.hpp): nothing per step
#: growth after the warm-up that still counts as flat (beyond what is kept by design)
FLAT_KB = 1024


def lift(pid: int, niceness: int = -10, fifo: int = 10) -> str:
    """Every thread of pid at SCHED_FIFO ``fifo`` when permitted, else at
    ``niceness`` (Linux: both per thread); what it got."""
    got = "SCHED_FIFO"
    for t in Path(f"/proc/{pid}/task").glob("*"):
        tid = int(t.name)
        try:
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(fifo))
        except OSError:
            try:
                os.setpriority(os.PRIO_PROCESS, tid, niceness)
                got = "nice" if got != "default" else got
            except OSError:
                got = "default"
    return got


def rss_kb(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def children(pid: int) -> list[int]:
    out = []
    for t in Path(f"/proc/{pid}/task").glob("*/children"):
        try:
            out += [int(x) for x in t.read_text().split()]
        except OSError:
            pass
    return out


def comm(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return ""


def udp_counters(pid: int) -> dict[str, int]:
    """The kernel's UDP counters of pid's network namespace (RcvbufErrors: a
    socket's buffer was full)."""
    try:
        lines = [ln.split() for ln in Path(f"/proc/{pid}/net/snmp").read_text().splitlines()
                 if ln.startswith("Udp:")]
        return dict(zip(lines[0][1:], map(int, lines[1][1:])))
    except (OSError, IndexError, ValueError):
        return {}


def percentile_windows(run, window_s: float) -> dict:
    """p50, p99 and max of the timing columns over the run's first and last
    ``window_s`` s (the run read a chunk at a time, the windows' values kept)."""
    names = ("latency_us", "compute_us", "wake_lateness_us", "tick_lateness_us")
    t_end = None
    for c in run.chunks():
        if len(c):
            t_end = float(c["t"][-1])
    if t_end is None:
        return {}
    parts: dict[str, dict[str, list]] = {n: {"first": [], "last": []} for n in names}
    for c in run.chunks():
        t = c["t"]
        for n in names:
            v = c[n]
            parts[n]["first"].append(v[(t <= window_s) & np.isfinite(v)])
            parts[n]["last"].append(v[(t >= t_end - window_s) & np.isfinite(v)])
    out = {}
    for n, w in parts.items():
        first, last = np.concatenate(w["first"]), np.concatenate(w["last"])
        if first.size == 0 or last.size == 0:
            continue
        out[n] = {k: {"p50": float(np.percentile(x, 50)), "p99": float(np.percentile(x, 99)),
                      "max": float(x.max()), "n": int(x.size)} for k, x in (("first", first), ("last", last))}
    return out


def log_check(out: Path, rows: int, steps: int) -> dict:
    """Per channel, the messages sent and those of them the log lacks (by seq)."""
    from sc_rt.logs.lcmlog import read_events

    sent = {"SCRT_STATE": rows, "SCRT_GUIDANCE": rows, "SCRT_TRUTH": rows, "SCRT_CMD": steps,
            "SCRT_CTRL_STATUS": steps}
    seen = {c.encode(): np.zeros(n, bool) for c, n in sent.items()}
    logged = dict.fromkeys(seen, 0)
    for _n, _t, ch, data in read_events(out / "run.lcmlog", partial=True):
        s = seen.get(bytes(ch))
        if s is not None and len(data) >= 24:
            logged[bytes(ch)] += 1
            k = int.from_bytes(data[16:24], "big", signed=True)  # seq (cmd_seq of a status) after fp, utime
            if 0 <= k < len(s):
                s[k] = True
    return {c.decode(): {"sent": len(s), "logged": logged[c], "missing": int(len(s) - np.count_nonzero(s))}
            for c, s in seen.items()}


def soak(minutes: float, rate: float = 100.0, out: Path | None = None, sample_s: float = 5.0,
         scenario: str = "ppc_feasible_100hz", port: int = 7761, renice_logger: bool = True,
         warmup_s: float | None = None, mode: str = "realtime") -> dict:
    """warmup_s: the memory's warm-up (default: 10 % of the run, at least 20 s);
    ``minutes``: of the run's time (lockstep: as fast as the loop goes)."""
    duration = minutes * 60.0
    out = Path(out or ROOT / "out" / "soak")
    url = f"udpm://239.255.76.67:{port}?ttl=0&recv_buf_size=4194304"
    cmd = [sys.executable, "-m", "sc_rt.cli", "hil", str(ROOT / "scenarios" / f"{scenario}.toml"),
           "--mode", mode, "--control-rate", f"{rate:g}", "--duration", f"{duration:g}",
           "--no-plots", "--out", str(out), "--lcm-url", url, *HIL_MEASURE]
    wrap = subprocess.run(["unshare", "-n", "true"], capture_output=True).returncode == 0
    if wrap:  # a private network namespace: unshare execs sh, which execs sc-rt: one pid
        cmd = ["unshare", "-n", "sh", "-c",
               "ip link set lo up && ip route add 224.0.0.0/4 dev lo && exec " + shlex.join(cmd)]
    for stale in ("trajectory.arrow", "record.raw.arrow"):  # a previous run's: not this run's end
        (out / stale).unlink(missing_ok=True)
    t0 = time.monotonic()
    t_finalize = None  # when the emulator began to read its record back (trajectory.arrow appeared)
    p = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    samples: list[tuple[float, int | None, int | None]] = []
    ctl = logger = None
    reniced = None
    udp: dict[str, int] = {}
    try:
        while p.poll() is None:
            if ctl is not None and rss_kb(ctl) is None:
                # that controller ended: on a fresh clone sc-rt hil first measures the bench
                # floor with a controller of its own (sc-rt floor), then starts the run's
                ctl = None
            if ctl is None:
                ctl = next((c for c in children(p.pid) if comm(c) == "sc-rt-controlle"), None)
            if logger is None:
                logger = next((c for c in children(p.pid) if comm(c) == "sc-rt-logger"), None)
                if logger is not None and renice_logger:
                    reniced = lift(logger)
            samples.append((time.monotonic() - t0, rss_kb(p.pid), rss_kb(ctl) if ctl else None))
            if t_finalize is None and (out / "trajectory.arrow").exists():
                t_finalize = samples[-1][0]
            udp = udp_counters(p.pid) or udp
            try:
                p.wait(sample_s if ctl is not None and logger is not None else 0.05)
            except subprocess.TimeoutExpired:
                pass
        stdout, stderr = p.communicate()
    except BaseException:
        os.killpg(p.pid, signal.SIGINT)
        p.wait()
        raise
    timing = hil_timing(p.returncode, out, "soak", stderr)
    summary = json.loads((out / "controller_summary.json").read_text())
    from sc_rt.results.record.run import Run

    tr = Run.load(out)  # trajectory.arrow, read a chunk at a time
    rows, steps = timing["rows"], summary["steps"]
    # warm-up: the first 10 % of the run (at least 20 s), from the first
    # sample with both processes up; the end: the run's (real time: its
    # duration from then, less a second; lockstep: the controller's last
    # sample): after it the emulator decodes and writes its record, which is
    # not the run's memory
    both = [s for s in samples if s[1] is not None and s[2] is not None]
    t_up = both[0][0] if both else 0.0
    run_wall = duration if mode == "realtime" else (both[-1][0] - t_up if both else 0.0)
    if t_finalize is not None:  # a run on disk: its record is read back from here on
        run_wall = min(run_wall, t_finalize - t_up)
    warm = t_up + (max(20.0, 0.1 * run_wall) if warmup_s is None else warmup_s)
    after = [s for s in both if warm <= s[0] <= t_up + run_wall - 1.0]
    mem = {}
    if len(after) >= 3:
        span = after[-1][0] - after[0][0]
        for i, name in ((1, "emulator"), (2, "controller")):
            grow_kb = after[-1][i] - after[0][i]
            mem[name] = {"rss_start_kb": after[0][i], "rss_end_kb": after[-1][i], "growth_kb": grow_kb,
                         "span_s": span, "max_kb": max(s[i] for s in after),
                         "max_growth_kb": max(s[i] for s in after) - after[0][i],
                         "bytes_per_step": grow_kb * 1024 / (span * rate) if span > 0 else None}
        c = mem["controller"]
        c["by_design_bytes_per_step"] = CONTROLLER_BYTES_PER_STEP
        c["unexplained_kb"] = c["growth_kb"] - CONTROLLER_BYTES_PER_STEP * c["span_s"] * rate / 1024
        c["flat"] = c["unexplained_kb"] <= FLAT_KB
        e = mem["emulator"]
        e["flat"] = e["growth_kb"] <= FLAT_KB
    window = min(600.0, duration / 4)
    pct = percentile_windows(tr, window)
    drift = {}
    for name, w in pct.items():
        a, b = w["first"]["p50"], w["last"]["p50"]
        drift[name] = {"p50_ratio": b / a if a else None,
                       "p99_ratio": w["last"]["p99"] / w["first"]["p99"] if w["first"]["p99"] else None,
                       "max_ratio": w["last"]["max"] / w["first"]["max"] if w["first"]["max"] else None}
    logc = log_check(out, rows, steps)
    return {"minutes": minutes, "rate_hz": rate, "loop_mode": mode, "rows": rows, "controller_steps": steps,
            "controller_percentiles": {k: summary.get(k) for k in ("compute_us", "wake_lateness_us", "state_age_us",
                                                                   "latency_us") if k in summary},
            "metrics_valid": json.loads((out / "metrics.json").read_text()).get("valid"),
            "log_missing": timing.get("log_missing"),
            "wall_s": time.monotonic() - t0, "memory": mem, "timing_windows_s": window, "timing": pct,
            "timing_drift": drift, "log": logc,
            "lost_log_events": sum(v["missing"] for v in logc.values()),
            "deadline_misses": timing["deadline_misses"], "dropped": timing["dropped"],
            "logger_reniced": reniced, "udp_counters_last_sample": udp, "load_avg_end": list(os.getloadavg()),
            "samples": samples}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=None, help="run length (default 30; --smoke: 0.1)")
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--mode", choices=("realtime", "lockstep"), default="realtime",
                    help="lockstep: --minutes of the run's time, as fast as the loop goes")
    ap.add_argument("--scenario", default="ppc_feasible_100hz")
    ap.add_argument("--sample", type=float, default=None, help="RSS sampling period [s] (default 5; --smoke: 0.25)")
    ap.add_argument("--out", default=str(ROOT / "out" / "soak"))
    ap.add_argument("--json", default=str(results_dir() / "soak.json"))
    ap.add_argument("--no-renice", action="store_true", help="leave lcm-logger at the default priority")
    ap.add_argument("--smoke", action="store_true",
                    help="a check that it runs: 6 s, a 1 s warm-up, RSS every 0.25 s (unless given)")
    a = ap.parse_args()
    warmup = 1.0 if a.smoke else None
    if a.minutes is None:
        a.minutes = 0.1 if a.smoke else 30.0
    if a.sample is None:
        a.sample = 0.25 if a.smoke else 5.0
    r = soak(a.minutes, a.rate, Path(a.out), a.sample, scenario=a.scenario, renice_logger=not a.no_renice,
             warmup_s=warmup, mode=a.mode)
    r["mode"] = "smoke" if a.smoke else "full"
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)
    Path(a.json).write_text(json.dumps({k: v for k, v in r.items() if k != "samples"}, indent=2) + "\n")
    print(json.dumps({k: r[k] for k in ("mode", "loop_mode", "minutes", "rows", "memory", "timing_drift",
                                        "lost_log_events", "deadline_misses", "dropped")}, indent=2))
    m = r["memory"]
    ok = bool(m) and m["controller"]["flat"] and m["emulator"]["flat"] and r["lost_log_events"] == 0
    # (a column that is zero throughout, lockstep's wake lateness, has no ratio)
    drift_ok = all(0.8 <= d["p50_ratio"] <= 1.25 for d in r["timing_drift"].values() if d["p50_ratio"] is not None)
    worst_ok = all(d["max_ratio"] <= 2.0 for d in r["timing_drift"].values() if d["max_ratio"] is not None)
    print(f"soak: {'ok' if ok else 'NOT ok'} (both processes' memory flat after the warm-up, no lost "
          f"log event), "
          f"lost log events {r['lost_log_events']}, timing p50 first vs last within 20 %: {drift_ok}, "
          f"worst case of the last window within 2x of the first's: {worst_ok}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
