"""The command line's arguments -> the run's plan (sc_rt.plan): the one
place where ``sc-rt sim`` and ``sc-rt hil`` read their run's options and
the law spec is parsed; everything below takes the plan."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sc_rt.cli.common import checked_out, scenario_arg
from sc_rt.cli.controller import external_choice
from sc_rt.cli.validate import UsageError, resolve_url
from sc_rt.plan.law import ExternalLaw, PythonLaw
from sc_rt.plan.run import Bus, Outputs, PlanConflict, RunPlan, plan_from_inputs, plan_run
from sc_rt.plan.timing import RealtimeLimits, Timing, TimingSetup
from sc_rt.scenario.schema import ScenarioError

__all__ = ["sim_plan", "hil_plan", "rerun_plan"]


def sim_plan(args: argparse.Namespace) -> RunPlan:
    """``sc-rt sim``'s plan: the scenario, --set, --law, the engine, the
    run's overrides and --out (checked, not yet claimed)."""
    out = checked_out(args.out)
    scn = _scenario(args)
    return _noted(plan_run(scn, law=args.law, engine=args.engine, control_rate_hz=args.control_rate,
                           duration=args.duration, plant_step=args.plant_step,
                           outputs=Outputs(out=out, plots=not args.no_plots)))


def hil_plan(args: argparse.Namespace) -> RunPlan:
    """``sc-rt hil``'s plan: the scenario, --set, --law or the external
    controller, the mode and the timing set-up, the outputs (--out, the
    figures, --mcap), the bus (--lcm-url, --prefix, --auth-key, fault
    commands) and the live view (--live: the run's URL is fixed here, so
    that the live server knows it before the run starts)."""
    out = checked_out(args.out)
    external_choice(args)  # --external's command (checked here)
    url = resolve_url(args.lcm_url, None)
    live = getattr(args, "live", None)
    if live is not None and url is None:
        from sc_rt.wire.lcmio import free_port_url

        url = free_port_url(ttl=0)
    mcap = getattr(args, "mcap", None)
    mcap = Path(args.out) / "run.mcap" if mcap == "" else (Path(mcap) if mcap else None)
    timing = Timing(mode=args.mode, time_scale=args.time_scale, realtime_priority=args.realtime_priority,
                    setup=TimingSetup(trigger=args.trigger, controller_cpu=args.controller_cpu,
                                      emulator_cpu=args.emulator_cpu, spin_us=args.spin_us),
                    floor=None if args.floor == "off" or args.mode != "realtime" else args.floor,
                    rt_limits=args.rt_limits or RealtimeLimits(), start_timeout=args.start_timeout,
                    controller_memory_limit_mb=args.controller_memory_limit)
    scn = _scenario(args)
    try:
        plan = plan_run(scn, law=args.law, engine="bench", control_rate_hz=args.control_rate,
                        duration=args.duration, external=args.external, external_wait=args.external_wait,
                        timing=timing, outputs=Outputs(out=out, plots=not args.no_plots, mcap=mcap),
                        bus=Bus(lcm_url=url, prefix=args.prefix, accept_fault_commands=args.accept_fault_commands,
                                auth_key=Path(args.auth_key) if args.auth_key else None, live=live))
    except PlanConflict as e:
        raise UsageError(f"--{e}") from None
    if args.start_timeout is not None and not isinstance(plan.law, (PythonLaw, ExternalLaw)):
        raise UsageError("--start-timeout applies to --external, --external-wait or a Python --law only")
    return _noted(plan)


def _scenario(args: argparse.Namespace):
    """The command's scenario, read (with --set); the file's own law probed
    here only when --law replaces it (a file naming a broken law is refused
    all the same), else by the plan."""
    return scenario_arg(args.scenario, args, strays=False, probe=args.law is not None)


def _noted(plan: RunPlan) -> RunPlan:
    """The plan, its notes said on stderr (one line each)."""
    for note in plan.notes:
        print(f"sc-rt: note: {note}", file=sys.stderr)
    return plan


def rerun_plan(args: argparse.Namespace) -> RunPlan:
    """``sc-rt rerun DIR``'s plan: the one the run in DIR recorded
    (``RunMeta.inputs``, sc_rt.plan.run.plan_from_inputs), its outputs to
    --out. A run that recorded no plan, or whose scenario or Python law file
    changed since, is refused (UsageError: exit 2, one line)."""
    from sc_rt.results.record.run import Run

    out = checked_out(args.out)
    try:
        inputs = Run.load(args.run_dir).meta.inputs
    except (OSError, ValueError, KeyError) as e:
        raise UsageError(f"{args.run_dir}: no run to replay ({e})") from None
    try:
        return _noted(plan_from_inputs(inputs, out=out))
    except ScenarioError:
        raise
    except ValueError as e:
        raise UsageError(f"{args.run_dir}: {e}") from None
