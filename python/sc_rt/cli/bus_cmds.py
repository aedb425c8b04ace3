"""``sc-rt spy``, ``lcm-spy``, ``fault``, ``report``, ``export``, ``replay``:
the commands on the bus and its logs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sc_rt.cli.common import bus_url, checked_out, claim_out, html_report, mcap_problem, print_metrics, write_mcap


def cmd_spy(args: argparse.Namespace) -> int:
    from sc_rt.tools.spy import main_loop

    if args.duration is not None and not args.duration > 0:
        print(f"sc-rt spy: error: --duration must be > 0, got {args.duration}", file=sys.stderr)
        return 2
    from sc_rt.wire.auth import load_key

    return main_loop(bus_url(args), args.channels, once=args.once, as_json=args.json,
                     duration=args.duration, refresh=args.refresh, window=args.window,
                     auth_key=load_key(args.auth_key))


def cmd_lcm_spy(args: argparse.Namespace) -> int:
    import os

    from sc_rt.tools.lcmspy import JavaMissing, spy_command, types_jar

    try:
        if args.build_only:
            print(types_jar(rebuild=args.rebuild, log=lambda m: print(m, file=sys.stderr)))
            return 0
        if args.rebuild:
            types_jar(rebuild=True)
        cmd, env = spy_command(bus_url(args), title=args.title)
    except JavaMissing as e:
        print(f"sc-rt lcm-spy: error: {e}", file=sys.stderr)
        return 2
    print(f"sc-rt lcm-spy: CLASSPATH={env['CLASSPATH']}\nsc-rt lcm-spy: {' '.join(cmd)}", flush=True)
    os.execvpe(cmd[0], cmd, env)  # the real tool replaces this process (signals reach it)
    return 0  # pragma: no cover


_WHEEL_ONLY = ("effectiveness", "bias", "friction", "rate")


def _fault_msg(args: argparse.Namespace):
    """The fault command of ``args``: a wheel's (fault_cmd_t) or a rod's
    (rod_fault_cmd_t); FaultArgError naming an option of the other target."""
    from sc_rt.tools.faultcmd import FaultArgError, clear_msg, inject_msg, rod_clear_msg, rod_inject_msg

    if args.action == "clear":
        return clear_msg(args.wheel) if args.rod is None else rod_clear_msg(args.rod)
    if args.rod is not None:
        given = [f"--{k}" for k in _WHEEL_ONLY if getattr(args, k) is not None] + (["--stuck"] if args.stuck else [])
        if given:
            raise FaultArgError(f"{given[0]} is a wheel fault's: a rod takes --kind (and --dipole when stuck)")
        if args.kind is None:
            raise FaultArgError("a rod fault needs --kind dead|stuck|reversed")
        return rod_inject_msg(args.rod, args.kind, dipole=args.dipole, at=args.at, until=args.until)
    if args.kind is not None or args.dipole is not None:
        raise FaultArgError(f"--{'kind' if args.kind is not None else 'dipole'} is a rod fault's: give --rod N")
    d = {k: (1.0 if k != "bias" else 0.0) if getattr(args, k) is None else getattr(args, k) for k in _WHEEL_ONLY}
    return inject_msg(args.wheel, stuck=args.stuck, at=args.at, until=args.until, **d)


def cmd_fault(args: argparse.Namespace) -> int:
    from sc_rt.tools.faultcmd import FaultArgError, send

    try:
        msg = _fault_msg(args)
        url = bus_url(args)
        from sc_rt.wire.auth import load_key

        sent = send(msg, url, args.prefix, timeout=args.timeout, wait=not args.no_wait,
                    auth_key=load_key(args.auth_key))
    except FaultArgError as e:
        print(f"sc-rt fault {args.action}: error: {e}", file=sys.stderr)
        return 2
    ch = sent.channel
    when = "now" if msg.now else f"at t = {msg.t_onset:g} s"
    until = '' if msg.t_end < 0 else f' until t = {msg.t_end:g} s'
    if args.rod is not None:
        kind = {1: "dead", 2: f"stuck at {msg.dipole:g} A m^2", 3: "reversed"}.get(msg.kind, "")
        what = f"{kind}, {when}{until}" if args.action == "inject" else "now"
        head = f"sc-rt fault: {args.action} rod {msg.rod} ({what}) -> {ch} on {url} (seq {msg.seq})"
    else:
        what = (f"effectiveness {msg.effectiveness:g}, bias {msg.bias:g} rad/s^2, rate {msg.rate:g} 1/s"
                f"{', stuck' if msg.stuck else ''}{f', friction x{msg.friction:g}' if msg.friction != 1.0 else ''}, "
                f"{when}{until}") if args.action == "inject" else "now"
        head = f"sc-rt fault: {args.action} wheel {msg.wheel} ({what}) -> {ch} on {url} (seq {msg.seq})"
    if args.no_wait:
        print(f"{head}; not waiting for the echo (applied only by an emulator started with "
              "--accept-fault-commands)")
        return 0
    if sent.refused_at is not None:
        print(f"{head}\nsc-rt fault: not applied: the emulator refused it (said on {sent.truth_channel} at "
              f"t = {sent.refused_at:.3f} s; why: its timing.json faults_applied)", file=sys.stderr)
        return 1
    if sent.applied_at is None:
        print(f"{head}\nsc-rt fault: not applied: no emulator echoed it on {sent.truth_channel} within "
              f"{args.timeout:g} s (none running on {url}, or not started with --accept-fault-commands)",
              file=sys.stderr)
        return 1
    print(f"{head}; applied: echoed on {sent.truth_channel} at t = {sent.applied_at:.3f} s")
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from sc_rt.logs.report import write_report

    out = Path(args.out) if args.out else Path(args.log).parent / "report"
    if mcap_problem(args.mcap, "report"):
        return 2
    if not Path(args.log).is_file():
        what = "not a regular file (a log is one)" if Path(args.log).exists() else "no such log file"
        print(f"sc-rt report: error: LOG {args.log}: {what}", file=sys.stderr)
        return 2
    claim_out(checked_out(str(out)))  # outputs belong to their run: a live run's directory is refused
    try:
        rep = write_report(args.log, out, scenario=args.scenario, prefix=args.prefix,
                           mode=args.mode, plots=not args.no_plots)
    except ValueError as e:
        print(f"sc-rt report: error: {e}", file=sys.stderr)
        return 2
    print(f"sc-rt report: {args.log}: {rep['events']} events in {rep['read_decode_s']:.2f} s "
          f"({rep['events_per_s']:.3g} events/s), {rep['rows']} rows, mode {rep['mode']}, "
          f"{rep['undecodable']} undecodable, skipped {rep['skipped']} -> {out}/")
    if rep.get("partial"):
        m = rep["metrics"]
        print(f"sc-rt report: PARTIAL: the log ends at t = {m.get('t_reached_s')} s"
              + (f" of {m['duration_s']:g} s" if m.get("t_reached_s") != m.get("duration_s") else "")
              + f" ({rep['incomplete_rows_at_end']} incomplete rows at its end left out); metrics.json "
              "\"partial\": true")
    lost = rep.get("incomplete_rows_dropped", 0) - rep.get("incomplete_rows_at_end", 0)
    if lost:
        print(f"sc-rt report: {lost} rows without their plant_truth_t (lost by the logger) left out")
    print_metrics(rep["metrics"])
    for c in rep["faults"]["commands"]:
        print(f"  fault command: {c}")
    html_report(out, "report")
    if args.mcap:  # the report reads damaged logs as far as it can: so does its MCAP
        return write_mcap(args.log, args.mcap, partial=True, who="report")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    return write_mcap(args.log, args.mcap, args.partial)


def cmd_replay(args: argparse.Namespace) -> int:
    import subprocess

    from sc_rt.logs.report import replay_command

    try:
        cmd = replay_command(args.log, bus_url(args), args.speed, args.channels, args.verbose)
    except ValueError as e:
        print(f"sc-rt replay: error: {e}", file=sys.stderr)
        return 2
    from sc_rt.hil.procs import child_kwargs
    from sc_rt.cli.interrupts import Interrupted

    proc = subprocess.Popen(cmd, **child_kwargs())  # its own group: stopped here, never orphaned
    try:
        return proc.wait()
    except Interrupted:
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
        raise
