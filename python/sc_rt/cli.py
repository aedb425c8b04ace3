"""The ``sc-rt`` command. Every subcommand that takes a scenario loads and
validates it first; a bad file exits with code 2 and a message naming the
file, line, key and value."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from . import __version__

LAW_CHOICES = ("dsc-ppc", "dsc", "pd", "rft")


def _scenario(path: str, args: argparse.Namespace | None = None):
    from .scenario import load_scenario

    return load_scenario(path)


def _print_metrics(m: dict) -> None:
    def f(v):
        return "-" if v is None else (f"{v:.3e}" if isinstance(v, float) else str(v))

    rows = [
        ("controller", m["controller"]), ("engine", m["engine"]),
        ("steps", m["steps"]), ("wall [s]", f"{m['wall_s']:.3f}"), ("finite", m["finite"]),
        ("first bound violation [s]", f(m["first_bound_violation_s"])),
        ("  axis", f(m["first_bound_violation_axis"])),
        ("|sigma_BD| at 30/100/300 s", " / ".join(f(m["sigma_e_norm"][k]) for k in ("30", "100", "300"))),
        ("max |omega_BD_B| after 70 s", f(m["max_abs_omega_e_after_70s"])),
        ("max observer error after 30 s", f(m["max_observer_error_after_30s"])),
        ("max |u_cmd| [rad/s^2]", f(m["max_abs_u_cmd"])),
        ("saturated fraction", f(m["saturated_fraction"])),
    ]
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"  {k:<{w}}  {v}")


def cmd_sim(args: argparse.Namespace) -> int:
    from .sim import simulate, write_result

    scn = _scenario(args.scenario)
    res = simulate(scn, law=args.controller, engine=args.engine,
                   control_rate_hz=args.control_rate, duration=args.duration,
                   plant_step=args.plant_step)
    out = Path(args.out)
    write_result(res, out)
    if not args.no_plots:
        from .plots import tracking_figures

        tracking_figures(res.trajectory, scn, out,
                         title=f"{scn.name}, {res.metrics['controller']}, {res.metrics['engine']}")
    print(f"sc-rt sim: {scn.name} -> {out}/")
    _print_metrics(res.metrics)
    if res.diverged:
        print(f"sc-rt sim: DIVERGED: {res.message}", file=sys.stderr)
    return 0


def cmd_hil(args: argparse.Namespace) -> int:
    from .hil import run_hil

    scn = _scenario(args.scenario)
    res = run_hil(scn, out=Path(args.out), mode=args.mode, law=args.controller,
                  control_rate_hz=args.control_rate, duration=args.duration, lcm_url=args.lcm_url,
                  prefix=args.prefix, realtime_priority=args.realtime_priority,
                  time_scale=args.time_scale, accept_fault_commands=args.accept_fault_commands,
                  plots=not args.no_plots)
    print(f"sc-rt hil: {scn.name} ({args.mode}) -> {res.out}/")
    _print_metrics(res.metrics)
    t = res.timing
    lat = t["state_to_cmd_latency_us"]
    print(f"  state-to-command latency [us]  p50 {lat['p50']}  p99 {lat['p99']}  max {lat['max']}")
    print(f"  steps/s {t['steps_per_s']:.0f}  deadline misses {t['deadline_misses']}  "
          f"dropped {t['dropped']}  malformed {t['malformed']}  scheduler {t['scheduler']}")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """The main job: the paper fault scenario through the real LCM loop."""
    scenario = Path(args.scenario)
    out = Path(args.out)
    ns = argparse.Namespace(scenario=str(scenario), out=str(out), mode="lockstep", controller=None,
                            control_rate=None, duration=None, lcm_url=args.lcm_url, prefix="",
                            realtime_priority=False, time_scale=1.0, accept_fault_commands=False,
                            no_plots=False)
    rc = cmd_hil(ns)
    print(f"\nsc-rt demo: report, metrics, log and figures in {out.resolve()}/")
    for name in ("metrics.json", "timing.json", "run.lcmlog", "attitude_error.png",
                 "attitude_error_log.png", "timing.png"):
        print(f"  {out / name}")
    return rc


def cmd_emulator(args: argparse.Namespace) -> int:
    from .emulator import Emulator
    from .lcmio import DEFAULT_URL

    scn = _scenario(args.scenario)
    emu = Emulator(scn, mode=args.mode, url=args.lcm_url or DEFAULT_URL, prefix=args.prefix,
                   rate=args.rate, time_scale=args.time_scale, duration=args.duration,
                   accept_fault_commands=args.accept_fault_commands)
    try:
        res = emu.run()
    except KeyboardInterrupt:
        print("sc-rt emulator: interrupted", file=sys.stderr)
        return 130
    print(json.dumps({"rows": res.rows, "counters": dict(res.counters),
                      "gaps_s": res.gaps, "diverged": res.diverged}))
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    from .check import check_scenario, exit_code

    findings = check_scenario(args.scenario, run_estimate=not args.fast)
    for f in findings:
        if f.level != "ok" or args.verbose:
            print(f)
    rc = exit_code(findings)
    n = {lvl: sum(f.level == lvl for f in findings) for lvl in ("error", "warning", "ok")}
    print(f"sc-rt check: {args.scenario}: {n['error']} errors, {n['warning']} warnings, {n['ok']} ok")
    return rc


def cmd_config(args: argparse.Namespace) -> int:
    scn = _scenario(args.scenario)
    data = scn.controller_config_msg(args.controller, args.control_rate).encode()
    Path(args.out).write_bytes(data)
    print(f"sc-rt config: controller_config_t ({len(data)} bytes) -> {args.out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="sc-rt",
        description="Real-time attitude-control emulator: fault-tolerant controllers against a "
                    "reaction-wheel spacecraft, offline and over LCM.",
    )
    p.add_argument("--version", action="version", version=f"sc-rt {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    s = sub.add_parser("sim", help="offline closed loop (plant + C++ controller core)")
    s.add_argument("scenario")
    s.add_argument("--controller", choices=LAW_CHOICES, help="control law (default: the scenario's)")
    s.add_argument("--engine", choices=("python", "cpp"), default="python")
    s.add_argument("--control-rate", type=float, metavar="HZ")
    s.add_argument("--duration", type=float, metavar="S")
    s.add_argument("--plant-step", type=float, metavar="S",
                   help="plant RK4 step (default: the scenario's, reduced to divide the control period)")
    s.add_argument("--out", default="out/sim", metavar="DIR")
    s.add_argument("--no-plots", action="store_true")
    s.set_defaults(func=cmd_sim)

    def lcm_opts(q):
        q.add_argument("--lcm-url", metavar="URL",
                       help="default: udpm://239.255.76.67:<free port>?ttl=0 (nothing leaves the machine)")
        q.add_argument("--prefix", default="", help="channel name prefix (default none)")

    h = sub.add_parser("hil", help="controller process + plant emulator + lcm-logger over LCM")
    h.add_argument("scenario")
    h.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    h.add_argument("--controller", choices=LAW_CHOICES)
    h.add_argument("--control-rate", type=float, metavar="HZ")
    h.add_argument("--duration", type=float, metavar="S")
    h.add_argument("--out", default="out/hil", metavar="DIR")
    h.add_argument("--realtime-priority", action="store_true",
                   help="controller asks for SCHED_FIFO + mlockall")
    h.add_argument("--time-scale", type=float, default=1.0, help="real time: > 1 runs faster")
    h.add_argument("--accept-fault-commands", action="store_true",
                   help="the emulator applies fault_cmd_t from SCRT_FAULT")
    h.add_argument("--no-plots", action="store_true")
    lcm_opts(h)
    h.set_defaults(func=cmd_hil)

    d = sub.add_parser("demo", help="the main job: paper fault scenario through the LCM loop")
    d.add_argument("--scenario", default=str(Path("scenarios") / "paper_faults.toml"))
    d.add_argument("--out", default="out/demo", metavar="DIR")
    d.add_argument("--lcm-url", metavar="URL")
    d.set_defaults(func=cmd_demo)

    e = sub.add_parser("emulator", help="the plant as an LCM process")
    e.add_argument("scenario")
    e.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    e.add_argument("--rate", type=float, metavar="HZ", help="state publish rate (default: control rate)")
    e.add_argument("--time-scale", type=float, default=1.0)
    e.add_argument("--duration", type=float, metavar="S")
    e.add_argument("--accept-fault-commands", action="store_true")
    lcm_opts(e)
    e.set_defaults(func=cmd_emulator)

    k = sub.add_parser("check", help="check a scenario: schema, bound at t=0, (26), Theorem 1, B, Cbar, limits")
    k.add_argument("scenario")
    k.add_argument("--verbose", "-v", action="store_true", help="also list the checks that pass")
    k.add_argument("--fast", action="store_true", help="estimate r's bound at t = 0 instead of along a run")
    k.set_defaults(func=cmd_check)

    c = sub.add_parser("config", help="write the scenario's controller_config_t for sc-rt-controller")
    c.add_argument("scenario")
    c.add_argument("--out", required=True, metavar="FILE")
    c.add_argument("--controller", choices=LAW_CHOICES)
    c.add_argument("--control-rate", type=float, metavar="HZ")
    c.set_defaults(func=cmd_config)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    from .scenario import ScenarioError

    try:
        return args.func(args)
    except ScenarioError as e:
        print(f"sc-rt: {e}", file=sys.stderr)
        return 2
    except (FileNotFoundError, RuntimeError) as e:
        print(f"sc-rt {args.command}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
