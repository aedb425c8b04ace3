"""The ``sc-rt`` command. Every subcommand that takes a scenario loads and
validates it first; a bad file exits with code 2 and a message naming the
file, line, key and value."""

from __future__ import annotations

import argparse
import errno
import json
import signal
import sys
from pathlib import Path

from sc_rt import __version__

from sc_rt.cli.interrupts import Interrupted, flag_signals, raise_on_signals
from sc_rt.cli.validate import (MAX_RATE_HZ, MAX_TIME_SCALE, OneLineParser, UsageError, check_run_size,
                                given_options, integer, lcm_url, number, out_dir, out_file, resolve_url,
                                rounded)
from sc_rt.cli.lawarg import LAW_HELP, core_law_choice, law_choice
from sc_rt.cli.controller import add_external_options, external_choice
from sc_rt.scenario.model import LAWS  # noqa: E402

LAW_CHOICES = tuple(LAWS)  # the law table (sc_rt.scenario.model)


def _scenario(path: str, args: argparse.Namespace | None = None):
    from sc_rt.scenario.model import load_scenario

    return load_scenario(path)


def _print_metrics(m: dict, faults=()) -> None:
    from sc_rt.results.verdict import verdict_line

    def f(v):
        return "-" if v is None else (f"{v:.3g}" if isinstance(v, float) else str(v))

    marks = list(m["sigma_e_norm"])
    faults = ", ".join(f"wheel {x['wheel']} from {x['onset']:g} s (L {x['effectiveness']:g}, "
                       f"bias {x['bias']:g} rad/s^2)" for x in faults) or "none"
    safe = m.get("safe_steps", 0)
    why = "; ".join(f"{k}: {v}" for k, v in m.get("safe_reasons", {}).items())
    rows = [
        ("verdict", verdict_line(m, m["controller"])),
        ("controller", m["controller"]), ("engine", m["engine"]),
        ("steps", m["steps"]), ("wall [s]", f"{m['wall_s']:.3f}"), ("finite", m["finite"]),
        ("first bound violation [s]", f(m["first_bound_violation_s"])),
        ("  axis", "-" if m["first_bound_violation_axis"] is None else "xyz"[m["first_bound_violation_axis"] - 1]),
        (f"|sigma_BD| at {'/'.join(marks)} s", " / ".join(f(m["sigma_e_norm"][k]) for k in marks)),
        ("max pointing error after 30 s [arcsec]", f(m.get("max_pointing_error_arcsec_after_30s"))),
        ("max |omega_BD_B| after 70 s [rad/s]", f(m["max_abs_omega_e_after_70s"])),
        ("max observer error after 30 s [rad/s^2]", f(m["max_observer_error_after_30s"])),
        ("max |u_cmd| before saturation [rad/s^2]", f(m["max_abs_u_cmd"])),
        ("max |wheel accel| applied [rad/s^2]", f(m["max_abs_wheel_accel"])),
        ("saturated fraction", f(m["saturated_fraction"])),
        ("SAFE steps", f"{safe}" + (f" from {m['safe_from_s']:.1f} s ({why})" if safe else "")),
        ("faults scheduled", faults),
    ]
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"  {k:<{w}}  {v}")


def _out_dir(value: str, option: str = "--out") -> Path:
    """The output directory, checked before anything runs (exit 2 if unusable)."""
    from sc_rt.results.output import check_out_dir

    problem = check_out_dir(Path(value), option)
    if problem:
        raise UsageError(problem)
    return Path(value)


def _html_report(out: Path, who: str) -> None:
    """report.html of the run in ``out`` (sc_rt.results.html_report)."""
    from sc_rt.results.html_report import write_html_report

    print(f"sc-rt {who}: report for reading: {write_html_report(out)}")


def cmd_sim(args: argparse.Namespace) -> int:
    from sc_rt.results.output import write_run
    from sc_rt.sim.engines import simulate

    from sc_rt.scenario.overrides import with_overrides

    from sc_rt.pylaw import is_python_law

    out = _out_dir(args.out)
    pylaw = args.law if is_python_law(args.law) else None  # a Python law: sc_rt.pylaw
    if pylaw and args.engine != "python":
        raise UsageError(f"--engine {args.engine}: a Python law (--law {pylaw}) runs on the python engine only")
    scn = with_overrides(_scenario(args.scenario), law=None if pylaw else args.law,
                         control_rate_hz=args.control_rate, duration=args.duration, plant_step=args.plant_step)
    check_run_size(scn, given_options(args, control_rate="--control-rate", duration="--duration",
                                      plant_step="--plant-step"))
    from sc_rt.sim import engines

    from sc_rt.scenario.overrides import grid

    engines.STOP.clear()
    print(f"sc-rt sim: {scn.name}: {args.engine} engine, {grid(scn).n_ctrl + 1} rows ...", file=sys.stderr,
          flush=True)
    with flag_signals(lambda _s: engines.STOP.set()) as signals:
        res = simulate(scn, engine=args.engine, law=pylaw)
    stopped = None
    if signals:  # a signal: the rows done so far (the python engine stops at its next step)
        stopped = f"interrupted by {signal.Signals(signals[0]).name}"
        if len(res) < grid(scn).n_ctrl + 1:
            mark_partial(res, stopped)
    files = write_run(res, out, figures=not args.no_plots)
    print(f"sc-rt sim: {scn.name} -> {out}/ ({len(files)} files: {', '.join(p.name for p in files)})")
    _print_metrics(res.metrics, res.meta.faults)
    _html_report(out, "sim")
    if res.diverged:
        print(f"sc-rt sim: DIVERGED: {res.message}", file=sys.stderr)
    if stopped:
        return _stopped(res, stopped, signals[0], out, "sim")
    return 0


def cmd_hil(args: argparse.Namespace) -> int:
    from sc_rt.bus.hil import run_hil

    from sc_rt.scenario.overrides import with_overrides

    out = _out_dir(args.out)
    pylaw = external_choice(args)  # a Python law, --external or --external-wait (checked here)
    scn = with_overrides(_scenario(args.scenario), law=None if pylaw else args.law,
                         control_rate_hz=args.control_rate, duration=args.duration)
    sizes = dict(control_rate="--control-rate", duration="--duration")
    if args.mode == "realtime":
        sizes["time_scale"] = "--time-scale"
    check_run_size(scn, given_options(args, **sizes), bus=True, realtime=args.mode == "realtime",
                   time_scale=args.time_scale)
    url = resolve_url(args.lcm_url, None)
    mcap = getattr(args, "mcap", None)
    mcap = str(Path(args.out) / "run.mcap") if mcap == "" else mcap
    if _mcap_problem(mcap, "hil"):
        return 2
    res = run_hil(scn, out=out, mode=args.mode, lcm_url=url,
                  prefix=args.prefix, realtime_priority=args.realtime_priority,
                  time_scale=args.time_scale, accept_fault_commands=args.accept_fault_commands,
                  plots=not args.no_plots, law=pylaw, external=args.external,
                  external_wait=args.external_wait, start_timeout=args.start_timeout)
    print(f"sc-rt hil: {scn.name} ({args.mode}) -> {res.out}/ ({len(res.files)} files: "
          f"{', '.join(p.name for p in res.files)}, run.lcmlog)")
    _print_metrics(res.metrics, res.run.meta.faults)
    t = rounded(res.timing)
    lat = t["state_to_cmd_latency_us"]
    print(f"  state-to-command latency [us]  p50 {lat['p50']}  p99 {lat['p99']}  max {lat['max']}")
    print(f"  steps/s {t['steps_per_s'] or 0:.0f}  deadline misses {t['deadline_misses']}  "
          f"stale states {t['stale_states']}  dropped {t['dropped']}  malformed {t['malformed']}  "
          f"scheduler {t['scheduler']}")
    if res.stopped:
        return _stopped(res.run, res.stopped, res.signum, res.out, "hil")
    _html_report(Path(res.out), "hil")
    if mcap:
        return _export_mcap(Path(res.out) / "run.lcmlog", mcap, who="hil")
    return 0


def mark_partial(run, why: str) -> None:
    """A finished run record that ends before its duration: partial, why, and the time reached."""
    run.partial = True
    run.metrics.update(partial=True, stopped=why, t_reached_s=float(run.t[-1]) if len(run) else None)


def _stopped(run, why: str, signum: int | None, out, who: str) -> int:
    """Say that a run stopped early and where its outputs are; the exit
    code: 128 + the signal, else 1."""
    reached = run.metrics.get("t_reached_s", float(run.t[-1]) if len(run) else None)
    what = (f"partial outputs in {out}/ (metrics.json \"partial\": true, {len(run)} complete rows)"
            if run.partial else f"the run had ended: complete outputs in {out}/")
    print(f"sc-rt {who}: STOPPED at t = {'-' if reached is None else f'{reached:.4g}'} s of "
          f"{run.meta.duration_s:g} s: {why}; {what}", file=sys.stderr)
    return 128 + signum if signum else 1


#: The demo's two runs: the paper's law on the paper's fault scenario, and
#: the design that holds on the same plant and faults (docs/REPRODUCTION.md).
DEMO_RUNS = (("paper DSC+PPC", "paper_faults", "paper"),
             ("feasible 10 Hz design", "ppc_feasible_10hz", "feasible_10hz"))


def cmd_demo(args: argparse.Namespace) -> int:
    """The main job: the paper's law and the feasible design, each through
    the real LCM loop (controller process, emulator, lcm-logger)."""
    from sc_rt.bus.hil import run_hil
    from sc_rt.results.verdict import verdict_line

    out = _out_dir(args.out)
    results = []
    for label, name, sub in DEMO_RUNS:
        scn = _scenario(name)
        print(f"sc-rt demo: {label} ({scn.name}) through LCM, lockstep ...", file=sys.stderr, flush=True)
        results.append((label, run_hil(scn, out=out / sub, mode="lockstep",
                                       lcm_url=resolve_url(args.lcm_url, None))))
    for label, res in results:
        print(verdict_line(res.metrics, label))
    for label, res in results:
        _html_report(Path(res.out), "demo")
    print("\nWhy the paper's law leaves its bound in a sampled loop, and how the feasible design "
          "was found: docs/REPRODUCTION.md")
    for label, res in results:
        print(f"\n{label}: {len(res.files)} files in {res.out.resolve()}/")
        for p in res.files:
            print(f"  {p}")
    return 0


def cmd_emulator(args: argparse.Namespace) -> int:
    from sc_rt.bus.emulator import Emulator
    from sc_rt.bus.lcmio import DEFAULT_URL

    from sc_rt.scenario.overrides import with_overrides

    if args.out:
        _out_dir(args.out)
    scn = with_overrides(_scenario(args.scenario), control_rate_hz=args.rate, duration=args.duration)
    check_run_size(scn, given_options(args, rate="--rate", duration="--duration", time_scale="--time-scale"),
                   bus=True, realtime=args.mode == "realtime", time_scale=args.time_scale)
    url = resolve_url(args.lcm_url, DEFAULT_URL)
    print(f"sc-rt emulator: LCM URL {url}", file=sys.stderr, flush=True)
    sig: list[int] = []
    emu = Emulator(scn, mode=args.mode, url=url, prefix=args.prefix, time_scale=args.time_scale,
                   accept_fault_commands=args.accept_fault_commands,
                   stop=lambda: f"interrupted by {signal.Signals(sig[0]).name}" if sig else None)
    with flag_signals(sig.append):  # the run stops at its next step, its rows kept
        res = emu.run()
    summary = {"rows": len(res), "counters": dict(res.counters), "gaps_s": rounded(res.gaps),
               "diverged": res.diverged, "partial": res.partial,
               "t_reached_s": float(res.t[-1]) if len(res) else None}
    if args.out:
        from sc_rt.results.metrics import finish_run
        from sc_rt.results.output import write_run

        out = Path(args.out)
        write_run(finish_run(res), out, figures=False)
        (out / "emulator.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary))
    if sig:
        return _stopped(res, res.message or "interrupted", sig[0], args.out or "-", "emulator")
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    from sc_rt.studies.check import LEVELS, check_scenario, exit_code

    findings = check_scenario(args.scenario, run_estimate=not args.fast, law=args.law)
    for f in findings:
        if f.level != "ok" or args.verbose:
            print(f)
    rc = exit_code(findings, strict=args.strict)
    n = {lvl: sum(f.level == lvl for f in findings) for lvl in LEVELS}
    print(f"sc-rt check: {args.scenario}{f' for {args.law}' if args.law else ''}: {n['error']} errors, "
          f"{n['warning']} warnings, {n['note']} notes{' (strict: as warnings)' if args.strict else ''}, "
          f"{n['ok']} ok -> exit {rc}")
    return rc


def cmd_scenarios(args: argparse.Namespace) -> int:
    """The shipped scenarios, one line each: name and description (or file)."""
    from sc_rt.scenario.shipped import shipped

    library = shipped()
    w = max(map(len, library), default=0)
    for name, (path, description) in library.items():
        print(f"{name:<{w}}  {path if args.paths else description}")
    return 0


def cmd_montecarlo(args: argparse.Namespace) -> int:
    from sc_rt.cli.montecarlo import cmd_montecarlo as run

    return run(args)


def cmd_config(args: argparse.Namespace) -> int:
    scn = _scenario(args.scenario)
    data = scn.controller_config_msg(args.law, args.control_rate).encode()
    Path(args.out).write_bytes(data)
    print(f"sc-rt config: controller_config_t ({len(data)} bytes) -> {args.out}")
    return 0


def cmd_design(args: argparse.Namespace) -> int:
    """PD design, margins and sampled-data stability (sc_rt.studies.design, docs/DESIGN.md)."""
    from sc_rt.studies.design import DEFAULT_LATENCY_S, design_report, format_design_text, write_design
    from sc_rt.sim.engines import with_overrides

    scn = with_overrides(_scenario(args.scenario), control_rate_hz=args.rate)  # validates --rate
    latency = DEFAULT_LATENCY_S if args.latency is None else args.latency
    if args.timing:
        try:
            timing = json.loads(Path(args.timing).read_text())
            latency = timing["state_to_cmd_latency_us"]["p99"] * 1e-6
        except (KeyError, TypeError, ValueError) as e:
            raise RuntimeError(f"{args.timing}: no state_to_cmd_latency_us.p99 ({e})") from e
    if not latency > 0:
        raise RuntimeError(f"latency must be > 0 s, got {latency!r}")
    rate = scn.run.control_rate_hz
    rep = design_report(scn, rate, latency=latency)
    out = Path(args.out)
    paths = write_design(rep, scn, out, plots=not args.no_plots)
    print(format_design_text(rep, out, paths))
    return 0


def cmd_reproduce(args: argparse.Namespace) -> int:
    """The paper's claims checked with numbers (sc_rt.studies.reproduce, docs/REPRODUCTION.md)."""
    from sc_rt.studies.reproduce import reproduce

    out = Path(args.out)
    doc = reproduce(out, engine=args.engine, control_rate_hz=args.control_rate,
                    plant_step=args.plant_step, plots=not args.no_plots,
                    with_sensitivity=args.sensitivity, with_search=args.search, dpi=args.dpi)
    print(f"sc-rt reproduce: {doc['command']} -> {out}/")
    for c in doc["claims"]:
        print(f"  {c['id']} {c['verdict']:<15} {c['claim']}\n      {c['measured']}")
    return 0


# --- monitoring and reports (issue 8): spy, lcm-spy, fault, report, replay ---
def _url(args: argparse.Namespace) -> str:
    """--lcm-url, else $SCRT_LCM_URL (checked), else LCM's usual port."""
    from sc_rt.bus.lcmio import DEFAULT_URL

    return resolve_url(args.lcm_url, DEFAULT_URL)


def cmd_spy(args: argparse.Namespace) -> int:
    from sc_rt.bus.spy import main_loop

    if args.duration is not None and not args.duration > 0:
        print(f"sc-rt spy: error: --duration must be > 0, got {args.duration}", file=sys.stderr)
        return 2
    return main_loop(_url(args), args.channels, once=args.once, as_json=args.json,
                     duration=args.duration, refresh=args.refresh, window=args.window)


def cmd_lcm_spy(args: argparse.Namespace) -> int:
    import os

    from sc_rt.bus.lcmspy import JavaMissing, spy_command, types_jar

    try:
        if args.build_only:
            print(types_jar(rebuild=args.rebuild, log=lambda m: print(m, file=sys.stderr)))
            return 0
        if args.rebuild:
            types_jar(rebuild=True)
        cmd, env = spy_command(_url(args), title=args.title)
    except JavaMissing as e:
        print(f"sc-rt lcm-spy: error: {e}", file=sys.stderr)
        return 2
    print(f"sc-rt lcm-spy: CLASSPATH={env['CLASSPATH']}\nsc-rt lcm-spy: {' '.join(cmd)}", flush=True)
    os.execvpe(cmd[0], cmd, env)  # the real tool replaces this process (signals reach it)
    return 0  # pragma: no cover


def cmd_fault(args: argparse.Namespace) -> int:
    from sc_rt.bus.faultcmd import FaultArgError, clear_msg, inject_msg, send

    try:
        if args.action == "inject":
            msg = inject_msg(args.wheel, effectiveness=args.effectiveness, bias=args.bias,
                             stuck=args.stuck, at=args.at, until=args.until, rate=args.rate)
        else:
            msg = clear_msg(args.wheel)
        url = _url(args)
        sent = send(msg, url, args.prefix, timeout=args.timeout, wait=not args.no_wait)
    except FaultArgError as e:
        print(f"sc-rt fault {args.action}: error: {e}", file=sys.stderr)
        return 2
    ch = sent.channel
    when = "now" if msg.now else f"at t = {msg.t_onset:g} s"
    what = (f"effectiveness {msg.effectiveness:g}, bias {msg.bias:g} rad/s^2, rate {msg.rate:g} 1/s"
            f"{', stuck' if msg.stuck else ''}, {when}"
            f"{'' if msg.t_end < 0 else f' until t = {msg.t_end:g} s'}") if args.action == "inject" else "now"
    head = f"sc-rt fault: {args.action} wheel {msg.wheel} ({what}) -> {ch} on {url} (seq {msg.seq})"
    if args.no_wait:
        print(f"{head}; not waiting for the echo (applied only by an emulator started with "
              "--accept-fault-commands)")
        return 0
    if sent.applied_at is None:
        print(f"{head}\nsc-rt fault: not applied: no emulator echoed it on {sent.truth_channel} within "
              f"{args.timeout:g} s (none running on {url}, or not started with --accept-fault-commands)",
              file=sys.stderr)
        return 1
    print(f"{head}; applied: echoed on {sent.truth_channel} at t = {sent.applied_at:.3f} s")
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from sc_rt.bus.report import write_report

    out = Path(args.out) if args.out else Path(args.log).parent / "report"
    if _mcap_problem(args.mcap, "report"):
        return 2
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
              + f" ({rep['incomplete_rows_dropped']} incomplete rows at its end left out); metrics.json "
              "\"partial\": true")
    _print_metrics(rep["metrics"])
    for c in rep["faults"]["commands"]:
        print(f"  fault command: {c}")
    _html_report(out, "report")
    if args.mcap:  # the report reads damaged logs as far as it can: so does its MCAP
        return _export_mcap(args.log, args.mcap, partial=True, who="report")
    return 0


def _export_mcap(log, out, partial: bool = False, who: str = "export") -> int:
    """Write the MCAP of ``log`` (sc-rt export, report --mcap, hil --mcap)."""
    from sc_rt.bus.mcap_export import ExportError, export_mcap

    try:
        s = export_mcap(log, out, partial=partial)
    except ExportError as e:
        print(f"sc-rt {who}: error: {e}", file=sys.stderr)
        return 2
    damaged = (f", damaged log: {s.skipped_bytes} bytes skipped, torn tail {s.torn_tail_bytes} bytes"
               if s.skipped_bytes or s.torn_tail_bytes else "")
    print(f"sc-rt {who}: {log}: {s.events} events -> {out} ({s.messages} messages, derived "
          f"{sum(s.derived.values())}) in {s.seconds:.2f} s ({s.events_per_s or 0:.3g} events/s); "
          f"{s.undecodable} undecodable{' ' + str(s.undecodable_kinds) if s.undecodable else ''} and "
          f"{s.foreign_events} events of foreign "
          f"channels carried raw{damaged}")
    return 0


def _mcap_problem(path: str | None, who: str) -> bool:
    """Print why ``--mcap path`` cannot be written (checked before any work)."""
    from sc_rt.bus.mcap_export import ExportError, check_output

    try:
        if path:
            check_output(Path(path))
    except ExportError as e:
        print(f"sc-rt {who}: error: {e}", file=sys.stderr)
        return True
    return False


def cmd_export(args: argparse.Namespace) -> int:
    return _export_mcap(args.log, args.mcap, args.partial)


def cmd_replay(args: argparse.Namespace) -> int:
    import subprocess

    from sc_rt.bus.report import replay_command

    try:
        cmd = replay_command(args.log, _url(args), args.speed, args.channels, args.verbose)
    except ValueError as e:
        print(f"sc-rt replay: error: {e}", file=sys.stderr)
        return 2
    try:
        return subprocess.call(cmd)
    except KeyboardInterrupt:
        return 130


def _add_monitoring(sub) -> None:
    url_help = ("default: $SCRT_LCM_URL, else udpm://239.255.76.67:7667?ttl=0 (sc-rt hil picks a free "
                "port and prints it: pass its URL)")

    y = sub.add_parser("spy", help="terminal monitor of the bus: rates, jitter, newest values")
    y.add_argument("--lcm-url", metavar="URL", type=lcm_url, help=url_help)
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

    f = sub.add_parser("fault", help="inject or clear a wheel fault live (fault_cmd_t on SCRT_FAULT)")
    fs = f.add_subparsers(dest="action", metavar="ACTION", required=True)
    fi = fs.add_parser("inject", help="inject a fault on one wheel")
    # the values are checked by sc_rt.bus.faultcmd.inject_msg (exit 2, one line)
    fi.add_argument("--wheel", type=int, required=True, metavar="N", help="wheel 1..4")
    fi.add_argument("--effectiveness", type=float, default=1.0, metavar="E",
                    help="L in [0, 1] (default: %(default)s)")
    fi.add_argument("--bias", type=float, default=0.0, metavar="B",
                    help="bias ubar [rad/s^2] (default: %(default)s)")
    fi.add_argument("--stuck", action="store_true", help="the wheel keeps its speed at onset")
    when = fi.add_mutually_exclusive_group()
    when.add_argument("--at", type=float, metavar="T",
                      help="onset at simulation time T [s] (refused when the emulator is already past it)")
    when.add_argument("--now", action="store_true", help="onset at the emulator's current time (default)")
    fi.add_argument("--until", type=float, metavar="T",
                    help="end at simulation time T [s] (default: never)")
    fi.add_argument("--rate", type=float, default=1.0, metavar="A",
                    help="evolution rate a of (16) [1/s] (default: %(default)s)")
    fc = fs.add_parser("clear", help="the wheel is healthy again from now on")
    fc.add_argument("--wheel", type=int, required=True, metavar="N", help="wheel 1..4")
    for q in (fi, fc):
        q.add_argument("--lcm-url", metavar="URL", type=lcm_url, help=url_help)
        q.add_argument("--prefix", default="", help="channel name prefix (default: none)")
        q.add_argument("--timeout", type=number(0, 600, unit="s"), default=3.0, metavar="S",
                       help="wait this long for an emulator's plant_truth_t to echo the fault "
                            "(default: %(default)s s); exit 1 if none does")
        q.add_argument("--no-wait", action="store_true",
                       help="publish and exit 0 without waiting for the echo")
        q.set_defaults(func=cmd_fault)

    r = sub.add_parser("report", help="metrics, timing and figures of a run from its LCM log")
    r.add_argument("log")
    r.add_argument("--out", metavar="DIR", type=out_dir, help="default: report/ next to the log")
    r.add_argument("--scenario", metavar="FILE",
                   help="scenario of the run (needed only for a log without SCRT_CONFIG; gives the duration)")
    r.add_argument("--prefix", help="channel prefix (default: detected)")
    r.add_argument("--mode", choices=("lockstep", "realtime"), help="default: detected")
    r.add_argument("--no-plots", action="store_true", help="no figures (default: figures)")
    r.add_argument("--mcap", metavar="OUT", help="also write the log as MCAP (as sc-rt export)")
    r.set_defaults(func=cmd_report)

    x = sub.add_parser("export", help="an LCM log as MCAP (JSON + schemas from the .lcm files) for Foxglove, PlotJuggler")
    x.add_argument("log")
    x.add_argument("--mcap", required=True, metavar="OUT", help="the MCAP file to write")
    x.add_argument("--partial", action="store_true",
                   help="a truncated or corrupt log: export the events that can be read (default: refuse)")
    x.set_defaults(func=cmd_export)

    p = sub.add_parser("replay", help="play an LCM log onto the bus (the wheel's lcm-logplayer)")
    p.add_argument("log")
    p.add_argument("--lcm-url", metavar="URL", type=lcm_url, help=url_help)
    p.add_argument("--speed", type=number(0, 1e4), default=1.0, metavar="X",
                   help="playback speed (default: %(default)s)")
    p.add_argument("--channels", metavar="REGEX", help="only these channels (default: all)")
    p.add_argument("--verbose", action="store_true", help="lcm-logplayer's own output")
    p.set_defaults(func=cmd_replay)


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="sc-rt",
        epilog="Exit codes: 0 done; 1 the run or check found a problem (sc-rt check: warnings; "
               "sc-rt fault: no emulator echoed; sc-rt spy: nothing heard); 2 a bad option, value, "
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

    s = sub.add_parser("sim", help="offline closed loop (plant + C++ controller core)")
    s.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    s.add_argument("--law", "--controller", dest="law", type=law_choice, metavar="LAW",
                   help=LAW_HELP + "; --controller is the old name")
    s.add_argument("--engine", choices=("python", "cpp", "unsampled"), default="python",
                   help="unsampled: reference mode, the law inside every RK4 stage (no hold) "
                        "(default: %(default)s)")
    s.add_argument("--control-rate", type=number(0, MAX_RATE_HZ, unit='Hz'), metavar="HZ", help="default: the scenario's")
    s.add_argument("--duration", type=number(unit="s"), metavar="S", help="default: the scenario's")
    s.add_argument("--plant-step", type=number(unit="s"), metavar="S",
                   help="plant RK4 step (default: the scenario's, reduced to divide the control period)")
    s.add_argument("--out", default="out/sim", type=out_dir, metavar="DIR", help="default: %(default)s")
    s.add_argument("--no-plots", action="store_true", help="no figures (default: figures)")
    s.set_defaults(func=cmd_sim)

    def lcm_opts(q, url_help="default: $SCRT_LCM_URL, else udpm://239.255.76.67:<a free port>?ttl=0 "
                             "(printed; nothing leaves the machine)"):
        q.add_argument("--lcm-url", metavar="URL", type=lcm_url, help=url_help)
        q.add_argument("--prefix", default="", help="channel name prefix (default: none)")

    h = sub.add_parser("hil", help="controller process + plant emulator + lcm-logger over LCM")
    h.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    h.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep", help="default: %(default)s")
    h.add_argument("--law", "--controller", dest="law", type=law_choice, metavar="LAW",
                   help=LAW_HELP + "; a Python law runs in `sc-rt controller`")
    h.add_argument("--control-rate", type=number(0, MAX_RATE_HZ, unit='Hz'), metavar="HZ", help="default: the scenario's")
    h.add_argument("--duration", type=number(unit="s"), metavar="S", help="default: the scenario's")
    h.add_argument("--out", default="out/hil", type=out_dir, metavar="DIR", help="default: %(default)s")
    h.add_argument("--realtime-priority", action="store_true",
                   help="controller asks for SCHED_FIFO + mlockall (default: off)")
    h.add_argument("--time-scale", type=number(0, MAX_TIME_SCALE), default=1.0, metavar="X",
                   help="real time: > 1 runs faster (default: %(default)s)")
    h.add_argument("--accept-fault-commands", action="store_true",
                   help="the emulator applies fault_cmd_t from SCRT_FAULT (default: ignored)")
    h.add_argument("--no-plots", action="store_true", help="no figures (default: figures)")
    h.add_argument("--mcap", nargs="?", const="", metavar="OUT",
                   help="also write the run's log as MCAP (default OUT: run.mcap in --out; as sc-rt export)")
    add_external_options(h)  # --external, --external-wait, --start-timeout (sc_rt/cli/controller.py)
    lcm_opts(h)
    h.set_defaults(func=cmd_hil)

    d = sub.add_parser("demo", help="the main job: the paper's DSC+PPC and the feasible 10 Hz design "
                       "on the paper's fault scenario, each through the real LCM loop")
    d.add_argument("--out", default="out/demo", type=out_dir, metavar="DIR",
                   help="output directory, one subdirectory per run (default: %(default)s)")
    d.add_argument("--lcm-url", metavar="URL", type=lcm_url,
                   help="LCM URL (default: $SCRT_LCM_URL, else a free port on 239.255.76.67, ttl=0)")
    d.set_defaults(func=cmd_demo)

    e = sub.add_parser("emulator", help="the plant as an LCM process")
    e.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    e.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep", help="default: %(default)s")
    e.add_argument("--rate", type=number(0, MAX_RATE_HZ, unit='Hz'), metavar="HZ",
                   help="state publish rate (default: the scenario's control rate)")
    e.add_argument("--time-scale", type=number(0, MAX_TIME_SCALE), default=1.0, metavar="X",
                   help="real time: > 1 runs faster (default: %(default)s)")
    e.add_argument("--duration", type=number(unit="s"), metavar="S", help="default: the scenario's")
    e.add_argument("--accept-fault-commands", action="store_true",
                   help="apply fault_cmd_t from SCRT_FAULT (default: ignored)")
    e.add_argument("--out", metavar="DIR", type=out_dir,
                   help="write trajectory.npz and emulator.json there (default: nothing written)")
    lcm_opts(e, "default: $SCRT_LCM_URL, else udpm://239.255.76.67:7667?ttl=0 (the port sc-rt-controller "
                "uses by default)")
    e.set_defaults(func=cmd_emulator)

    k = sub.add_parser("check", help="check a scenario: schema, bound at t=0, (26), Theorem 1, B, Cbar, limits")
    k.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    k.add_argument("--verbose", "-v", action="store_true", help="also list the checks that pass")
    k.add_argument("--fast", action="store_true", help="estimate r's bound at t = 0 instead of along a run")
    k.add_argument("--law", "--controller", dest="law", type=core_law_choice, metavar="LAW",
                   help="check for this law (default: the scenario's): only its conditions are checked; "
                        + ", ".join(LAW_CHOICES) + " or plugin:PATH_OR_NAME")
    k.add_argument("--strict", action="store_true", help="notes count as warnings (exit 1)")
    k.set_defaults(func=cmd_check)

    n = sub.add_parser("scenarios", help="the shipped scenarios: any SCENARIO argument may be one of these names")
    n.add_argument("--paths", action="store_true", help="print each file instead of its description")
    n.set_defaults(func=cmd_scenarios)

    from sc_rt.cli.montecarlo import add_parser as add_montecarlo

    add_montecarlo(sub)  # its options and their checks: sc_rt/cli/montecarlo.py
    from sc_rt.cli.controller import add_parser as add_controller

    add_controller(sub)  # sc-rt controller --law module:Class: sc_rt/cli/controller.py
    add_new_law(sub)  # sc-rt new-law: sc_rt/cli/newlaw.py
    from sc_rt.cli.compare import add_parser as add_compare

    add_compare(sub)  # sc-rt compare: sc_rt/cli/compare.py

    c = sub.add_parser("config", help="write the scenario's controller_config_t for sc-rt-controller")
    c.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    c.add_argument("--out", required=True, type=out_file, metavar="FILE", help="the file to write")
    c.add_argument("--law", "--controller", dest="law", type=core_law_choice, metavar="LAW",
                   help="control law: " + ", ".join(LAW_CHOICES) + " or plugin:PATH_OR_NAME (default: the scenario's)")
    c.add_argument("--control-rate", type=number(0, MAX_RATE_HZ, unit='Hz'), metavar="HZ", help="default: the scenario's")
    c.set_defaults(func=cmd_config)

    g = sub.add_parser("design", help="PD design, stability margins and sampled-data stability limits")
    g.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    g.add_argument("--rate", type=number(0, MAX_RATE_HZ, unit='Hz'), metavar="HZ", help="control rate (default: the scenario's)")
    g.add_argument("--latency", type=number(0, 10, unit="s"), metavar="S",
                   help="latency of the Pade case (default 1.2e-3 s, a measured HIL p99)")
    g.add_argument("--timing", metavar="FILE", help="take the latency from a HIL timing.json (p99)")
    g.add_argument("--out", default="out/design", type=out_dir, metavar="DIR", help="default: %(default)s")
    g.add_argument("--no-plots", action="store_true", help="no figures (default: figures)")
    g.set_defaults(func=cmd_design)
    q = sub.add_parser("reproduce", help="check the paper's claims: both scenarios, four laws -> claims.json, figures")
    q.add_argument("--out", default="out/reproduce", type=out_dir, metavar="DIR", help="default: %(default)s")
    q.add_argument("--engine", choices=("python", "cpp"), default="cpp", help="default: %(default)s")
    q.add_argument("--control-rate", type=number(0, MAX_RATE_HZ, unit='Hz'), metavar="HZ", help="default: the scenarios' 10 Hz")
    q.add_argument("--plant-step", type=number(unit="s"), metavar="S", help="default: the scenarios' 0.1 s")
    q.add_argument("--sensitivity", action="store_true",
                   help="also the verdicts at 10 Hz (plant step 0.1 and 0.01 s), 100 Hz and 1 kHz")
    q.add_argument("--search", action="store_true",
                   help="also bisect the tightest chiinf that holds per rate and run scenarios/ppc_feasible_*.toml")
    q.add_argument("--dpi", type=integer(10, 1200), default=80, help="figure resolution (default: %(default)s)")
    q.add_argument("--no-plots", action="store_true", help="no figures (default: figures)")
    q.set_defaults(func=cmd_reproduce)
    _add_monitoring(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    raise_on_signals()  # SIGINT, SIGTERM: Interrupted (exit 130, 143) unless a command handles them
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    from sc_rt.scenario.model import ScenarioError

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
        print(f"sc-rt {args.command}: error: cannot write {e.filename or 'the outputs'}: {e.strerror}; "
              "the outputs are incomplete", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
