"""The console text of a campaign's requirement statistics
(``sc_rt.studies.campaign.requirements.campaign_requirements``): one line
per requirement with its verdict at the confidence, one more with its
numbers. Formatting only; the statistics are the campaign's."""

from __future__ import annotations

from typing import Any

__all__ = ["requirement_lines"]


def _g(v: Any) -> str:
    return "-" if v is None else f"{v:.4g}"


def requirement_lines(reqs: list[dict[str, Any]], confidence: float, coverage: float) -> list[str]:
    """The console lines of ``campaign_requirements``: one line per
    requirement (its verdict at the confidence), one more with its numbers."""
    c = f"{100 * confidence:g} %"
    out = [f"requirements across the runs ({c} confidence; a per-run requirement must hold in "
           f">= {coverage:g} of the runs):"]
    w = max([len(r["name"]) for r in reqs] + [11])
    for r in reqs:
        unit = "" if r.get("unit") in (None, "-") else f" {r['unit']}"
        met = r.get("met_at_confidence")
        verdict = ("MET" if met else "NOT DEMONSTRATED") + f" at {c}" if met is not None else r["statistic"].upper()
        what = f"{r['kind']} {r.get('axis') or ''} p{r['confidence']:g} {r['interpretation']}" \
            if r.get("confidence") else r["kind"]
        out.append(f"  {r['name']:<{w}}  {what.replace('  ', ' ')}, bound {_g(r['bound'])}{unit}: {verdict}")
        out.append("    " + _detail(r, unit, c))
    return out


def _detail(r: dict[str, Any], unit: str, c: str) -> str:
    s = r["statistic"]
    if s == "not applicable" or "why" in r:
        return r.get("why", "")
    if s == "mixed":
        text = (f"the fraction of the span within the bound, mean over {r['runs']} runs {r['mean_within']:.5g} "
                f"({r['runs_never_outside']} runs never outside): at least {r['lower_bound']:.4g} with {c} "
                f"confidence (required {r['required']:g}); p{r['confidence']:g} of every run's values pooled "
                f"{_g(r['pooled_quantile'])}{unit}")
    else:
        f = r if s == "runs" else r["worst"]
        lo, hi = f["interval"]
        where = ("" if s == "runs" else
                 f"{r['bins']} time bins of {r['bin_s']:g} s, the worst at {r['worst_t_s']:g} s: ")
        text = (f"{where}{f['runs_met']}/{f['runs']} runs {'met it' if s == 'runs' else 'within'}: fraction "
                f"{f['fraction']:.4g} ({c} CI {lo:.4g}-{hi:.4g}), at least {f['lower_bound']:.4g} with {c} "
                f"confidence (required {r['required']:g})")
        if s == "ensemble":
            text += (f"; p{r['confidence']:g} across runs up to {_g(r['quantile_max'])}{unit}, "
                     + (f"its {c} upper bound up to {_g(r['upper_bound_max'])}{unit}" if r["upper_bound_max"]
                        is not None else f"too few runs for its {c} upper bound"))
        elif r.get("across_runs"):
            a = r["across_runs"]
            text += f"; p{a['p']:g} of the values across runs {_g(a['value'])}{unit} " + (
                f"({c} upper bound {_g(a['upper_bound'])}{unit})" if a["upper_bound"] is not None
                else f"(too few runs for its {c} upper bound)")
    if not r.get("met_at_confidence"):
        none = "none ever outside the bound" if s == "mixed" else "no failure"
        need = r["runs_needed_without_failure"]
        text += (f"; {need} runs needed with {none}" if need is not None
                 else f"; no finite number of runs shows a fraction of {r['required']:g}")
        if s == "mixed" and r["mean_within"] < r["required"]:
            text += "; the fraction seen is below the required one"
        elif "runs_needed_with_these_failures" in r:
            more = r["runs_needed_with_these_failures"]
            text += (f", {more} with these failures and no more" if more is not None
                     else "; the fraction seen is below the required one (more runs show it only if "
                          "they raise it)")
    return text
