"""``sc-rt sim``, ``hil``, ``demo``, ``emulator``: the commands that run the loop."""

from __future__ import annotations

import argparse
import json
import signal
import sys
from pathlib import Path

from sc_rt.cli.interrupts import flag_signals
from sc_rt.cli.validate import UsageError, check_run_size, given_options, resolve_url, rounded
from sc_rt.cli.controller import external_choice
from sc_rt.cli.common import (checked_out, claim_out, html_report, invalid_exit, mcap_problem,
                              print_metrics, report_stopped, scenario_arg, strict_exit, write_mcap)
from sc_rt.results.judge.gate import gate_problems


def cmd_sim(args: argparse.Namespace) -> int:
    from sc_rt.results.judge.metrics import mark_partial
    from sc_rt.results.present.output import write_run

    from sc_rt.scenario.overrides import with_overrides

    out = checked_out(args.out)
    # any law, a Python one too (sc_rt.pylaw: it runs inside the core's controller, on every engine)
    scn = with_overrides(scenario_arg(args.scenario, args), law=args.law,
                         control_rate_hz=args.control_rate, duration=args.duration, plant_step=args.plant_step)
    if args.engine == "unsampled":
        from sc_rt.sim.unsampled import refusal

        if (why := refusal(scn.run.controller)) is not None:
            raise UsageError(f"--engine unsampled: {why}")
    check_run_size(scn, given_options(args, control_rate="--control-rate", duration="--duration",
                                      plant_step="--plant-step"), on_disk=args.engine == "cpp" and scn.sensors is None,
                   out=out)
    claim_out(out)
    from sc_rt.sim import engines

    from sc_rt.scenario.overrides import grid

    engines.STOP.clear()
    from sc_rt.sim.isolated import RunCrashed, simulate_contained

    from sc_rt.isolate import forward_signal

    def on_signal(signum: int) -> None:  # this process's loop stops at its next step; a law's child too
        engines.STOP.set()
        forward_signal(signum)

    with flag_signals(on_signal) as signals:  # before the start line: a signal after it stops the run, partial
        print(f"sc-rt sim: {scn.name}: {args.engine} engine, {grid(scn).n_ctrl + 1} rows ...", file=sys.stderr,
              flush=True)
        try:  # a plugin's or a Python law's run is in a child: its end is one line, not exit 139 or 0
            res = simulate_contained(scn, engine=args.engine, record_dir=out)
        except RunCrashed as e:
            print(f"sc-rt sim: {'STOPPED' if signals else 'FAILED'}: {e}", file=sys.stderr)
            return 128 + signals[0] if signals else 1
    stopped = None
    if signals:  # a signal: the rows done so far (the python engine stops at its next step)
        stopped = f"interrupted by {signal.Signals(signals[0]).name}"
        if len(res) < grid(scn).n_ctrl + 1:
            mark_partial(res, stopped)
    files = write_run(res, out, figures=not args.no_plots)
    print(f"sc-rt sim: {scn.name} -> {out}/ ({len(files)} files: {', '.join(p.name for p in files)})")
    print_metrics(res.metrics, res.meta.faults)
    html_report(out, "sim")
    if res.diverged:
        print(f"sc-rt sim: DIVERGED: {res.message}", file=sys.stderr)
    if stopped:
        return report_stopped(res, stopped, signals[0], out, "sim")
    return strict_exit(gate_problems(res.metrics), invalid_exit(res.metrics, "sim"), "sim", args.strict)


def cmd_hil(args: argparse.Namespace) -> int:
    from sc_rt.hil.runner import run_hil
    from sc_rt.cli.floor_cmd import cmd_floor, timing_setup

    if args.mode is None:
        args.mode = "realtime" if args.self_test else "lockstep"
    if args.self_test:  # the bench floor only (sc-rt floor), a short run
        args.duration, args.rtt_count, args.json, args.no_cache = args.duration or 2.0, 2000, False, False
        return cmd_floor(args)

    from sc_rt.scenario.overrides import with_overrides

    out = checked_out(args.out)
    pylaw = external_choice(args)  # a Python law, --external or --external-wait (checked here)
    scn = with_overrides(scenario_arg(args.scenario, args), law=None if pylaw else args.law,
                         control_rate_hz=args.control_rate, duration=args.duration)
    sizes = dict(control_rate="--control-rate", duration="--duration")
    if args.mode == "realtime":
        sizes["time_scale"] = "--time-scale"
    check_run_size(scn, given_options(args, **sizes), bus=True, realtime=args.mode == "realtime",
                   time_scale=args.time_scale, out=out)
    url = resolve_url(args.lcm_url, None)
    live = getattr(args, "live", None)  # --live [PORT]: sc-rt live beside the run (sc_rt/hil/livechild.py)
    if live is not None and url is None:
        from sc_rt.wire.lcmio import free_port_url

        url = free_port_url(ttl=0)  # the run's URL, known to the live server before the run starts
    mcap = getattr(args, "mcap", None)
    mcap = str(Path(args.out) / "run.mcap") if mcap == "" else mcap
    if mcap_problem(mcap, "hil"):
        return 2
    claim_out(out)
    from sc_rt.hil.livechild import beside_run

    with beside_run(live, url, args.prefix, args.auth_key):
        res = run_hil(scn, out=out, mode=args.mode, lcm_url=url,
                      prefix=args.prefix, realtime_priority=args.realtime_priority,
                      time_scale=args.time_scale, accept_fault_commands=args.accept_fault_commands,
                      plots=not args.no_plots, law=pylaw, external=args.external,
                      external_wait=args.external_wait, start_timeout=args.start_timeout,
                      auth_key=args.auth_key, setup=timing_setup(args),
                      floor=None if args.floor == "off" or args.mode != "realtime" else args.floor,
                      rt_limits=args.rt_limits, controller_memory_limit_mb=args.controller_memory_limit)
    print(f"sc-rt hil: {scn.name} ({args.mode}) -> {res.out}/ ({len(res.files)} files: "
          f"{', '.join(p.name for p in res.files)}, run.lcmlog)")
    print_metrics(res.metrics, res.run.meta.faults)
    t = rounded(res.timing)
    lat = t["state_to_cmd_latency_us"]
    print(f"  state-to-command latency [us]  p50 {lat['p50']}  p99 {lat['p99']}  max {lat['max']}")
    print(f"  steps/s {t['steps_per_s'] or 0:.0f}  deadline misses {t['deadline_misses']}  "
          f"stale states {t['stale_states']}  dropped {t['dropped']}  malformed {t['malformed']}  "
          f"scheduler {t['scheduler']}")
    if t.get("over_floor"):
        print(f"  {t['over_floor']['line']}")
    html_report(Path(res.out), "hil")  # a run stopped early too: its report says so at the top
    if res.stopped:
        return report_stopped(res.run, res.stopped, res.signum, res.out, "hil")
    if mcap and (rc := write_mcap(Path(res.out) / "run.lcmlog", mcap, who="hil")):
        return rc
    return strict_exit(gate_problems(res.metrics), invalid_exit(res.metrics, "hil"), "hil", args.strict)


#: The demo's two runs: the paper's law on the paper's fault scenario, and
#: the design that holds on the same plant and faults (docs/REPRODUCTION.md).
DEMO_RUNS = (("paper DSC+PPC", "paper_faults", "paper"),
             ("feasible 10 Hz design", "ppc_feasible_10hz", "feasible_10hz"))


def cmd_demo(args: argparse.Namespace) -> int:
    """The main job: the paper's law and the feasible design, each through
    the real LCM loop (controller process, emulator, lcm-logger)."""
    from sc_rt.hil.runner import run_hil
    from sc_rt.results.judge.verdict import verdict_line

    out = checked_out(args.out)
    claim_out(out)
    results = []
    for label, name, sub in DEMO_RUNS:
        scn = scenario_arg(name)
        print(f"sc-rt demo: {label} ({scn.name}) through LCM, lockstep ...", file=sys.stderr, flush=True)
        res = run_hil(scn, out=out / sub, mode="lockstep", lcm_url=resolve_url(args.lcm_url, None))
        if res.stopped:  # interrupted (or the logger died): no further run
            return report_stopped(res.run, res.stopped, res.signum, res.out, "demo")
        results.append((label, res))
    for label, res in results:
        print(verdict_line(res.metrics, label))
    for _label, res in results:
        html_report(Path(res.out), "demo")
    print("\nWhy the paper's law leaves its bound in a sampled loop, and how the feasible design "
          "was found: docs/REPRODUCTION.md")
    for label, res in results:
        print(f"\n{label}: {len(res.files)} files in {res.out.resolve()}/")
        for p in res.files:
            print(f"  {p}")
    return 0


def cmd_emulator(args: argparse.Namespace) -> int:
    from sc_rt.wire.auth import load_key
    from sc_rt.emulator.process import Emulator, Options
    from sc_rt.wire.lcmio import DEFAULT_URL

    from sc_rt.scenario.overrides import with_overrides

    if args.out:
        checked_out(args.out)
    scn = with_overrides(scenario_arg(args.scenario), control_rate_hz=args.rate, duration=args.duration)
    check_run_size(scn, given_options(args, rate="--rate", duration="--duration", time_scale="--time-scale"),
                   bus=True, realtime=args.mode == "realtime", time_scale=args.time_scale,
                   out=Path(args.out) if args.out else None)
    url = resolve_url(args.lcm_url, DEFAULT_URL)
    if args.out:
        claim_out(Path(args.out))
    sig: list[int] = []
    with flag_signals(sig.append):  # from here the run stops at its next step, its rows kept
        emu = Emulator(scn, Options(mode=args.mode, url=url, prefix=args.prefix, time_scale=args.time_scale,
                                    accept_fault_commands=args.accept_fault_commands,
                                    start_timeout=args.start_timeout, auth_key=load_key(args.auth_key),
                                    record_dir=Path(args.out) if args.out else None),
                       stop=lambda: f"interrupted by {signal.Signals(sig[0]).name}" if sig else None)
        print(f"sc-rt emulator: LCM URL {url}", file=sys.stderr, flush=True)
        res = emu.run()
    summary = {"rows": len(res), "counters": dict(res.counters), "gaps_s": rounded(res.gaps),
               "diverged": res.diverged, "partial": res.partial,
               "t_reached_s": emu.t_reached if len(res) else None}
    if args.out:
        from sc_rt.results.judge.metrics import fill_tracking_errors, finish_run
        from sc_rt.results.present.output import write_run

        out = Path(args.out)
        guidance = scn.core_config().guidance
        fill_tracking_errors(res, guidance)  # rows without a status: from the plant side
        write_run(finish_run(res, guidance), out, figures=False)
        (out / "emulator.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(rounded(summary)))
    if sig:
        return report_stopped(res, res.message or "interrupted", sig[0], args.out or "-", "emulator")
    if emu.invalid:  # another bench on our channels (emulator/collision.py): partial, invalid
        return report_stopped(res, emu.invalid, None, args.out or "-", "emulator")
    return 0
