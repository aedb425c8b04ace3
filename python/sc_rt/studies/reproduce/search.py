"""The tightest chiinf that holds, by bisection on the runs (both paper cases,
300 s), and the runs of the shipped feasible designs (``ppc_feasible_*``)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sc_rt.scenario.model import Scenario
from sc_rt.scenario.variants import with_law_params, with_ppc, without_faults
from sc_rt.sim.engines import simulate
from sc_rt.studies.reproduce.cases import CASES, scenario_label, shipped_scenario
from sc_rt.studies.reproduce.claims import fmt

__all__ = ["FEASIBLE", "chiinf_min", "feasible_search", "format_search_md", "holds", "tightest_chiinf"]

#: control rate [Hz] -> shipped scenario name of the feasible design at that rate
FEASIBLE = {10.0: "ppc_feasible_10hz", 100.0: "ppc_feasible_100hz", 1000.0: "ppc_feasible_1khz"}


def holds(scn: Scenario, chiinf, rate: float, *, engine: str = "cpp") -> dict[str, Any]:
    """DSC+PPC with this chiinf at this rate in both the scenario and its fault-free copy."""
    out = {}
    for case, s in (("faults", scn), ("fault_free", without_faults(scn))):
        r = simulate(with_ppc(s, chiinf=chiinf), law="dsc-ppc", engine=engine, control_rate_hz=rate)
        out[case] = r.metrics["first_bound_violation_s"]
    out["holds"] = all(v is None for k, v in out.items() if k != "holds")
    return out


def chiinf_min(scn: Scenario, rate: float) -> np.ndarray:
    """The predicted smallest stable chiinf (sc_rt.studies.design.stability_limit), the larger
    of the scenario with its faults and without them, per axis."""
    from sc_rt.studies import design as D

    return np.maximum(*(np.asarray(D.stability_limit(s, "dsc-ppc", rate, horizon=1.0).chiinf_min, float)
                        for s in (scn, without_faults(scn))))


def tightest_chiinf(scn: Scenario, rate: float, *, lo: float = 0.5, hi: float = 2.0, rtol: float = 0.01,
                    engine: str = "cpp") -> dict[str, Any]:
    """Bisection on a factor c of chiinf = c * chiinf_min(scn, rate), both cases (the
    scenario and its fault-free copy), 300 s: the smallest c that holds (to rtol)."""
    base = chiinf_min(scn, rate)
    log = []
    r_hi = holds(scn, hi * base, rate, engine=engine)
    r_lo = holds(scn, lo * base, rate, engine=engine)
    log += [(hi, r_hi), (lo, r_lo)]
    if not r_hi["holds"] or r_lo["holds"]:
        return {"rate_hz": rate, "chiinf_min_predicted": base.tolist(), "bracket_ok": False, "log": log}
    while hi / lo > 1 + rtol:
        mid = math.sqrt(lo * hi)
        r = holds(scn, mid * base, rate, engine=engine)
        log.append((mid, r))
        if r["holds"]:
            hi = mid
        else:
            lo = mid
    return {"rate_hz": rate, "chiinf_min_predicted": base.tolist(), "bracket_ok": True,
            "factor_holds": hi, "factor_fails": lo, "chiinf_tightest": (hi * base).tolist(),
            "log": [{"factor": f, **r} for f, r in log]}


def feasible_search(*, engine: str = "cpp", rates=(10.0, 100.0, 1000.0)) -> dict[str, Any]:
    """Per rate: the tightest chiinf that holds (bisection) with the paper's k2 = 4 and
    with k2 = 1.6 f, and the shipped scenarios' runs in both cases."""
    paper = shipped_scenario(CASES["faults"])
    rows = []
    for rate in rates:
        for k2 in (paper.controller.resolved("dsc-ppc")["k2"], 1.6 * rate):
            r = tightest_chiinf(with_law_params(paper, "dsc-ppc", k2=float(k2)), rate, engine=engine)
            r["k2"] = float(k2)
            rows.append(r)
    shipped = []
    for rate in rates:
        name = FEASIBLE.get(rate)
        if name is None:
            continue
        scn = shipped_scenario(name)
        for case, s in (("faults", scn), ("fault_free", without_faults(scn))):
            res = simulate(s, engine=engine)
            m = res.metrics
            shipped.append({"file": scenario_label(name), "case": case, "rate_hz": rate,
                            "k2": scn.controller.resolved("dsc-ppc")["k2"],
                            "chiinf": [float(v) for v in scn.controller.ppc.chiinf],
                            "first_bound_violation_s": m["first_bound_violation_s"],
                            "max_abs_lambda": float(np.nanmax(np.abs(res["lam"]))),
                            "sigma_e_norm_300s": m["sigma_e_norm"]["300"],
                            "max_abs_omega_e_after_70s": m["max_abs_omega_e_after_70s"],
                            "max_observer_error_after_30s": m["max_observer_error_after_30s"],
                            "max_abs_u_cmd": m["max_abs_u_cmd"],
                            "saturated_fraction": m["saturated_fraction"]})
    return {"search": rows, "shipped": shipped}


def format_search_md(doc: dict[str, Any]) -> str:
    lines = [("| rate | k2 [1/s] | predicted chiinf_min x / y / z | tightest factor that holds (fails) | "
             "tightest chiinf x / y / z |"), "|---|---|---|---|---|"]
    for r in doc["search"]:
        p = " / ".join(f"{v:.3g}" for v in r["chiinf_min_predicted"])
        if r.get("bracket_ok"):
            t = " / ".join(f"{v:.3g}" for v in r["chiinf_tightest"])
            f = f"{r['factor_holds']:.4f} ({r['factor_fails']:.4f})"
        else:
            t, f = "bracket failed", "-"
        lines.append(f"| {r['rate_hz']:g} Hz | {r['k2']:g} | {p} | {f} | {t} |")
    lines += ["", ("| file | case | k2 | chiinf | first violation | max abs lambda | norm sigma_e at 300 s | "
              "max abs omega_e after 70 s | max observer error after 30 s | max abs u_cmd | saturated fraction |"),
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in doc["shipped"]:
        lines.append(f"| `{s['file']}` | {s['case']} | {s['k2']:g} | "
                     f"{', '.join(f'{v:.3g}' for v in s['chiinf'])} | {fmt(s['first_bound_violation_s'])} | "
                     f"{s['max_abs_lambda']:.3f} | {fmt(s['sigma_e_norm_300s'])} | "
                     f"{fmt(s['max_abs_omega_e_after_70s'])} | {fmt(s['max_observer_error_after_30s'])} | "
                     f"{fmt(s['max_abs_u_cmd'])} | {s['saturated_fraction']:.4f} |")
    return "\n".join(lines) + "\n"
