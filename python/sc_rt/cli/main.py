"""The ``sc-rt`` command. Every subcommand that takes a scenario loads and
validates it first; a bad file exits with code 2 and a message naming the
file, line, key and value."""

from __future__ import annotations

import argparse
import errno
import sys

from sc_rt import __version__
from sc_rt.cli.interrupts import Interrupted, raise_on_signals
from sc_rt.cli.validate import (AUTH_KEY_HELP, LAW_HELP, MAX_RATE_HZ, MAX_TIME_SCALE, OneLineParser, UsageError,
                                auth_key_file, core_law_choice, integer, lcm_url, law_arg, law_choice, number, out_dir,
                                out_file)
from sc_rt.cli.controller import add_external_options
from sc_rt.cli.floor_cmd import add_floor_parser, add_timing_options
from sc_rt.cli.common import LAW_CHOICES, add_set, add_strict
from sc_rt.cli.run_cmds import cmd_demo, cmd_emulator, cmd_hil, cmd_rerun, cmd_sim
from sc_rt.cli.study_cmds import cmd_check, cmd_config, cmd_design, cmd_reproduce, cmd_scenarios
from sc_rt.cli.bus_cmds import cmd_export, cmd_fault, cmd_lcm_spy, cmd_replay, cmd_report, cmd_spy


def _add_monitoring(sub) -> None:
    url_help = ("default: $SCRT_LCM_URL, else udpm://239.255.76.67:7667?ttl=0 (sc-rt hil picks a free "
                "port and prints it: pass its URL)")

    y = sub.add_parser("spy", help="terminal monitor of the bus: rates, jitter, newest values")
    y.add_argument("--lcm-url", metavar="URL", type=lcm_url, help=url_help)
    y.add_argument("--auth-key", metavar="FILE", type=auth_key_file, help=AUTH_KEY_HELP)
    y.add_argument("--channels", default=".*", metavar="REGEX",
                   help="channels to watch (LCM regex: the whole name must match; default: %(default)s, all)")
    y.add_argument("--once", action="store_true",
                   help="listen --duration seconds, print one snapshot (exit 1 if nothing was heard)")
    y.add_argument("--json", action="store_true", help="JSON instead of the table")
    y.add_argument("--duration", type=number(0, 1e6, unit="s"), metavar="S",
                   help="--once: listening time (default 1.5 s); live: stop after S s (exit 1 if "
                        "nothing was heard; default: until Ctrl-C)")
    y.add_argument("--refresh", type=number(0, 3600, unit="s"), default=0.5, metavar="S",
                   help="live: redraw period (default: %(default)s s)")
    y.add_argument("--window", type=number(0, 3600, unit="s"), default=2.0, metavar="S",
                   help="live: rate window (default: %(default)s s)")
    y.set_defaults(func=cmd_spy)

    j = sub.add_parser("lcm-spy", help="LCM's lcm-spy (GUI) with the sc_rt_lcm types on its CLASSPATH")
    j.add_argument("--lcm-url", metavar="URL", type=lcm_url, help=url_help)
    j.add_argument("--title", help="window title (default: lcm-spy's)")
    j.add_argument("--build-only", action="store_true", help="build (or find) the types jar, print its path")
    j.add_argument("--rebuild", action="store_true", help="rebuild the cached types jar")
    j.set_defaults(func=cmd_lcm_spy)

    f = sub.add_parser("fault", help="inject or clear a wheel's or a magnetorquer rod's fault live "
                                     "(fault_cmd_t on SCRT_FAULT, rod_fault_cmd_t on SCRT_ROD_FAULT)")
    fs = f.add_subparsers(dest="action", metavar="ACTION", required=True)
    fi = fs.add_parser("inject", help="inject a fault on one wheel or one rod")
    # the values are checked by sc_rt.tools.faultcmd.inject_msg / rod_inject_msg (exit 2, one line)
    target = fi.add_mutually_exclusive_group(required=True)
    target.add_argument("--wheel", type=int, metavar="N", help="wheel 1..4")
    target.add_argument("--rod", type=int, metavar="N",
                        help="magnetorquer rod 1..N of the plant's [magnetorquers] (at most 6)")
    fi.add_argument("--effectiveness", type=float, metavar="E", help="wheel: L in [0, 1] (default: 1)")
    fi.add_argument("--bias", type=float, metavar="B", help="wheel: bias ubar [rad/s^2] (default: 0)")
    fi.add_argument("--stuck", action="store_true",
                    help="wheel: keeps its speed at onset (on [wheels]: seizes, its speed decaying with 1/rate)")
    fi.add_argument("--friction", type=float, metavar="K",
                    help="wheel: friction multiplier, torque-commanded wheels only (default: 1)")
    fi.add_argument("--kind", choices=("dead", "stuck", "reversed"),
                    help="rod: dead (0), stuck (--dipole whatever the command) or reversed (polarity)")
    fi.add_argument("--dipole", type=float, metavar="X", help="rod: a stuck rod's dipole [A m^2]")
    when = fi.add_mutually_exclusive_group()
    when.add_argument("--at", type=float, metavar="T",
                      help="onset at simulation time T [s] (refused when the emulator is already past it)")
    when.add_argument("--now", action="store_true", help="onset at the emulator's current time (default)")
    fi.add_argument("--until", type=float, metavar="T",
                    help="end at simulation time T [s] (default: never)")
    fi.add_argument("--rate", type=float, metavar="A",
                    help="wheel: evolution rate a of (16) [1/s] (default: 1)")
    fc = fs.add_parser("clear", help="the wheel or rod is healthy again from now on")
    target = fc.add_mutually_exclusive_group(required=True)
    target.add_argument("--wheel", type=int, metavar="N", help="wheel 1..4")
    target.add_argument("--rod", type=int, metavar="N", help="magnetorquer rod 1..N")
    for q in (fi, fc):
        q.add_argument("--lcm-url", metavar="URL", type=lcm_url, help=url_help)
        q.add_argument("--prefix", default="", help="channel name prefix (default: none)")
        q.add_argument("--auth-key", metavar="FILE", type=auth_key_file, help=AUTH_KEY_HELP)
        q.add_argument("--timeout", type=number(0, 600, unit="s"), default=3.0, metavar="S",
                       help="wait this long for an emulator's plant_truth_t to echo the wheel's or the "
                            "rod's fault (default: %(default)s s); exit 1 if none does")
        q.add_argument("--no-wait", action="store_true",
                       help="publish and exit 0 without waiting for the echo")
        q.set_defaults(func=cmd_fault)

    r = sub.add_parser("report", help="metrics, timing and figures of a run from its LCM log")
    r.add_argument("log", help="an lcm-logger log (sc-rt hil writes run.lcmlog)")
    r.add_argument("--out", metavar="DIR", type=out_dir, help="default: report/ next to the log")
    r.add_argument("--scenario", metavar="FILE",
                   help="scenario of the run (needed only for a log without SCRT_CONFIG; gives the duration)")
    r.add_argument("--prefix", help="channel prefix (default: detected)")
    r.add_argument("--mode", choices=("lockstep", "realtime"), help="default: detected")
    r.add_argument("--no-plots", action="store_true", help="no figures (default: figures)")
    r.add_argument("--mcap", metavar="OUT", help="also write the log as MCAP (as sc-rt export)")
    r.set_defaults(func=cmd_report)

    x = sub.add_parser("export",
                       help="an LCM log as MCAP (JSON + schemas from the .lcm files) for Foxglove, PlotJuggler")
    x.add_argument("log", help="an lcm-logger log")
    x.add_argument("--mcap", required=True, metavar="OUT", help="the MCAP file to write")
    x.add_argument("--partial", action="store_true",
                   help="a truncated or corrupt log: export the events that can be read (default: refuse)")
    x.set_defaults(func=cmd_export)

    p = sub.add_parser("replay", help="play an LCM log onto the bus (the wheel's lcm-logplayer)")
    p.add_argument("log", help="an lcm-logger log")
    p.add_argument("--lcm-url", metavar="URL", type=lcm_url, help=url_help)
    p.add_argument("--speed", type=number(0, 1e4), default=1.0, metavar="X",
                   help="playback speed (default: %(default)s)")
    p.add_argument("--channels", metavar="REGEX", help="only these channels (default: all)")
    p.add_argument("--verbose", action="store_true", help="lcm-logplayer's own output")
    p.set_defaults(func=cmd_replay)


def _lcm_opts(q, url_help="default: $SCRT_LCM_URL, else udpm://239.255.76.67:<a free port>?ttl=0 "
                            "(printed; nothing leaves the machine)") -> None:
    q.add_argument("--lcm-url", metavar="URL", type=lcm_url, help=url_help)
    q.add_argument("--prefix", default="", help="channel name prefix (default: none)")
    q.add_argument("--auth-key", metavar="FILE", type=auth_key_file, help=AUTH_KEY_HELP)


def _add_sim(sub) -> None:
    """sc-rt sim."""
    s = sub.add_parser("sim", help="offline closed loop (plant + C++ controller core)")
    s.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    s.add_argument("--law", "--controller", dest="law", type=law_arg, metavar="LAW",
                   help=LAW_HELP + "; --controller is the old name")
    s.add_argument("--engine", choices=("python", "cpp", "unsampled"), default="python",
                   help="unsampled: reference mode, the law inside every RK4 stage (no hold) "
                        "(default: %(default)s)")
    s.add_argument("--control-rate", type=number(0, MAX_RATE_HZ, unit='Hz'), metavar="HZ",
                   help="default: the scenario's")
    s.add_argument("--duration", type=number(unit="s"), metavar="S", help="default: the scenario's")
    s.add_argument("--plant-step", type=number(unit="s"), metavar="S",
                   help="plant RK4 step (default: the scenario's, reduced to divide the control period)")
    s.add_argument("--out", default="out/sim", type=out_dir, metavar="DIR", help="default: %(default)s")
    s.add_argument("--no-plots", action="store_true", help="no figures (default: figures)")
    add_strict(s)
    add_set(s)
    s.set_defaults(func=cmd_sim)


def _add_rerun(sub) -> None:
    """sc-rt rerun."""
    r = sub.add_parser("rerun", help="run again the plan a sim, hil or montecarlo --rerun run recorded (its scenario "
                                     "file, overrides, drawn values, law, engine or mode and set-up)")
    r.add_argument("run_dir", metavar="DIR",
                   help="the recorded run's directory (its trajectory.arrow, or an older run's trajectory.npz)")
    r.add_argument("--out", required=True, type=out_dir, metavar="DIR", help="where the new run writes")
    add_strict(r)
    r.set_defaults(func=cmd_rerun)


def _add_hil(sub) -> None:
    """sc-rt hil."""
    h = sub.add_parser("hil", help="controller process + plant emulator + lcm-logger over LCM")
    h.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    h.add_argument("--mode", choices=("lockstep", "realtime"),
                   help="default: lockstep (--self-test: realtime)")
    h.add_argument("--law", "--controller", dest="law", type=law_arg, metavar="LAW",
                   help=LAW_HELP + "; a Python law runs in `sc-rt controller`")
    h.add_argument("--control-rate", type=number(0, MAX_RATE_HZ, unit='Hz'), metavar="HZ",
                   help="default: the scenario's")
    h.add_argument("--duration", type=number(unit="s"), metavar="S", help="default: the scenario's")
    h.add_argument("--out", default="out/hil", type=out_dir, metavar="DIR", help="default: %(default)s")
    h.add_argument("--realtime-priority", action=argparse.BooleanOptionalAction, default=None,
                   help="the controller and the emulator ask for SCHED_FIFO + mlockall, and fall back to "
                        "SCHED_OTHER where not permitted (the output says which) (default: on in real time, "
                        "off in lockstep)")
    h.add_argument("--time-scale", type=number(0, MAX_TIME_SCALE), default=1.0, metavar="X",
                   help="real time: > 1 runs faster (default: %(default)s)")
    h.add_argument("--accept-fault-commands", action="store_true",
                   help="the emulator applies fault_cmd_t from SCRT_FAULT and rod_fault_cmd_t from SCRT_ROD_FAULT "
                        "(default: ignored)")
    h.add_argument("--no-plots", action="store_true", help="no figures (default: figures)")
    h.add_argument("--mcap", nargs="?", const="", metavar="OUT",
                   help="also write the run's log as MCAP (default OUT: run.mcap in --out; as sc-rt export)")
    add_external_options(h)  # --external, --external-wait, --start-timeout (sc_rt/cli/controller.py)
    add_timing_options(h)  # --trigger, CPUs, --spin-us, --floor, --self-test (sc_rt/cli/floor_cmd.py)
    from sc_rt.cli.live_cmd import add_hil_option

    add_hil_option(h)  # --live [PORT] (sc_rt/cli/live_cmd.py)
    _lcm_opts(h)
    add_strict(h)
    add_set(h)
    h.set_defaults(func=cmd_hil)


def _add_demo(sub) -> None:
    """sc-rt demo."""
    d = sub.add_parser("demo", help="the main job: the paper's DSC+PPC and the feasible 10 Hz design "
                       "on the paper's fault scenario, each through the real LCM loop")
    d.add_argument("--out", default="out/demo", type=out_dir, metavar="DIR",
                   help="output directory, one subdirectory per run (default: %(default)s)")
    d.add_argument("--lcm-url", metavar="URL", type=lcm_url,
                   help="LCM URL (default: $SCRT_LCM_URL, else a free port on 239.255.76.67, ttl=0)")
    d.set_defaults(func=cmd_demo)


def _add_emulator(sub) -> None:
    """sc-rt emulator."""
    e = sub.add_parser("emulator", help="the plant as an LCM process")
    e.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    e.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep", help="default: %(default)s")
    e.add_argument("--rate", type=number(0, MAX_RATE_HZ, unit='Hz'), metavar="HZ",
                   help="state publish rate (default: the scenario's control rate)")
    e.add_argument("--time-scale", type=number(0, MAX_TIME_SCALE), default=1.0, metavar="X",
                   help="real time: > 1 runs faster (default: %(default)s)")
    e.add_argument("--duration", type=number(unit="s"), metavar="S", help="default: the scenario's")
    e.add_argument("--accept-fault-commands", action="store_true",
                   help="apply fault_cmd_t from SCRT_FAULT and rod_fault_cmd_t from SCRT_ROD_FAULT (default: ignored)")
    e.add_argument("--out", metavar="DIR", type=out_dir,
                   help="write trajectory.arrow and emulator.json there (default: nothing written)")
    e.add_argument("--start-timeout", type=number(0, 86400, unit="s"), metavar="S",
                   help="re-send the first state until a controller answers it, up to S s (a controller "
                        "started after the emulator; default: no wait)")
    add_set(e)
    _lcm_opts(e, "default: $SCRT_LCM_URL, else udpm://239.255.76.67:7667?ttl=0 (the port sc-rt-controller "
                "uses by default)")
    e.set_defaults(func=cmd_emulator)


def _add_check(sub) -> None:
    """sc-rt check and sc-rt scenarios."""
    k = sub.add_parser("check", help="check a scenario: schema, bound at t=0, (26), Theorem 1, B, Cbar, limits")
    k.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    k.add_argument("--verbose", "-v", action="store_true", help="also list the checks that pass")
    k.add_argument("--fast", action="store_true", help="estimate r's bound at t = 0 instead of along a run")
    k.add_argument("--law", "--controller", dest="law", type=law_choice, metavar="LAW",
                   help="check for this law (default: the scenario's): only its conditions are checked; "
                        + LAW_HELP.removeprefix("control law: "))
    k.add_argument("--strict", action="store_true", help="notes count as warnings (exit 1)")
    add_set(k)
    k.set_defaults(func=cmd_check)

    n = sub.add_parser("scenarios", help="the shipped scenarios: any SCENARIO argument may be one of these names")
    n.add_argument("--paths", action="store_true", help="print each file instead of its description")
    n.set_defaults(func=cmd_scenarios)


def _add_config(sub) -> None:
    """sc-rt config."""
    c = sub.add_parser("config", help="write the scenario's controller_config_t for sc-rt-controller")
    c.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    c.add_argument("--out", required=True, type=out_file, metavar="FILE", help="the file to write")
    c.add_argument("--law", "--controller", dest="law", type=core_law_choice, metavar="LAW",
                   help="control law: " + ", ".join(LAW_CHOICES) + " or plugin:PATH_OR_NAME (default: the scenario's)")
    c.add_argument("--control-rate", type=number(0, MAX_RATE_HZ, unit='Hz'), metavar="HZ",
                   help="default: the scenario's")
    add_set(c)
    c.set_defaults(func=cmd_config)


def _add_design(sub) -> None:
    """sc-rt design."""
    g = sub.add_parser("design", help="PD design, stability margins and sampled-data stability limits")
    g.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    g.add_argument("--rate", type=number(0, MAX_RATE_HZ, unit='Hz'), metavar="HZ",
                   help="control rate (default: the scenario's)")
    g.add_argument("--latency", type=number(0, 10, unit="s"), metavar="S",
                   help="latency of the Pade case (default 1.2e-3 s, a measured HIL p99)")
    g.add_argument("--timing", metavar="FILE", help="take the latency from a HIL timing.json (p99)")
    g.add_argument("--out", default="out/design", type=out_dir, metavar="DIR", help="default: %(default)s")
    g.add_argument("--no-plots", action="store_true", help="no figures (default: figures)")
    add_set(g)
    g.set_defaults(func=cmd_design)


def _add_reproduce(sub) -> None:
    """sc-rt reproduce."""
    q = sub.add_parser("reproduce", help="check the paper's claims: both scenarios, four laws -> claims.json, figures")
    q.add_argument("--out", default="out/reproduce", type=out_dir, metavar="DIR", help="default: %(default)s")
    q.add_argument("--engine", choices=("python", "cpp"), default="cpp", help="default: %(default)s")
    q.add_argument("--control-rate", type=number(0, MAX_RATE_HZ, unit='Hz'), metavar="HZ",
                   help="default: the scenarios' 10 Hz")
    q.add_argument("--plant-step", type=number(unit="s"), metavar="S", help="default: the scenarios' 0.1 s")
    q.add_argument("--sensitivity", action="store_true",
                   help="also the verdicts at 10 Hz (plant step 0.1 and 0.01 s), 100 Hz and 1 kHz")
    q.add_argument("--search", action="store_true",
                   help="also bisect the tightest chiinf that holds per rate and run scenarios/ppc_feasible_*.toml")
    q.add_argument("--dpi", type=integer(10, 1200), default=80, help="figure resolution (default: %(default)s)")
    q.add_argument("--no-plots", action="store_true", help="no figures (default: figures)")
    q.set_defaults(func=cmd_reproduce)


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="sc-rt",
        epilog="Exit codes: 0 done; 1 the run or check found a problem (sc-rt check: warnings; "
               "sc-rt fault: no emulator echoed; sc-rt spy: nothing heard; with --strict: a failed "
               "requirement, an expect not matched, an invalid run); 2 a bad option, value, "
               "scenario or path (one line, nothing started); 130/143 interrupted by SIGINT/SIGTERM "
               "(partial outputs written and marked). LCM URL: --lcm-url, else $SCRT_LCM_URL.",
        description="Real-time attitude-control emulator: fault-tolerant controllers against a "
                    "reaction-wheel spacecraft, offline and over LCM.",
    )
    p.add_argument("--version", action="version", version=f"sc-rt {__version__}")
    from sc_rt.cli.newlaw import CmakeDirAction, add_parser as add_new_law

    p.add_argument("--cmake-dir", action=CmakeDirAction,
                   help="print the directory of the installed sc_rtConfig.cmake (law plugins, docs/LAWS.md) and exit")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    for add in (_add_sim, _add_hil, _add_rerun, add_floor_parser, _add_demo, _add_emulator, _add_check):
        add(sub)
    from sc_rt.cli.montecarlo import add_parser as add_montecarlo

    add_montecarlo(sub)  # its options and their checks: sc_rt/cli/montecarlo.py
    from sc_rt.cli.controller import add_parser as add_controller

    add_controller(sub)  # sc-rt controller --law module:Class: sc_rt/cli/controller.py
    add_new_law(sub)  # sc-rt new-law: sc_rt/cli/newlaw.py
    from sc_rt.cli.compare import add_parser as add_compare

    add_compare(sub)  # sc-rt compare: sc_rt/cli/compare.py
    from sc_rt.cli.live_cmd import add_parser as add_live

    add_live(sub)  # sc-rt live: sc_rt/cli/live_cmd.py

    for add in (_add_config, _add_design, _add_reproduce, _add_monitoring):
        add(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    import signal

    old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        return _main(argv)
    finally:  # main() called in a process that goes on (tests, notebooks): its handlers back
        for s, h in old.items():
            if h is not None:
                signal.signal(s, h)


def _main(argv: list[str] | None) -> int:
    raise_on_signals()  # SIGINT, SIGTERM: Interrupted (exit 130, 143) unless a command handles them
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    from sc_rt.isolate import probe_timeout, stall_timeout
    from sc_rt.scenario.model import ScenarioError

    for limit in (probe_timeout, stall_timeout):  # the environment's limits, before anything starts
        try:
            limit()
        except ValueError as e:
            print(f"sc-rt {args.command}: {e}", file=sys.stderr)
            return 2
    try:
        return args.func(args)
    except ScenarioError as e:
        print(f"sc-rt: {e}", file=sys.stderr)
        return 2
    except UsageError as e:
        print(f"sc-rt {args.command}: {e}", file=sys.stderr)
        return 2
    except Interrupted as e:
        print(f"sc-rt {args.command}: {e}: stopped", file=sys.stderr)
        return e.exit_code
    except (FileNotFoundError, RuntimeError) as e:
        print(f"sc-rt {args.command}: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        if e.errno not in (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EIO):
            raise
        out = getattr(args, "out", None)
        where = e.filename or (f"into --out {out}" if out else "the outputs")
        print(f"sc-rt {args.command}: error: cannot write {where}: {e.strerror or e}; "
              "the outputs are incomplete", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
