"""A campaign's requirements: what the runs say together (docs/REQUIREMENTS.md,
section 4).

Each run's dataset row holds, per requirement, its result (columns
``req.NAME.passed``, ``.status``, ``.value``) and for the ensemble and mixed
ones its binned series (``.bins``, ``.within``: sc_rt.results.judge.ensemble).
From them, per requirement:

- every kind: the runs meeting it, the fraction with its two-sided
  Clopper-Pearson interval and the one-sided lower bound at the campaign's
  ``confidence``; a run with no result (invalid draw, crash, a span that
  never began) counts as not meeting it. A per-run requirement (temporal,
  settling, margins, envelope) is *met at the confidence* when that lower
  bound reaches ``coverage``, the fraction of runs it must hold in; the
  value across runs at ``coverage`` (nearest rank) is given with its
  distribution-free upper confidence bound (an order statistic);
- ensemble: per time bin, the runs within the bound, the p-quantile across
  runs with its upper confidence bound and the lower bound of the fraction
  within; met at the confidence when that bound reaches the requirement's
  own probability p in every bin (equivalently: the upper bound of the
  quantile is within the bound everywhere);
- mixed: the mean over runs of the fraction of time within the bound, its
  lower bound (the larger of Hoeffding's and the Clopper-Pearson bound of
  the runs that never left the bound, each at half the risk), and the
  p-quantile of every run's bins pooled;
- whenever it is not met at the confidence: the runs a zero-failure
  campaign needs (p^n <= 1 - confidence), and with the failures seen, the
  runs that would do if no more failed.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sc_rt.results.judge.ensemble import bin_width
from sc_rt.results.judge.pointing import nearest_rank
from sc_rt.studies.campaign.stats import (clopper_pearson, clopper_pearson_lower, hoeffding_lower,
                                          quantile_upper_rank, runs_needed)

__all__ = ["campaign_requirements", "row_columns"]


def row_columns(results: list[dict[str, Any]], series: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """A run's dataset columns for its requirements: ``results`` its
    ``metrics["requirements"]``, ``series`` sc_rt.results.judge.ensemble.campaign_series."""
    row: dict[str, Any] = {}
    for r in results:
        key = f"req.{r['name']}"
        row.update({f"{key}.passed": r.get("passed"), f"{key}.status": r.get("status"),
                    f"{key}.value": None if r.get("value") is None else float(r["value"])})
    for name, s in series.items():
        row.update({f"req.{name}.bins": s["bins"], f"req.{name}.within": s["within"]})
    judged = [r["passed"] for r in results if r.get("passed") is not None]
    row["meets_requirements"] = all(judged) if judged else None
    return row


def _fraction(k: int, n: int, confidence: float) -> dict[str, Any]:
    lo, hi = clopper_pearson(k, n, confidence)
    return {"runs_met": k, "runs": n, "fraction": k / n, "interval": [lo, hi],
            "lower_bound": clopper_pearson_lower(k, n, confidence)}


def _needs(p: float, confidence: float, k: int, n: int, lower: float) -> dict[str, Any]:
    """Whether ``lower`` reaches p, and the runs a campaign would need."""
    failures = n - k
    out: dict[str, Any] = {"required": p, "met_at_confidence": lower >= p,
                           "runs_needed_without_failure": runs_needed(p, confidence)}
    if failures and k / n >= p:
        out["runs_needed_with_these_failures"] = runs_needed(p, confidence, failures)
    elif failures:
        # the fraction seen is below p: more runs show it only if they bring it above p
        out["runs_needed_with_these_failures"] = None
    return out


def _values_across(values: list[float | None], q: float, confidence: float) -> dict[str, Any] | None:
    """The per-run values' q-quantile across runs and its upper confidence bound."""
    v = np.sort(np.array([np.inf if x is None else x for x in values], float))
    if v.size == 0 or not np.any(np.isfinite(v)):
        return None
    r = quantile_upper_rank(v.size, q, confidence)
    return {"p": q, "value": nearest_rank(v, q), "upper_bound": float(v[r - 1]) if r else None}


def _per_run(req: dict[str, Any], rows: list[dict[str, Any]], confidence: float, coverage: float) -> dict[str, Any]:
    key = f"req.{req['name']}"
    passed = [r.get(f"{key}.passed") for r in rows]
    n, k = len(rows), sum(x is True for x in passed)
    out = _fraction(k, n, confidence)
    out.update(_needs(coverage, confidence, k, n, out["lower_bound"]))
    if req["kind"] != "envelope":
        out["across_runs"] = _values_across([r.get(f"{key}.value") for r in rows], coverage, confidence)
    return out


def _matrix(req: dict[str, Any], rows: list[dict[str, Any]]) -> np.ndarray:
    """(runs, bins) of the ensemble series; a run without one fails in every bin another run has."""
    key = f"req.{req['name']}.bins"
    have = [r.get(key) for r in rows]
    nb = max((len(b) for b in have if b is not None), default=0)
    m = np.full((len(rows), nb), np.nan)
    for i, b in enumerate(have):
        if b is not None:
            m[i, :len(b)] = np.array([np.nan if x is None else x for x in b], float)
    span = ~np.all(np.isnan(m), axis=0)
    for i, b in enumerate(have):
        if b is None:
            m[i, span] = np.inf
    return m


def _ensemble(req: dict[str, Any], rows: list[dict[str, Any]], width: float, confidence: float) -> dict[str, Any]:
    p, bound = float(req["confidence"]), float(req["bound"])
    m = _matrix(req, rows)
    cols = np.flatnonzero(~np.all(np.isnan(m), axis=0))
    if cols.size == 0:
        return {"why": "no run has a value in the span"}
    per: dict[str, list[Any]] = {k: [] for k in ("t_s", "runs", "within", "quantile", "upper_bound", "lower_bound")}
    for j in cols:
        v = m[:, j]
        v = np.sort(v[~np.isnan(v)])
        n, k = v.size, int(np.sum(v <= bound))
        r = quantile_upper_rank(n, p, confidence)
        per["t_s"].append(round(j * width, 9))
        per["runs"].append(n)
        per["within"].append(k)
        per["quantile"].append(nearest_rank(v, p))
        per["upper_bound"].append(float(v[r - 1]) if r else None)
        per["lower_bound"].append(clopper_pearson_lower(k, n, confidence))
    worst = int(np.argmin(per["lower_bound"]))
    n_w, k_w = per["runs"][worst], per["within"][worst]
    ubs = per["upper_bound"]
    out = {"bin_s": width, "bins": int(cols.size), "worst_t_s": per["t_s"][worst],
           "worst": {**_fraction(k_w, n_w, confidence), "quantile": per["quantile"][worst]},
           "quantile_max": max(per["quantile"]), "upper_bound_max": None if None in ubs else max(ubs),
           "whole_span": _fraction(int(np.sum(np.nanmax(np.where(np.isnan(m[:, cols]), -np.inf, m[:, cols]),
                                                       axis=1) <= bound)), len(rows), confidence),
           "per_bin": per}
    out.update(_needs(p, confidence, k_w, n_w, min(per["lower_bound"])))
    return out


def _mixed(req: dict[str, Any], rows: list[dict[str, Any]], confidence: float) -> dict[str, Any]:
    p = float(req["confidence"])
    key = f"req.{req['name']}"
    f = np.array([0.0 if r.get(f"{key}.within") is None else float(r[f"{key}.within"]) for r in rows])
    n = f.size
    half = 1.0 - (1.0 - confidence) / 2.0  # two bounds, each at half the risk (Bonferroni)
    clean = int(np.sum(f >= 1.0))
    lower = max(hoeffding_lower(float(f.mean()), n, half), clopper_pearson_lower(clean, n, half))
    m = _matrix(req, rows)
    pooled = m[~np.isnan(m)]
    out = {"mean_within": float(f.mean()), "runs_never_outside": clean, "runs": n, "lower_bound": lower,
           "pooled_quantile": nearest_rank(pooled, p) if pooled.size else None,
           "runs_met": clean, "fraction": clean / n}
    out.update(required=p, met_at_confidence=lower >= p, runs_needed_without_failure=runs_needed(p, half))
    return out


def campaign_requirements(requirements: tuple[Any, ...], rows: list[dict[str, Any]], duration_s: float,
                          control_rate_hz: float, confidence: float = 0.95,
                          coverage: float = 0.95) -> list[dict[str, Any]]:
    """Per requirement of the scenario (its ``Requirement`` rows or their
    dicts), its campaign statistics over the dataset ``rows`` (see the
    module's docstring): one dict each, with name, kind, interpretation,
    bound, unit, its statistics and ``met_at_confidence``."""
    import dataclasses

    width = bin_width(duration_s, control_rate_hz)
    out = []
    for req in requirements:
        req = dataclasses.asdict(req) if dataclasses.is_dataclass(req) else dict(req)
        head = {k: req.get(k) for k in ("name", "kind", "axis", "interpretation", "confidence", "bound", "unit")}
        if req["kind"] == "envelope":
            head["bound"], head["unit"] = 1.0, "-"
        elif req["kind"] == "settling":  # judged by its time, within its band
            head.update(bound=req["settle_by"], unit="s", band=req["bound"], band_unit=req["unit"])
        statuses = {r.get(f"req.{req['name']}.status") for r in rows} - {None}
        interp = req.get("interpretation") or ""
        if statuses == {"not applicable"}:
            out.append({**head, "statistic": "not applicable", "met_at_confidence": None,
                        "why": "no run has a knowledge error (no [sensors])"})
        elif interp == "ensemble":
            out.append({**head, "statistic": "ensemble", **_ensemble(req, rows, width, confidence)})
        elif interp == "mixed":
            out.append({**head, "statistic": "mixed", **_mixed(req, rows, confidence)})
        else:
            out.append({**head, "statistic": "runs", **_per_run(req, rows, confidence, coverage)})
        out[-1].setdefault("met_at_confidence", None)
    return out
