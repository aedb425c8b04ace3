"""``sc-rt compare SCENARIO --law a --law b ...``: the laws on one scenario,
side by side (docs/LAWS.md): verdict, bound violations, settling, peak wheel
acceleration, SAFE and law-invalid steps; then, when the scenario states
requirements, the laws ranked by margin on each one (docs/REQUIREMENTS.md).
Markdown tables on stdout, and with --out in ``compare.json`` and a markdown file."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.cli.lawarg import LAW_HELP, law_choice
from sc_rt.cli.validate import check_run_size, given_options, number, out_dir

__all__ = ["add_parser", "cmd_compare", "compare_row", "overall", "rank_requirements", "ranking_table",
           "settling_time", "COLUMNS"]

#: (key, header, format) of the table's columns.
COLUMNS = (
    ("law", "law", "{}"),
    ("bound_held", "bound held", "{}"),
    ("first_bound_violation_s", "first violation [s]", "{:.1f}"),
    ("bound_violation_fraction", "rows outside bound", "{:.3f}"),
    ("settling_s", "settling [s]", "{:.1f}"),
    ("final_pointing_arcsec", "final error [arcsec]", "{:.3g}"),
    ("max_abs_wheel_accel", "peak wheel accel [rad/s^2]", "{:.3g}"),
    ("safe_steps", "SAFE steps", "{}"),
    ("law_invalid_steps", "law invalid", "{}"),
    ("valid", "valid run", "{}"),
)


def settling_time(t: np.ndarray, sigma_BD: np.ndarray, frac: float) -> float | None:
    """[s] the first time after which the pointing error stays within ``frac``
    of its initial value (None if it does not settle by the end)."""
    from sc_rt.results.verdict import pointing_arcsec

    e = pointing_arcsec(sigma_BD)
    if not len(e) or not np.all(np.isfinite(e)):
        return None
    out = np.flatnonzero(e > frac * e[0])
    if not len(out):
        return float(t[0])
    k = int(out[-1]) + 1
    return float(t[k]) if k < len(t) else None


#: What a row keeps of each requirement's result.
REQUIREMENT_KEYS = ("name", "kind", "axis", "interpretation", "confidence", "value", "bound", "unit", "margin",
                    "relative_margin", "passed", "status")


def compare_row(run, label: str, settle_frac: float = 0.02) -> dict[str, Any]:
    from sc_rt.results.verdict import pointing_arcsec, requirements_summary

    m = run.metrics
    ok = np.all(run["bound_ok"], axis=1)
    return {
        "law": label,
        "bound_held": bool(np.all(ok)),
        "first_bound_violation_s": m.get("first_bound_violation_s"),
        "bound_violation_fraction": float(np.mean(~ok)) if len(ok) else None,
        "settling_s": settling_time(run["t"], run["sigma_BD"], settle_frac),
        "final_pointing_arcsec": float(pointing_arcsec(run["sigma_BD"][-1:])[0]) if len(ok) else None,
        "max_abs_wheel_accel": m.get("max_abs_wheel_accel"),
        "safe_steps": m.get("safe_steps"),
        "law_invalid_steps": m.get("law_invalid_steps"),
        "diverged": bool(m.get("diverged", False)),
        "valid": m.get("valid", True) is not False,
        "invalid_reason": m.get("invalid_reason"),
        "verdict": None if m.get("requirements") is None else requirements_summary(m["requirements"]),
        "requirements": [{k: r.get(k) for k in REQUIREMENT_KEYS} for r in m.get("requirements") or []],
    }


def _rank_key(r: dict[str, Any]) -> tuple[int, float]:
    """Best first: a larger margin relative to the bound; a failure without a
    value (never settled) after every value; not evaluated last."""
    if r.get("passed") is None:
        return (2, 0.0)
    m = r.get("relative_margin")
    return (1, 0.0) if m is None else (0, -float(m))


def rank_requirements(rows: list[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """Per requirement (in the scenario's order), the laws' results ranked by
    their margin relative to the bound, best first (``rank`` 1, 2, ...;
    None: not evaluated or not applicable for that law); a law whose run
    failed (a crash) has no result and is left out."""
    out: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        for r in row.get("requirements") or []:
            if r.get("interpretation") not in ("ensemble", "mixed"):  # across runs: sc-rt montecarlo
                out.setdefault(r["name"], []).append({"law": row["law"], **r})
    for entries in out.values():
        entries.sort(key=_rank_key)
        for i, e in enumerate(entries):
            e["rank"] = i + 1 if e.get("passed") is not None else None
    return out


def _num(v: Any, unit: str | None) -> str:
    if v is None:
        return "-"
    return f"{v:.4g}" + ("" if unit in (None, "-") else f" {unit}")


def ranking_table(ranked: dict[str, list[dict[str, Any]]]) -> str:
    """The ranking as a markdown table: requirement, rank, law, value, bound,
    margin (and relative to the bound), result."""
    head = "| requirement | rank | law | value | bound | margin | result |\n|---|---|---|---|---|---|---|"
    body = []
    for name, entries in ranked.items():
        for i, e in enumerate(entries):
            unit = e.get("unit")
            rel = e.get("relative_margin")
            margin = "-" if e.get("margin") is None else (
                f"{e['margin']:+.4g}" + ("" if unit in (None, "-") else f" {unit}")
                + ("" if rel is None or unit == "-" else f" ({100 * rel:+.3g} %)"))
            result = e["status"].upper() if e.get("status") in ("pass", "fail") else (e.get("status") or "-")
            body.append(f"| {name if i == 0 else ''} | {e['rank'] or '-'} | {e['law']} | {_num(e.get('value'), unit)} "
                        f"| {_num(e.get('bound'), unit)} | {margin} | {result} |")
    return "\n".join([head, *body])


def overall(rows: list[dict[str, Any]]) -> list[tuple[str, dict[str, Any] | None]]:
    """The laws ordered by their worst requirement (the smallest margin
    relative to its bound, as the verdict line): (law, that requirement)."""
    from sc_rt.results.requirements import worst

    judged = [(row["law"], worst(row.get("requirements") or [])) for row in rows if row.get("requirements")]
    return sorted(judged, key=lambda x: (2, 0.0) if x[1] is None else _rank_key(x[1]))


def _overall_line(rows: list[dict[str, Any]]) -> str:
    parts = []
    for i, (law, w) in enumerate(overall(rows)):
        if w is None:
            parts.append(f"{i + 1}. {law} (none evaluated)")
        elif w.get("relative_margin") is None:
            parts.append(f"{i + 1}. {law} ({w['name']} {w['status']})")
        else:
            parts.append(f"{i + 1}. {law} ({w['name']} {100 * w['relative_margin']:+.3g} %)")
    return "Overall, by each law's worst margin relative to its bound: " + ", ".join(parts)


def _cell(v: Any, fmt: str) -> str:
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    return fmt.format(v)


def table(rows: list[dict[str, Any]]) -> str:
    head = "| " + " | ".join(h for _, h, _ in COLUMNS) + " |"
    sep = "|" + "|".join("---" for _ in COLUMNS) + "|"
    body = ["| " + " | ".join(_cell(r.get(k), f) for k, _, f in COLUMNS) + " |" for r in rows]
    return "\n".join([head, sep, *body])


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
    c.add_argument("--out", metavar="DIR", type=out_dir, help="also write DIR/compare.json and DIR/compare.md")
    c.set_defaults(func=cmd_compare)


def cmd_compare(args: argparse.Namespace) -> int:
    from sc_rt.cli.common import scenario_arg
    from sc_rt.scenario.model import law_identity
    from sc_rt.scenario.overrides import with_overrides

    if args.duration is not None and not args.duration > 0:
        print(f"sc-rt compare: --duration {args.duration:g}: must be > 0", file=sys.stderr)
        return 2
    if not 0 < args.settle < 1:
        print(f"sc-rt compare: --settle {args.settle:g}: must be in (0, 1)", file=sys.stderr)
        return 2
    scn = scenario_arg(args.scenario)
    check_run_size(with_overrides(scn, duration=args.duration), given_options(args, duration="--duration"))
    # every law checked (a plugin or a Python law constructed with its table) before any run
    scns = {law: with_overrides(scn, law=law, duration=args.duration) for law in args.laws}
    from sc_rt.sim.isolated import RunCrashed, simulate_contained

    rows = []
    failed = 0
    for law in args.laws:
        # its label: a plugin's or a Python law's name (which also names its table, [laws.NAME])
        label = law_identity(scns[law].run.controller)["name"]
        run_scn, kw = scns[law], dict(engine=args.engine)
        try:  # a plugin runs in a child of its own: its crash fails its row, not the comparison
            run = simulate_contained(run_scn, **kw)
        except RunCrashed as e:
            rows.append({"law": label, "valid": False, "invalid_reason": str(e), "crashed": True})
            failed += 1
            print(f"sc-rt compare: {scn.name}: {label} FAILED: {e}", file=sys.stderr, flush=True)
            continue
        row = compare_row(run, label, args.settle)
        rows.append(row)
        if not row["valid"]:
            failed += 1
            print(f"sc-rt compare: {scn.name}: {label} INVALID: {row['invalid_reason']}", file=sys.stderr, flush=True)
        else:
            print(f"sc-rt compare: {scn.name}: {label} done", file=sys.stderr, flush=True)
    text = table(rows)
    print(f"{scn.name} ({args.engine} engine, settling within {args.settle:g} of the initial error)\n")
    print(text)
    ranked = rank_requirements(rows)
    if ranked:
        text += ("\n\nThe laws ranked by margin on each requirement (relative to its bound, best first):\n\n"
                 + ranking_table(ranked) + "\n\n" + _overall_line(rows))
        across = [r.name for r in scn.requirements if r.interpretation in ("ensemble", "mixed")]
        if across:
            text += f"\n(judged across runs only, by sc-rt montecarlo: {', '.join(across)})"
        print(text[text.index("\n\nThe laws ranked"):])
    if args.out:
        from sc_rt.results.run import json_safe

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        doc = {"scenario": scn.name, "rows": rows,
               "ranking": {name: [e["law"] for e in entries if e["rank"] is not None]
                           for name, entries in ranked.items()},
               "overall": [law for law, _ in overall(rows)]}
        (out / "compare.json").write_text(json.dumps(json_safe(doc), indent=2) + "\n")
        (out / "compare.md").write_text(text + "\n")
    return 1 if failed else 0
