"""The tables of ``sc-rt compare`` (markdown): the laws side by side, the
ranking per requirement, the overall line. Formats the judging of
sc_rt.results.judge.compare."""

from __future__ import annotations

from typing import Any

from sc_rt.results.judge.compare import overall

__all__ = ["COLUMNS", "ENVELOPE_COLUMNS", "overall_line", "ranking_table", "table"]

#: (key, header, format) of the table's columns.
COLUMNS = (
    ("law", "law", "{}"),
    ("bound_held", "bound held", "{}"),
    ("first_bound_violation_s", "first violation [s]", "{:.1f}"),
    ("bound_violation_fraction", "rows outside bound", "{:.3f}"),
    ("requirements_met", "requirements met", "{}"),
    ("settling_s", "settling [s]", "{:.1f}"),
    ("final_pointing_arcsec", "final true error [arcsec]", "{:.3g}"),
    ("max_abs_wheel_accel", "peak wheel accel [rad/s^2]", "{:.3g}"),
    ("safe_steps", "SAFE steps", "{}"),
    ("law_invalid_steps", "law invalid", "{}"),
    ("valid", "valid run", "{}"),
)


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
            if "seed_spread" in e:  # several seeds: the margin is their mean; its spread beside it
                margin += f", spread {100 * e['seed_spread']:.3g} %"
            if e.get("within_seed_spread_of_next"):
                result += " (next: within the seed spread)"
            body.append(f"| {name if i == 0 else ''} | {e['rank'] or '-'} | {e['law']} | {_num(e.get('value'), unit)} "
                        f"| {_num(e.get('bound'), unit)} | {margin} | {result} |")
    return "\n".join([head, *body])


def overall_line(rows: list[dict[str, Any]]) -> str:
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


#: The envelope's columns: only where the scenario asks for it (``table``'s ``envelope``).
ENVELOPE_COLUMNS = ("bound_held", "first_bound_violation_s", "bound_violation_fraction")


def table(rows: list[dict[str, Any]], envelope: bool = True) -> str:
    """The laws side by side as a markdown table (COLUMNS): with
    ``envelope`` (the scenario asks for it) the prescribed bound's columns,
    otherwise the requirements met in their place."""
    cols = [c for c in COLUMNS if (envelope if c[0] in ENVELOPE_COLUMNS else
                                   not envelope if c[0] == "requirements_met" else True)]
    head = "| " + " | ".join(h for _, h, _ in cols) + " |"
    sep = "|" + "|".join("---" for _ in cols) + "|"
    body = ["| " + " | ".join(_cell(r.get(k), f) for k, _, f in cols) + " |" for r in rows]
    return "\n".join([head, sep, *body])
