"""``sc-rt compare SCENARIO --law a --law b ...``: the laws on one scenario,
side by side (docs/LAWS.md): the prescribed bound (where the scenario asks
for the envelope) or the requirements met, settling, peak wheel
acceleration, SAFE and law-invalid steps; then, when the scenario states
requirements, the laws ranked by margin on each one (docs/REQUIREMENTS.md).
Markdown tables on stdout, and with --out in ``compare.json`` and a markdown file."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

from sc_rt.cli.common import add_set, add_strict, strict_exit
from sc_rt.cli.validate import LAW_HELP, check_run_size, given_options, integer, law_choice, number, out_dir

__all__ = ["add_parser", "cmd_compare"]


def add_parser(sub) -> None:
    c = sub.add_parser("compare", help="several laws on one scenario: a table of verdicts and metrics")
    c.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    c.add_argument("--law", dest="laws", action="append", type=law_choice, metavar="LAW", required=True,
                   help=LAW_HELP + "; repeat for each law")
    c.add_argument("--engine", choices=("python", "cpp"), default="cpp",
                   help="offline engine (default cpp; a Python law runs on python)")
    c.add_argument("--duration", type=number(unit="s"), metavar="S", help="[s] default: the scenario's")
    c.add_argument("--settle", type=float, default=0.02, metavar="FRAC",
                   help="settling: the pointing error stays within FRAC of its initial value (default 0.02)")
    c.add_argument("--seeds", type=integer(1, 1000), metavar="N",
                   help="run each law N times, sensor-noise seeds seed..seed+N-1, and rank by the mean margin, "
                        "saying which differences lie within the seeds' spread (default: 5 for a scenario with "
                        "[sensors], 1 without: its runs have no noise)")
    c.add_argument("--out", metavar="DIR", type=out_dir, help="also write DIR/compare.json and DIR/compare.md")
    add_strict(c)  # every law's run through the gate
    add_set(c)
    c.set_defaults(func=cmd_compare)


def cmd_compare(args: argparse.Namespace) -> int:
    from sc_rt.cli.common import scenario_arg
    from sc_rt.plan.run import plan_run
    from sc_rt.scenario.overrides import with_overrides

    if args.duration is not None and not args.duration > 0:
        print(f"sc-rt compare: --duration {args.duration:g}: must be > 0", file=sys.stderr)
        return 2
    if not 0 < args.settle < 1:
        print(f"sc-rt compare: --settle {args.settle:g}: must be in (0, 1)", file=sys.stderr)
        return 2
    scn = scenario_arg(args.scenario, args)
    check_run_size(with_overrides(scn, duration=args.duration), given_options(args, duration="--duration"))
    # every law checked (a plugin or a Python law constructed with its table) before any run
    plans = {law: plan_run(scn, law=law, engine=args.engine, duration=args.duration, strays=False)
             for law in args.laws}
    from sc_rt.results.judge.compare import compare_row, merge_seeds, overall, rank_requirements
    from sc_rt.results.present.tables import overall_line, ranking_table, table
    from sc_rt.sim.isolated import RunCrashed, simulate_plan

    seeds = args.seeds or (5 if scn.sensors is not None else 1)
    if seeds > 1 and scn.sensors is None:
        print(f"sc-rt compare: --seeds {seeds}: {scn.name} has no [sensors]: its runs have no noise, one each",
              file=sys.stderr)
        seeds = 1
    rows = []
    failed = 0
    for law in args.laws:
        # its label: a plugin's or a Python law's name (which also names its table, [laws.NAME])
        plan = plans[law]
        label = plan.law.name
        try:  # a plugin runs in a child of its own: its crash fails its row, not the comparison
            runs = [simulate_plan(dataclasses.replace(plan, scenario=_with_seed(plan.scenario, k)))
                    for k in range(seeds)]
        except RunCrashed as e:
            rows.append({"law": label, "valid": False, "invalid_reason": str(e), "crashed": True})
            failed += 1
            print(f"sc-rt compare: {scn.name}: {label} FAILED: {e}", file=sys.stderr, flush=True)
            continue
        row = merge_seeds([compare_row(run, label, args.settle) for run in runs])
        rows.append(row)
        if not row["valid"]:
            failed += 1
            print(f"sc-rt compare: {scn.name}: {label} INVALID: {row['invalid_reason']}", file=sys.stderr, flush=True)
        else:
            print(f"sc-rt compare: {scn.name}: {label} done", file=sys.stderr, flush=True)
    from sc_rt.results.judge.verdict import asks_envelope

    text = table(rows, envelope=asks_envelope(scn.requirements))  # the bound's columns where it is asked for
    print(f"{scn.name} ({args.engine} engine, settling within {args.settle:g} of the initial error"
          + (f"; each law over {seeds} sensor-noise seeds, its margins their mean" if seeds > 1 else "") + ")\n")
    print(text)
    ranked = rank_requirements(rows)
    if ranked:
        text += ("\n\nThe laws ranked by margin on each requirement (relative to its bound, best first):\n\n"
                 + ranking_table(ranked) + "\n\n" + overall_line(rows))
        across = [r.name for r in scn.requirements if r.interpretation in ("ensemble", "mixed")]
        if across:
            text += f"\n(judged across runs only, by sc-rt montecarlo: {', '.join(across)})"
        print(text[text.index("\n\nThe laws ranked"):])
    expects = _expect_lines(rows)
    if expects:
        text += "\n\n" + "\n".join(expects)
        print("\n" + "\n".join(expects))
    if args.out:
        from sc_rt.results.record.run import json_safe

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        doc = {"scenario": scn.name, "rows": rows,
               "ranking": {name: [e["law"] for e in entries if e["rank"] is not None]
                           for name, entries in ranked.items()},
               "overall": [law for law, _ in overall(rows)],
               # what each law's runs were made from (RunPlan.inputs: the file and its sha256, the law's
               # parameters as run, overrides, sc-rt's version and commit)
               "inputs": {plans[law].law.name: plans[law].inputs() for law in args.laws}}
        (out / "compare.json").write_text(json.dumps(json_safe(doc), indent=2) + "\n")
        (out / "compare.md").write_text(text + "\n")
    return strict_exit(_gate(rows), 1 if failed else 0, "compare", args.strict)


def _with_seed(scn, k: int):
    """``scn`` with its sensors' seed moved on by ``k`` (k = 0: the scenario itself)."""
    if k == 0 or scn.sensors is None:
        return scn
    import dataclasses

    return dataclasses.replace(scn, sensors=dataclasses.replace(scn.sensors, seed=scn.sensors.seed + k))


def _expect_lines(rows: list[dict]) -> list[str]:
    """The file's expect against each law's run ([] when the file states none)."""
    from sc_rt.results.judge.gate import expect_line

    lines = [f"{row['law']}: {line}" for row in rows if (line := expect_line(row.get("expect")))]
    return [f"The file's expect, per law: {lines[0]}", *(f"  {x}" for x in lines[1:])] if lines else []


def _gate(rows: list[dict]) -> list[str]:
    """--strict's problems, law by law: a crashed or invalid run, a failed
    requirement, an expect not matched (sc_rt.results.judge.gate)."""
    from sc_rt.results.judge.gate import gate_problems

    out = []
    for row in rows:
        if row.get("crashed"):
            out.append(f"{row['law']}: the run crashed ({row.get('invalid_reason')})")
            continue
        metrics = {"valid": row.get("valid"), "invalid_reason": row.get("invalid_reason"),
                   "diverged": row.get("diverged"), "requirements": row.get("requirements"),
                   "expect": row.get("expect")}
        out += [f"{row['law']}: {p}" for p in gate_problems(metrics)]
    return out
