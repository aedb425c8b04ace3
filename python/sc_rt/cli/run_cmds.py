"""``sc-rt sim``, ``hil``, ``demo``, ``emulator``: the commands that run the loop."""

from __future__ import annotations

import argparse
import json
import signal
import sys
from pathlib import Path

from sc_rt.cli.interrupts import flag_signals
from sc_rt.cli.validate import UsageError, check_run_size, given_options, resolve_url, rounded
from sc_rt.cli.planning import hil_plan, rerun_plan, sim_plan
from sc_rt.cli.common import (checked_out, claim_out, html_report, invalid_exit, mcap_problem,
                              print_metrics, report_stopped, scenario_arg, strict_exit,
                              write_mcap)
from sc_rt.results.judge.gate import gate_problems


def cmd_sim(args: argparse.Namespace) -> int:
    # any law, a Python one too (sc_rt.pylaw: it runs inside the core's controller, on every engine)
    plan = sim_plan(args)
    return run_sim(plan, given_options(args, control_rate="--control-rate", duration="--duration",
                                       plant_step="--plant-step"), args.strict)


def cmd_rerun(args: argparse.Namespace) -> int:
    """``sc-rt rerun DIR``: the plan a run recorded, run again (sim or hil)."""
    plan = rerun_plan(args)
    print(f"sc-rt rerun: {args.run_dir}: {plan.scenario.name}, law {plan.law.name}, "
          f"{plan.engine if plan.engine != 'bench' else plan.mode} -> {plan.outputs.out}/", file=sys.stderr)
    if plan.engine == "bench":
        return run_bench(plan, "the recorded run", args.strict)
    return run_sim(plan, "the recorded run", args.strict)


def run_sim(plan, given: str, strict: bool) -> int:
    """An offline run of ``plan``, written to its directory, its summary
    printed; the exit code (``strict``: the gate's)."""
    from sc_rt.results.judge.metrics import mark_partial
    from sc_rt.results.present.output import write_run

    scn, out = plan.scenario, plan.outputs.out
    if plan.engine == "unsampled":
        from sc_rt.sim.unsampled import refusal

        if (why := refusal(plan.law.spec)) is not None:
            raise UsageError(f"--engine unsampled: {why}")
    check_run_size(scn, given, on_disk=plan.engine == "cpp" and scn.sensors is None, out=out)
    claim_out(out)
    from sc_rt.sim import engines

    from sc_rt.scenario.overrides import grid

    engines.STOP.clear()
    from sc_rt.sim.isolated import RunCrashed, simulate_plan

    from sc_rt.isolate import forward_signal

    def on_signal(signum: int) -> None:  # this process's loop stops at its next step; a law's child too
        engines.STOP.set()
        forward_signal(signum)

    with flag_signals(on_signal) as signals:  # before the start line: a signal after it stops the run, partial
        print(f"sc-rt sim: {scn.name}: {plan.engine} engine, {grid(scn).n_ctrl + 1} rows ...", file=sys.stderr,
              flush=True)
        try:  # a plugin's or a Python law's run is in a child: its end is one line, not exit 139 or 0
            res = simulate_plan(plan)
        except RunCrashed as e:
            print(f"sc-rt sim: {'STOPPED' if signals else 'FAILED'}: {e}", file=sys.stderr)
            return 128 + signals[0] if signals else 1
    stopped = None
    if signals:  # a signal: the rows done so far (the python engine stops at its next step)
        stopped = f"interrupted by {signal.Signals(signals[0]).name}"
        if len(res) < grid(scn).n_ctrl + 1:
            mark_partial(res, stopped)
    files = write_run(res, out, figures=plan.outputs.plots)
    print(f"sc-rt sim: {scn.name} -> {out}/ ({len(files)} files: {', '.join(p.name for p in files)})")
    print_metrics(res.metrics, res.meta.faults)
    html_report(out, "sim")
    if res.diverged:
        print(f"sc-rt sim: DIVERGED: {res.message}", file=sys.stderr)
    if stopped:
        return report_stopped(res, stopped, signals[0], out, "sim")
    return strict_exit(gate_problems(res.metrics), invalid_exit(res.metrics, "sim"), "sim", strict)


def cmd_hil(args: argparse.Namespace) -> int:
    from sc_rt.cli.floor_cmd import cmd_floor

    if args.mode is None:
        args.mode = "realtime" if args.self_test else "lockstep"
    if args.self_test:  # the bench floor only (sc-rt floor), a short run
        args.duration, args.rtt_count, args.json, args.no_cache = args.duration or 2.0, 2000, False, False
        return cmd_floor(args)

    plan = hil_plan(args)
    sizes = dict(control_rate="--control-rate", duration="--duration")
    if plan.mode == "realtime":
        sizes["time_scale"] = "--time-scale"
    return run_bench(plan, given_options(args, **sizes), args.strict)


def run_bench(plan, given: str, strict: bool) -> int:
    """A bench run of ``plan`` (sc_rt.hil.runner.run_hil), with the live view
    beside it when planned, its summary printed; the exit code."""
    from sc_rt.hil.runner import run_hil

    scn, out = plan.scenario, plan.outputs.out
    check_run_size(scn, given, bus=True, realtime=plan.mode == "realtime", time_scale=plan.timing.time_scale, out=out)
    mcap = plan.outputs.mcap
    if mcap_problem(None if mcap is None else str(mcap), "hil"):
        return 2
    claim_out(out)
    from sc_rt.hil.livechild import beside_run

    with beside_run(plan.bus.live, plan.bus.lcm_url, plan.bus.prefix, plan.bus.auth_key):
        res = run_hil(plan)
    print(f"sc-rt hil: {scn.name} ({plan.mode}) -> {res.out}/ ({len(res.files)} files: "
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
    if mcap and (rc := write_mcap(Path(res.out) / "run.lcmlog", str(mcap), who="hil")):
        return rc
    return strict_exit(gate_problems(res.metrics), invalid_exit(res.metrics, "hil"), "hil", strict)


#: The demo's two runs: the paper's law on the paper's fault scenario, and
#: the design that holds on the same plant and faults (docs/REPRODUCTION.md).
DEMO_RUNS = (("paper DSC+PPC", "paper_faults", "paper"),
             ("feasible 10 Hz design", "ppc_feasible_10hz", "feasible_10hz"))


def cmd_demo(args: argparse.Namespace) -> int:
    """The main job: the paper's law and the feasible design, each through
    the real LCM loop (controller process, emulator, lcm-logger)."""
    from sc_rt.hil.runner import run_hil
    from sc_rt.plan import Bus, Outputs, Timing, plan_run
    from sc_rt.results.judge.verdict import verdict_line

    out = checked_out(args.out)
    claim_out(out)
    results = []
    for label, name, sub in DEMO_RUNS:
        scn = scenario_arg(name, strays=False, probe=False)
        plan = plan_run(scn, engine="bench", timing=Timing(mode="lockstep"),
                        outputs=Outputs(out=out / sub), bus=Bus(lcm_url=resolve_url(args.lcm_url, None)))
        print(f"sc-rt demo: {label} ({plan.scenario.name}) through LCM, lockstep ...", file=sys.stderr, flush=True)
        res = run_hil(plan)
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
    scn = with_overrides(scenario_arg(args.scenario, args), control_rate_hz=args.rate, duration=args.duration)
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
