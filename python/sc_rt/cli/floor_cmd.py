"""``sc-rt floor`` (also ``sc-rt hil --self-test``): the bench's floor on this
machine and configuration (hil/floor.py), and the timing options that
``sc-rt hil`` and ``sc-rt floor`` share (trigger, CPUs, the emulator's spin,
the floor policy)."""

from __future__ import annotations

import argparse
import json
import math
import sys

from sc_rt.cli.common import add_set
from sc_rt.cli.validate import MAX_RATE_HZ, integer, number

__all__ = ["add_timing_options", "timing_setup", "add_floor_parser", "cmd_floor", "floor_table"]


def add_timing_options(h: argparse.ArgumentParser, *, floor_policy: bool = True) -> None:
    h.add_argument("--trigger", choices=("event", "timer"), default="event",
                   help="real time: the controller steps on each state's arrival (event), or on its own "
                        "timer phase-locked to the state arrivals (timer) (default: %(default)s)")
    h.add_argument("--controller-cpu", type=integer(0), metavar="N",
                   help="pin the controller (sc-rt-controller, or a Python law's sc-rt controller) to CPU N")
    h.add_argument("--emulator-cpu", type=integer(0), metavar="N", help="pin the emulator's thread to CPU N")
    h.add_argument("--spin-us", type=number(0, 1e6, open_lo=False, unit="us"), default=100.0, metavar="US",
                   help="real time: the emulator polls instead of sleeping for the last US before each "
                        "tick (default: %(default)s; 0: sleeps to the tick)")
    if floor_policy:
        h.add_argument("--rt-limits", type=rt_limits, metavar="K=F,...",
                       help="real time: what 'kept real time' means, as fractions: misses (deadline misses "
                            "per step), skipped (periods without a controller step), dropped (watchdog zeros "
                            "per row), stale (stale states per step), late (answers later than a control "
                            "period per answer, after the timer's 2 s acquisition), late_ticks (plant ticks "
                            "later than a period per row); and stall, the worst plant tick's lateness in "
                            "periods; a run beyond one is invalid (default: misses=0.01,skipped=0.01,"
                            "dropped=0.01,stale=0.5,late=0.01,late_ticks=0.01,stall=25)")
        h.add_argument("--floor", choices=("auto", "cached", "measure", "off"), default="auto",
                       help="real time: the bench floor timing.json and timing.png compare the run with: "
                            "auto (cached when younger than an hour, else a 2 s null-controller run "
                            "first), cached, measure, off (default: %(default)s)")
        h.add_argument("--controller-memory-limit", type=number(1, 1e7, unit="MB"), default=2048.0, metavar="MB",
                       help="[MB] the controller process's resident memory beyond which it is killed and the "
                            "run stops, invalid (default: %(default)g)")
        h.add_argument("--self-test", action="store_true",
                       help="measure the bench floor only (as sc-rt floor) and exit")


def rt_limits(text: str):
    """--rt-limits misses=F,...,stall=N (any subset; fractions in [0, 1], stall in periods >= 1)."""
    import dataclasses

    from sc_rt.logs.timing import RealtimeLimits

    keys = [f.name for f in dataclasses.fields(RealtimeLimits) if f.name != "allowance"]
    values = {}
    for part in text.split(","):
        key, sep, val = part.partition("=")
        key = key.strip()
        if not sep or key not in keys:
            raise argparse.ArgumentTypeError(f"{part!r}: expected " + ", ".join(f"{k}=F" for k in keys))
        try:
            v = float(val)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{part!r}: {val!r} is not a number") from None
        if key == "stall":
            if not (math.isfinite(v) and v >= 1.0):
                raise argparse.ArgumentTypeError(f"{part!r}: a number of control periods >= 1")
        elif not 0.0 <= v <= 1.0:
            raise argparse.ArgumentTypeError(f"{part!r}: a fraction in [0, 1]")
        values[key] = v
    return dataclasses.replace(RealtimeLimits(), **values)


def timing_setup(args: argparse.Namespace):
    from sc_rt.hil.floor import TimingSetup

    return TimingSetup(trigger=args.trigger, controller_cpu=args.controller_cpu,
                       emulator_cpu=args.emulator_cpu, spin_us=args.spin_us)


def add_floor_parser(sub) -> None:
    f = sub.add_parser("floor", help="the bench floor: a null controller (zero compute) through the same "
                       "processes and messages, and the LCM round trip")
    f.add_argument("scenario", nargs="?", default="paper_faults",
                   help="scenario (default: %(default)s; the floor hardly depends on it)")
    f.add_argument("--mode", choices=("lockstep", "realtime"), default="realtime", help="default: %(default)s")
    f.add_argument("--control-rate", type=number(0, MAX_RATE_HZ, unit="Hz"), metavar="HZ",
                   help="default: the scenario's")
    f.add_argument("--duration", type=number(0, 3600, unit="s"), default=2.0, metavar="S",
                   help="the null-controller run (default: %(default)s)")
    f.add_argument("--rtt-count", type=integer(1), default=2000, metavar="N",
                   help="LCM round trips of sc-rt-lcm-pingpong (default: %(default)s)")
    f.add_argument("--realtime-priority", action=argparse.BooleanOptionalAction, default=None,
                   help="SCHED_FIFO + mlockall for the controller and the emulator where permitted (root or "
                        "CAP_SYS_NICE; else SCHED_OTHER, said in the output) (default: on in real time, off in "
                        "lockstep)")
    f.add_argument("--json", action="store_true", help="print the floor as JSON")
    f.add_argument("--no-cache", action="store_true", help="do not write the floor cache")
    add_timing_options(f, floor_policy=False)
    add_set(f)
    f.set_defaults(func=cmd_floor)


def floor_table(f: dict) -> str:
    def q(d):
        d = d or {}
        return " / ".join("-" if d.get(k) is None else f"{d[k]:.0f}" for k in ("p50", "p99", "max"))

    rows = [("LCM round trip, C++ ping-pong [us]", q(f.get("lcm_rtt_us"))),
            ("state-to-command latency [us]", q(f.get("latency_us"))),
            ("controller state age [us]", q(f.get("state_age_us")))]
    if f.get("mode") == "realtime":
        rows += [("controller wake lateness [us]", q(f.get("wake_lateness_us"))),
                 ("emulator tick lateness [us]", q(f.get("tick_lateness_us")))]
    fresh = f.get("fresh_fraction")
    head = (f"bench floor: {f.get('host')}, {f.get('mode')} {f.get('control_rate_hz'):g} Hz, "
            f"{(f.get('setup') or {}).get('trigger', 'timer')} trigger, controller {f.get('scheduler')}, "
            f"emulator {f.get('emulator_scheduler')}, {f.get('duration_s'):g} s, load "
            + " ".join(f"{x:.2f}" for x in f.get("load_avg", [])))
    lines = [head, f"  {'figure':<40} p50 / p99 / max"]
    lines += [f"  {name:<40} {v}" for name, v in rows]
    lines.append(f"  steps {f.get('steps')}  deadline misses {f.get('deadline_misses')}  stale states "
                 f"{f.get('stale_states')}  fresh {'-' if fresh is None else f'{100 * fresh:.2f} %'}")
    return "\n".join(lines)


def cmd_floor(args: argparse.Namespace) -> int:
    from sc_rt.hil.floor import floor_for, measure_floor
    from sc_rt.hil.runner import run_hil
    from sc_rt.cli.common import scenario_arg

    scn = scenario_arg(args.scenario, args)
    setup = timing_setup(args)
    if args.realtime_priority is None:  # as sc-rt hil: on in real time
        args.realtime_priority = args.mode == "realtime"
    if args.no_cache:
        f = measure_floor(scn, run=run_hil, mode=args.mode, control_rate_hz=args.control_rate, duration=args.duration,
                          realtime_priority=args.realtime_priority, setup=setup, rtt_count=args.rtt_count)
        f["source"] = "measured (not cached)"
    else:
        f = floor_for(scn, run=run_hil, mode=args.mode, control_rate_hz=args.control_rate,
                      realtime_priority=args.realtime_priority, setup=setup, policy="measure",
                      duration=args.duration, rtt_count=args.rtt_count)
    if args.json:
        json.dump(f, sys.stdout, indent=2)
        print()
    else:
        print(floor_table(f))
        if f.get("file"):
            print(f"  cached in {f['file']}")
    return 0
