"""Laws compared on one scenario (``sc-rt compare``, docs/LAWS.md): a row of
each law's run (verdict, requirements met, the bound where the scenario asks
for the envelope, settling, peaks, SAFE and law-invalid steps, its
requirement results), the laws ranked by margin on each
requirement, and overall by each law's worst margin. Pure data from finished
runs; the tables that show them: sc_rt.results.present.tables."""

from __future__ import annotations

from typing import Any

import numpy as np

from sc_rt.results.judge.estimation import true_error_fields
from sc_rt.results.judge.pointing import settling_time
from sc_rt.results.judge.requirements import is_sensed, worst
from sc_rt.results.judge.verdict import asks_envelope, pointing_arcsec, requirements_summary

__all__ = ["REQUIREMENT_KEYS", "compare_row", "overall", "rank_key", "rank_requirements", "requirements_met",
           "settling_s"]


def settling_s(t: np.ndarray, sigma_BD: np.ndarray, frac: float) -> float | None:
    """[s] the first time from which the pointing error stays within ``frac``
    of its initial value (pointing.settling_time, the requirements' own
    definition, with the band ``frac * e(0)``); None if it does not settle by
    the end or the initial error is not finite."""
    e = pointing_arcsec(sigma_BD)
    if not len(e) or not np.isfinite(e[0]):
        return None
    return settling_time(t, e, frac * float(e[0]))


#: What a row keeps of each requirement's result.
REQUIREMENT_KEYS = ("name", "kind", "axis", "interpretation", "confidence", "value", "bound", "unit", "margin",
                    "relative_margin", "passed", "status")


def compare_row(run, label: str, settle_frac: float = 0.02) -> dict[str, Any]:
    """One law's row: its run's verdict, settling within ``settle_frac`` of
    the initial error and the final error (the true ones: with sensors
    ``sigma_BD_true``, not the law's estimate), peaks, SAFE and law-invalid
    steps, requirements; and the prescribed bound (held, first violation,
    rows outside) only where the scenario asks for the envelope
    (``asks_envelope``)."""
    m = run.metrics
    ok = np.all(run["bound_ok"], axis=1)
    sig = run[true_error_fields(is_sensed(run))[0]]
    bound = {"bound_held": bool(np.all(ok)), "first_bound_violation_s": m.get("first_bound_violation_s"),
             "bound_violation_fraction": float(np.mean(~ok)) if len(ok) else None}
    return {
        "law": label,
        **(bound if asks_envelope(m.get("requirements")) else {}),
        "requirements_met": requirements_met(m.get("requirements")),
        "settling_s": settling_s(run["t"], sig, settle_frac),
        "final_pointing_arcsec": float(pointing_arcsec(sig[-1:])[0]) if len(ok) else None,
        "max_abs_wheel_accel": m.get("max_abs_wheel_accel"),
        "safe_steps": m.get("safe_steps"),
        "law_invalid_steps": m.get("law_invalid_steps"),
        "diverged": bool(m.get("diverged", False)),
        "valid": m.get("valid", True) is not False,
        "invalid_reason": m.get("invalid_reason"),
        "verdict": None if m.get("requirements") is None else requirements_summary(m["requirements"]),
        "requirements": [{k: r.get(k) for k in REQUIREMENT_KEYS} for r in m.get("requirements") or []],
        "expect": m.get("expect"),  # the file's expect against this law's run (sc_rt.results.judge.gate)
    }


def requirements_met(reqs: list[dict[str, Any]] | None) -> str | None:
    """The requirements a run met, in short: "7/7", "4/7" (of those judged
    within the run), "none stated"; None for metrics without requirements."""
    if reqs is None:
        return None
    if not reqs:
        return "none stated"
    judged = [r for r in reqs if r.get("passed") is not None]
    return f"{sum(bool(r['passed']) for r in judged)}/{len(judged)}" if judged else "none judged"


def rank_key(r: dict[str, Any]) -> tuple[int, float]:
    """Best first: a larger margin relative to the bound; a failure without a
    value (never settled) after every value; not evaluated last."""
    if r.get("passed") is None:
        return (2, 0.0)
    m = r.get("relative_margin")
    return (1, 0.0) if m is None else (0, -float(m))


def merge_seeds(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """One law's row from its runs over several sensor-noise seeds (``rows``,
    one per seed, each a ``compare_row``): the first run's row, each
    requirement's ``value`` and ``relative_margin`` the mean over the seeds,
    with every seed's relative margin (``seed_relative_margins``) and their
    spread (max - min); ``passed`` only when every seed passed. The ranking
    (``rank_requirements``) then says which differences lie within it."""
    if len(rows) == 1:
        return rows[0]
    out = dict(rows[0])
    out["seeds"] = len(rows)
    out["valid"] = all(r.get("valid", True) for r in rows)
    reqs = []
    for i, r in enumerate(rows[0].get("requirements") or []):
        same = [row["requirements"][i] for row in rows if len(row.get("requirements") or []) > i]
        rel = [x.get("relative_margin") for x in same]
        val = [x.get("value") for x in same]
        merged = dict(r)
        if all(v is not None for v in rel):
            merged["relative_margin"] = float(np.mean(rel))
            merged["seed_relative_margins"] = [float(v) for v in rel]
            merged["seed_spread"] = float(np.max(rel) - np.min(rel))
        if all(v is not None for v in val):
            merged["value"] = float(np.mean(val))
        passed = [x.get("passed") for x in same]
        merged["passed"] = None if any(v is None for v in passed) else all(passed)
        merged["status"] = r.get("status") if merged["passed"] is None else ("pass" if merged["passed"] else "fail")
        reqs.append(merged)
    out["requirements"] = reqs
    return out


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
        entries.sort(key=rank_key)
        for i, e in enumerate(entries):
            e["rank"] = i + 1 if e.get("passed") is not None else None
            # over several seeds: is the next one's mean within either's spread (a difference of noise)?
            if i + 1 < len(entries) and "seed_spread" in e and "seed_spread" in entries[i + 1]:
                gap = abs(e["relative_margin"] - entries[i + 1]["relative_margin"])
                e["within_seed_spread_of_next"] = bool(gap <= max(e["seed_spread"], entries[i + 1]["seed_spread"]))
    return out


def overall(rows: list[dict[str, Any]]) -> list[tuple[str, dict[str, Any] | None]]:
    """The laws ordered by their worst requirement (the smallest margin
    relative to its bound, as the verdict line): (law, that requirement)."""
    judged = [(row["law"], worst(row.get("requirements") or [])) for row in rows if row.get("requirements")]
    return sorted(judged, key=lambda x: (2, 0.0) if x[1] is None else rank_key(x[1]))
