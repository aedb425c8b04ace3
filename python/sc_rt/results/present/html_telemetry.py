"""The law's telemetry section of report.html: each named value of the
summary sc_rt.results.judge.law_telemetry made (unit, final, min, max) and
the fixed slots the law filled."""

from __future__ import annotations

from html import escape
from typing import Any

from sc_rt.pylaw import split_unit

__all__ = ["telemetry_table"]


def telemetry_table(summary: dict[str, Any] | None) -> str:
    """The HTML section of report.html: each named value (unit, final, min,
    max) and the fixed slots the law filled; a line saying so when none."""
    if not summary or (not summary.get("names") and not summary.get("fixed_slots_used")):
        return "<p>The law reports no telemetry of its own (no named values, no x2d or rho_hat).</p>"
    rows = []
    for name, s in (summary.get("values") or {}).items():
        base, unit = split_unit(name)
        cells = "".join(f"<td class=num>{'-' if s.get(k) is None else f'{s[k]:.6g}'}</td>"
                        for k in ("final", "min", "max"))
        rows.append(f"<tr><td>{escape(base)}</td><td>{escape(unit or '-')}</td>{cells}</tr>")
    html = ("<table id=law-telemetry><tr><th>named value</th><th>unit</th><th>final</th><th>min</th><th>max</th></tr>"
            + "".join(rows) + "</table>") if rows else "<p>No named values.</p>"
    slots = summary.get("fixed_slots_used") or []
    if slots:
        html += f"<p>Fixed slots the law filled: {escape(', '.join(slots))} (in trajectory and law_telemetry.png).</p>"
    return html
