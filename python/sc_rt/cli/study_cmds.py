"""``sc-rt check``, ``scenarios``, ``montecarlo``, ``config``, ``design``,
``reproduce``: the commands about scenarios and designs."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from sc_rt.cli.common import scenario_arg


def cmd_check(args: argparse.Namespace) -> int:
    from sc_rt.cli.validate import check_run_size
    from sc_rt.scenario.model import ScenarioError
    from sc_rt.scenario.reader import load_scenario
    from sc_rt.studies.check import LEVELS, check_scenario, exit_code

    if not args.fast:  # the offline run that bounds ||r|| must fit (file errors: the findings below)
        try:
            scn = load_scenario(args.scenario, args.sets or ())
        except ScenarioError:
            scn = None
        if scn is not None:
            check_run_size(scn, f"{args.scenario}'s run (--fast checks without it)")
    findings = check_scenario(args.scenario, run_estimate=not args.fast, law=args.law, sets=args.sets or ())
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
    scn = scenario_arg(args.scenario, args)
    data = scn.controller_config_msg(args.law, args.control_rate).encode()
    Path(args.out).write_bytes(data)
    print(f"sc-rt config: controller_config_t ({len(data)} bytes) -> {args.out}")
    return 0


def cmd_design(args: argparse.Namespace) -> int:
    """PD design, margins and sampled-data stability (sc_rt.studies.design, docs/DESIGN.md)."""
    from sc_rt.studies.design import DEFAULT_LATENCY_S, design_report, format_design_text, write_design
    from sc_rt.sim.engines import with_overrides

    scn = with_overrides(scenario_arg(args.scenario, args), control_rate_hz=args.rate)  # validates --rate
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
    from sc_rt.cli.validate import check_run_size, given_options
    from sc_rt.scenario.reader import load_scenario
    from sc_rt.scenario.overrides import with_overrides
    from sc_rt.studies.reproduce import reproduce

    # the paper's scenarios at the rate and plant step asked for: each of their runs must fit
    check_run_size(with_overrides(load_scenario("paper_faults"), control_rate_hz=args.control_rate,
                                  plant_step=args.plant_step),
                   given_options(args, control_rate="--control-rate", plant_step="--plant-step"))
    out = Path(args.out)
    doc = reproduce(out, engine=args.engine, control_rate_hz=args.control_rate,
                    plant_step=args.plant_step, plots=not args.no_plots,
                    with_sensitivity=args.sensitivity, with_search=args.search, dpi=args.dpi)
    print(f"sc-rt reproduce: {doc['command']} -> {out}/")
    for c in doc["claims"]:
        print(f"  {c['id']} {c['verdict']:<15} {c['claim']}\n      {c['measured']}")
    return 0
