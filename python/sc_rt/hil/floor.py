"""The bench's floor (``sc-rt floor``, ``sc-rt hil --self-test``): what this
machine and configuration give a controller that costs nothing.

The same processes and messages as a run (``sc-rt-controller --null-law``:
every state answered with a zero command and a status, no law step; the
emulator, lcm-logger), for a short time, plus the C++ LCM round trip
(``sc-rt-lcm-pingpong``). A run's timing.json and timing.png carry the floor
of its host, mode, rate, scheduler and trigger next to its own figures
("bench floor p99 X us; this controller added Y us"): measured before the
run, or taken from the cache of an earlier measurement (``cached``; at most
``max_age_s`` old), and they say which (docs/HIL.md, "The bench floor").
"""

from __future__ import annotations

import json
import os
import shlex
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any, Callable

from sc_rt.wire.lcmio import free_port_url
from sc_rt.plan.run import Bus, Outputs, plan_run
from sc_rt.plan.timing import Timing, TimingSetup
from sc_rt.scenario.model import Scenario

__all__ = ["TimingSetup", "measure_floor", "floor_for", "lcm_round_trip", "compare_to_floor",
           "floor_cache_dir", "FLOOR_SERIES", "DEFAULT_FLOOR_S", "DEFAULT_MAX_AGE_S"]

#: the floor run's length [s] when measured before a run
DEFAULT_FLOOR_S = 2.0
#: a cached floor older than this [s] is measured again (the machine's load drifts)
DEFAULT_MAX_AGE_S = 3600.0
#: the run fields the floor gives a p99 for (timing.png draws them)
FLOOR_SERIES = ("latency_us", "tick_lateness_us", "wake_lateness_us", "state_age_us", "compute_us")
_TIMING_KEYS = {"latency_us": "state_to_cmd_latency_us", "tick_lateness_us": "emulator_tick_lateness_us",
                "wake_lateness_us": "wake_lateness_us", "state_age_us": "state_age_us",
                "compute_us": "compute_us"}


def floor_cache_dir() -> Path:
    """$SCRT_FLOOR_CACHE, else $XDG_CACHE_HOME/sc-rt/floor, else ~/.cache/sc-rt/floor."""
    if os.environ.get("SCRT_FLOOR_CACHE"):
        return Path(os.environ["SCRT_FLOOR_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "sc-rt" / "floor"


def _cache_path(mode: str, rate: float, realtime_priority: bool, setup: TimingSetup) -> Path:
    host = socket.gethostname().replace("/", "_")
    sched = "fifo" if realtime_priority else "other"
    return floor_cache_dir() / f"floor-{host}-{mode}-{rate:g}hz-{sched}-{setup.key()}.json"


def _pingpong() -> str:
    here = Path(sys.executable).parent / "sc-rt-lcm-pingpong"
    return str(here) if here.exists() else "sc-rt-lcm-pingpong"


def lcm_round_trip(count: int = 2000, url: str | None = None, fifo: bool = False) -> dict[str, Any]:
    """The C++ <-> C++ LCM round trip with the loop's message sizes
    (sc-rt-lcm-pingpong): {"n", "lost", "rtt_us": {p50, p99, max, min}};
    ``fifo``: both ends at SCHED_FIFO 80 (chrt), as the controller with
    --realtime-priority (falls back to SCHED_OTHER when refused)."""
    url = url or free_port_url(ttl=0)
    exe = shlex.quote(_pingpong())
    if fifo and subprocess.run(["chrt", "-f", "80", "true"], capture_output=True).returncode == 0:
        exe = "chrt -f 80 " + exe
    script = (f"{exe} --role pong --lcm-url {shlex.quote(url)} 2>/dev/null & P=$!; sleep 0.3; "
              f"{exe} --role ping --lcm-url {shlex.quote(url)} --count {int(count)}; kill $P")
    r = subprocess.run(["sh", "-c", script], capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        raise RuntimeError(f"sc-rt-lcm-pingpong failed: {r.stderr.strip()}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def measure_floor(scn: Scenario, *, run: Callable[..., Any], mode: str = "realtime",
                  control_rate_hz: float | None = None, duration: float = DEFAULT_FLOOR_S,
                  realtime_priority: bool = True, setup: TimingSetup | None = None, rtt_count: int = 2000,
                  lcm_url: str | None = None) -> dict[str, Any]:
    """A null-controller run of ``duration`` s and the LCM round trip; the
    floor's figures (p50/p99/max per series), its counts and its conditions.
    ``run`` is ``sc_rt.hil.runner.run_hil``, passed in by its callers (the
    runner asks this module for its runs' floors: no import cycle)."""
    setup = setup or TimingSetup()
    null = TimingSetup(**{**asdict(setup), "null_law": True})
    rate = control_rate_hz or scn.run.control_rate_hz
    rtt = lcm_round_trip(rtt_count, fifo=realtime_priority)
    with tempfile.TemporaryDirectory(prefix="sc-rt-floor-") as d:
        t0 = time.time()
        plan = plan_run(scn, engine="bench", control_rate_hz=rate, duration=duration,
                        timing=Timing(mode=mode, realtime_priority=realtime_priority, setup=null),
                        outputs=Outputs(out=Path(d), plots=False), bus=Bus(lcm_url=lcm_url))
        res = run(plan)
        t = res.timing
    if res.stopped:  # interrupted (or the logger died): no floor, and no run after it
        print(f"sc-rt: the bench floor's run stopped: {res.stopped}", file=sys.stderr)
        raise SystemExit(128 + res.signum if res.signum else 1)
    out = {
        "host": socket.gethostname(), "measured_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(t0)),
        "load_avg": list(os.getloadavg()), "mode": mode, "control_rate_hz": rate, "duration_s": duration,
        "realtime_priority": realtime_priority, "scheduler": t["scheduler"],
        "emulator_scheduler": t.get("emulator_scheduler"), "setup": asdict(setup),
        "steps": t["steps"], "rows": t["rows"], "deadline_misses": t["deadline_misses"],
        "stale_states": t["stale_states"], "fresh_fraction": t.get("fresh_fraction"),
        "steps_per_s": t["steps_per_s"], "lcm_rtt_us": rtt["rtt_us"], "lcm_rtt_n": rtt["n"],
        "emulator_breakdown_us": t.get("emulator_breakdown_us"),
    }
    for series, key in _TIMING_KEYS.items():
        out[series] = t[key]
    return out


def floor_for(scn: Scenario, *, run: Callable[..., Any], mode: str, control_rate_hz: float | None,
              realtime_priority: bool, setup: TimingSetup | None = None, policy: str = "auto",
              duration: float = DEFAULT_FLOOR_S, max_age_s: float = DEFAULT_MAX_AGE_S,
              rtt_count: int = 2000) -> dict[str, Any]:
    """The floor a run is compared with. ``policy``: ``measure`` (now, then
    cached), ``cached`` (the cache's, else measured), ``auto`` (the cache's
    when younger than ``max_age_s``, else measured). The result says which
    (``source``: "measured before the run" or "cached") and where it is kept."""
    if policy not in ("auto", "cached", "measure"):
        raise ValueError(f"floor policy must be auto, cached or measure, got {policy!r}")
    setup = setup or TimingSetup()
    rate = control_rate_hz or scn.run.control_rate_hz
    path = _cache_path(mode, rate, realtime_priority, setup)
    if policy != "measure" and path.exists():
        try:
            f = json.loads(path.read_text())
            age = time.time() - path.stat().st_mtime
            if policy == "cached" or age <= max_age_s:
                return {**f, "source": "cached", "file": str(path), "age_s": age}
        except (OSError, ValueError):
            pass  # unreadable: measure again
    f = measure_floor(scn, run=run, mode=mode, control_rate_hz=rate, duration=duration,
                      realtime_priority=realtime_priority, setup=setup, rtt_count=rtt_count)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(f, indent=2) + "\n")
    except OSError:
        pass  # no cache: the run still carries its floor
    return {**f, "source": "measured before the run", "file": str(path), "age_s": 0.0}


def compare_to_floor(timing: dict[str, Any], floor: dict[str, Any]) -> dict[str, Any]:
    """What the run added to the floor, per series (p50 and p99 [us]), and
    the line the figures and reports print."""
    added: dict[str, Any] = {}
    for series, key in _TIMING_KEYS.items():
        run, fl = timing.get(key) or {}, floor.get(series) or {}
        added[series] = {q: (run[q] - fl[q]) if run.get(q) is not None and fl.get(q) is not None else None
                         for q in ("p50", "p99")}
    lat, fl = timing.get("state_to_cmd_latency_us") or {}, floor.get("latency_us") or {}
    src = floor.get("source")
    if src == "cached" and floor.get("measured_at"):
        src = f"cached, measured {floor['measured_at']}" + (
            f" at load {floor['load_avg'][0]:.1f}" if floor.get("load_avg") else "")
    if lat.get("p99") is not None and fl.get("p99") is not None:
        more = lat["p99"] - fl["p99"]
        line = (f"bench floor p99 {fl['p99']:.0f} us; this controller added {more:.0f} us "
                f"(latency p99 {lat['p99']:.0f} us; floor {src})" if more >= 0 else
                f"bench floor p99 {fl['p99']:.0f} us; this controller added nothing measurable (latency p99 "
                f"{lat['p99']:.0f} us, {-more:.0f} us below the floor's: the machine's load moved; floor "
                f"{src})")
    else:
        line = "bench floor: no latency figures"
    # the cache is keyed on the priority asked for: a floor measured where it was refused (or
    # granted) compares with a run that got the other is said so, not silently compared
    got, then = timing.get("scheduler"), floor.get("scheduler")
    if got and then and got.split()[0] != then.split()[0]:
        line += f" (the floor ran {then}, this run {got}: not like for like)"
    return {"added_us": added, "line": line}
