"""The requirement table that opens ``report.html`` (sc_rt.results.present.html_report;
docs/REQUIREMENTS.md): per requirement its measure, value, bound, margin and
result, coloured, the counterpart index beside it (knowledge beside
performance, with sensors) and how the value was found."""

from __future__ import annotations

from html import escape
from typing import Any

from sc_rt.results.judge.verdict import outside_text

__all__ = ["requirements_table"]


def requirements_table(reqs: list[dict[str, Any]] | None) -> str:
    """The requirement table that opens the report: per requirement its
    measure, value, bound, margin and result (coloured)."""
    if not reqs:
        return ('<section id="requirements"><p>No requirements stated ([[requirements]] in the scenario, '
                "docs/REQUIREMENTS.md): the metrics below, no verdict.</p></section>")

    def num(v: Any) -> str:
        return "-" if v is None else f"{v:.4g}" if isinstance(v, (int, float)) else escape(str(v))

    rows = []
    for r in reqs:
        status = r.get("status") or ("pass" if r.get("passed") else "fail")
        measure = " ".join(str(x) for x in (r.get("kind"), r.get("axis") or "",
                                            f"p{r['confidence']:g}" if r.get("confidence") else "",
                                            r.get("interpretation") or "") if x)
        unit = "" if r.get("unit") in (None, "-") else " " + escape(str(r["unit"]))
        shown = status.upper()
        if r.get("passed") is None and r.get("interpretation") in ("ensemble", "mixed"):
            shown = "ACROSS RUNS (sc-rt montecarlo)"
        outside = outside_text(r)
        cp = r.get("counterpart") or {}
        beside = [f"{escape(cp['kind'])} {num(cp.get('value'))}{unit}"] if cp else []
        if r.get("window_max_bound") is not None:  # RPE, RKE: the window-max statistic, a bound on the index
            beside.append(f"window-max bound {num(r['window_max_bound'])}{unit}")
        beside = "; ".join(beside) or "-"
        rows.append(f'<tr class="{escape(status.replace(" ", "-"))}"><td>{escape(str(r.get("name")))}</td>'
                    f"<td>{escape(measure)}</td><td class=num>{num(r.get('value'))}{unit}</td>"
                    f"<td class=num>{num(r.get('bound'))}{unit}</td><td class=num>{num(r.get('margin'))}{unit}</td>"
                    f"<td class=num>{escape(outside)}</td><td>{escape(shown)}</td><td class=num>{beside}</td>"
                    f"<td>{escape(str(r.get('note') or ''))}</td></tr>")
    return ('<section id="requirements"><table id="requirements-table"><tr><th>requirement</th><th>measure</th>'
            "<th>value</th><th>bound</th><th>margin</th>"
            '<th title="the first and last time its values were outside the bound">outside bound</th>'
            "<th>result</th>"
            '<th title="with sensors: the knowledge index beside a performance one, and back; RPE, RKE: the '
            'window-max bound">beside it</th>'
            "<th>how</th></tr>"
            + "".join(rows) + "</table></section>")
