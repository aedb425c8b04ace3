"""``sc-rt controller``: a Python law as an LCM controller process
(sc_rt.controller.pycontroller), and the options of ``sc-rt hil`` that put any
controller process on the bench: ``--external COMMAND``, ``--external-wait``,
``--start-timeout`` (sc_rt.hil.external, docs/PROTOCOL.md)."""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import sys

from sc_rt.cli.validate import (AUTH_KEY_HELP, MAX_RATE_HZ, UsageError, auth_key_file, integer, law_choice, lcm_url,
                                number, resolve_url)
from sc_rt.cli.common import add_set
from sc_rt.pylaw import is_python_law

__all__ = ["add_parser", "add_external_options", "external_choice", "cmd_controller"]


def add_external_options(h: argparse.ArgumentParser) -> None:
    g = h.add_mutually_exclusive_group()
    g.add_argument("--external", metavar="COMMAND",
                   help="start COMMAND as the controller instead of sc-rt-controller: any process that "
                        "speaks the protocol (docs/PROTOCOL.md); placeholders {url} {prefix} {mode} "
                        "{config} {summary} {python}, the same values in $SCRT_LCM_URL, $SCRT_PREFIX, "
                        "$SCRT_MODE, $SCRT_CONFIG, $SCRT_SUMMARY")
    g.add_argument("--external-wait", action="store_true",
                   help="start no controller: wait for one started by hand on the printed URL")
    h.add_argument("--start-timeout", type=number(0, 86400, unit="s"), metavar="S",
                   help="--external/--external-wait: wait this long for the controller's first answer "
                        "(default 30 s, --external-wait 300 s)")


def external_choice(args: argparse.Namespace) -> None:
    """``sc-rt hil --external``'s command, checked: it splits and its program
    exists. (A Python --law with --external/--external-wait and a
    --start-timeout without either are refused where the run is planned,
    sc_rt.cli.planning.)"""
    if args.external is not None:
        try:
            argv = shlex.split(args.external)
        except ValueError as e:
            raise UsageError(f"--external {args.external!r}: {e}") from e
        if not argv:
            raise UsageError("--external: empty command")
        prog = argv[0]
        if "{" not in prog and shutil.which(prog) is None:
            raise UsageError(f"--external {args.external!r}: cannot start {prog!r}: not found or not executable")


def add_parser(sub) -> None:
    c = sub.add_parser("controller", help="a Python law as an LCM controller process (lockstep or real time)")
    c.add_argument("scenario", nargs="?", help="a scenario file or shipped name (or --config)")
    c.add_argument("--law", type=law_choice, required=True, metavar="MODULE:CLASS",
                   help="the Python law: module:Class or path/file.py:Class (docs/LAWS.md)")
    c.add_argument("--config", metavar="FILE",
                   help="controller_config_t file instead of a scenario (sc-rt config, sc-rt hil writes one)")
    c.add_argument("--control-rate", type=number(0, MAX_RATE_HZ, unit="Hz"), metavar="HZ",
                   help="with a scenario: the rate (default: the scenario's; 10-100 Hz is what Python keeps)")
    c.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep", help="default: %(default)s")
    c.add_argument("--lcm-url", metavar="URL", type=lcm_url,
                   help="default: $SCRT_LCM_URL, else udpm://239.255.76.67:7667?ttl=0")
    c.add_argument("--prefix", default="", help="channel name prefix (default: none)")
    c.add_argument("--auth-key", metavar="FILE", type=auth_key_file,
                   default=os.environ.get("SCRT_AUTH_KEY") or None,
                   help=AUTH_KEY_HELP + " ($SCRT_AUTH_KEY: set by sc-rt hil --auth-key)")
    c.add_argument("--phase-offset", type=number(-1e6, 1e6, unit="us"), default=50.0, metavar="US",
                   help="real time: wake at least US after a state arrives (as sc-rt-controller; "
                        "default %(default)s)")
    c.add_argument("--max-steps", type=integer(1, 10**12), metavar="N", help="stop after N steps")
    c.add_argument("--summary", metavar="FILE", help="write the exit summary (JSON) there too")
    c.add_argument("--trigger", choices=("event", "timer"), default="event",
                   help="real time: step on each state's arrival (event), or on its own timer phase-locked to "
                        "the state arrivals (timer), as sc-rt-controller (default: %(default)s)")
    c.add_argument("--realtime-priority", action=argparse.BooleanOptionalAction, default=False,
                   help="the stepping thread asks for SCHED_FIFO 80 and mlockall, and falls back to SCHED_OTHER "
                        "with a warning where not permitted (the summary's scheduler says which; default: off)")
    c.add_argument("--cpu", type=integer(0), metavar="N", help="pin the stepping thread to CPU N")
    add_set(c)
    c.set_defaults(func=cmd_controller)


def cmd_controller(args: argparse.Namespace) -> int:
    from pathlib import Path

    from sc_rt import _core
    from sc_rt.wire.lcmio import DEFAULT_URL
    from sc_rt.wire.auth import load_key
    from sc_rt.controller.pycontroller import PyControllerProcess, write_summary
    from sc_rt.pylaw import register

    if not is_python_law(args.law):
        raise UsageError(f"--law {args.law}: sc-rt controller runs Python laws (module:Class); "
                         "the core's laws run in sc-rt-controller")
    if (args.scenario is None) == (args.config is None):
        raise UsageError("give exactly one of SCENARIO and --config FILE")
    try:
        spec = register(args.law)  # into the core's registry: the Controller runs it
    except ValueError as e:
        raise UsageError(str(e)) from e
    if args.config:
        try:
            raw = Path(args.config).read_bytes()
            cfg = _core.ControllerConfig.from_lcm_bytes(raw)
            nav = _core.nav_from_config_bytes(raw)
        except (OSError, ValueError, RuntimeError) as e:
            raise UsageError(f"--config {args.config}: {e}") from e
        cfg.law = spec  # the config's table is this law's (sc-rt hil writes the Python law's)
    else:
        from sc_rt.scenario.reader import load_scenario
        from sc_rt.scenario.overrides import with_overrides

        try:  # the Python law's own table ([laws.NAME], NAME its name attribute or class name)
            scn = with_overrides(load_scenario(args.scenario, args.sets or ()), control_rate_hz=args.control_rate)
            msg = scn.controller_config_msg(law=spec)
        except ValueError as e:
            raise UsageError(str(e)) from e
        cfg, nav = _core.ControllerConfig.from_lcm_bytes(msg.encode()), _core.nav_from_config_bytes(msg.encode())
    try:
        proc = PyControllerProcess(cfg, url=resolve_url(args.lcm_url, DEFAULT_URL),
                                   prefix=args.prefix, mode=args.mode, max_steps=args.max_steps,
                                   phase_offset_us=args.phase_offset, auth_key=load_key(args.auth_key), nav=nav,
                                   trigger=args.trigger, realtime_priority=args.realtime_priority, cpu=args.cpu)
    except ValueError as e:
        raise UsageError(str(e)) from e
    write_summary(proc.run(), args.summary)
    print(f"sc-rt controller: {proc.cnt['steps']} steps", file=sys.stderr)
    return 0
