"""``sc-rt design``: the report (one JSON-able dict), its text and design.json (docs/DESIGN.md)."""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.scenario.model import Scenario
from sc_rt.studies.design.figures import plot_loops, plot_spectral
from sc_rt.studies.design.linear import AXES, INERTIAS, input_matrices
from sc_rt.studies.design.margins import DEFAULT_LATENCY_S, closed_form_pd_margins, coupling, pd_margins
from sc_rt.studies.design.noise import noise_floor_report
from sc_rt.studies.design.pd import PdDesign, default_pd_design
from sc_rt.studies.lawparams import pd_gains
from sc_rt.studies.design.stability import (compare_loss_of_stability, simulated_loss_of_stability,
                                            stability_limit, without_wheel_limits)

__all__ = [
    "MARGINS_LOOP",
    "design_report",
    "chiinf_check",
    "format_margins_table",
    "format_sampled_table",
    "format_chiinf_check",
    "format_loss_of_stability",
    "format_design_text",
    "write_design",
]

#: What the margins are of: the PD baseline, not the DSC+PPC law (whose
#: sampled-data stability is the other table).
MARGINS_LOOP = ("PD loop u = -B+ (beta1 x1 + beta2 x2), broken at the axis command v, "
                "one axis at a time")


def chiinf_check(scn: Scenario, limit: dict[str, Any]) -> dict[str, Any]:
    """The scenario's chiinf against the smallest stable chiinf of a dsc-ppc ``limit``.

    ``ratio = chiinf / chiinf_min`` per axis: below 1 the envelope ends where
    the linearised sampled loop is unstable at that rate.
    """
    have = [float(c) for c in scn.controller.ppc.chiinf]
    need = limit["chiinf_min"]
    ratio = [h / n if n and math.isfinite(n) else None for h, n in zip(have, need)]
    return {"rate_hz": limit["rate_hz"], "chiinf": have, "chiinf_min": list(need), "ratio": ratio,
            "stable_at_end": [r is not None and r >= 1.0 for r in ratio]}


def design_report(scn: Scenario, rate: float | None = None, *, latency: float = DEFAULT_LATENCY_S,
                  pd: PdDesign | None = None, context_rates=(10.0, 100.0, 1000.0),
                  inertia: str = "true", observer: str = "linear-part",
                  simulate: bool = True) -> dict[str, Any]:
    """Everything ``sc-rt design`` prints and writes, as one JSON-able dict.

    ``simulate``: also run the scenario's DSC+PPC loop at ``rate`` (cpp
    engine, the scenario's duration) and compare its loss of stability with
    the prediction (``loss_of_stability``); when the run breaks its bound
    before the predicted loss, once more without wheel limits.

    Parameters
    ----------
    scn : Scenario
        The scenario (``sc_rt.load_scenario``).
    rate : float, optional
        [Hz] the control rate of the design. None: the scenario's.
    latency : float
        [s] the state-to-command latency of the "pade" margins case
        (default ``DEFAULT_LATENCY_S``).
    pd : PdDesign, optional
        The PD gains whose margins are computed. None: ``default_pd_design``
        (the envelope's settling time, critically damped).
    context_rates : iterable of float
        [Hz] more rates of the sampled-data table, besides ``rate``.
    inertia : {"true", "nominal"}
        The inertia of the sampled-data loops: the plant's J0 + dJ ("true")
        or the controller's J0 ("nominal").
    observer : {"linear-part", "local-gain"}
        The observer's linearisation in the sampled-data loops
        (``observer_gains``).
    simulate : bool
        Also simulate, as above (``loss_of_stability``).

    Returns
    -------
    dict
        The report: the PD gains, closed-form and computed margins
        (``margins``), coupling, the sampled-data limits of dsc-ppc and dsc
        per rate (``sampled_data``), ``chiinf_check``, ``noise_floor`` and,
        with ``simulate``, ``loss_of_stability``. ``format_design_text``
        prints it; ``write_design`` writes it.

    Raises
    ------
    ValueError
        An unknown ``inertia`` or ``observer``; no default PD design (a zero
        PPC gamma) when ``pd`` is None.
    """
    rate = scn.run.control_rate_hz if rate is None else float(rate)
    pd = default_pd_design(scn) if pd is None else pd
    rows = pd_margins(scn, pd, rate=rate, latency=latency)
    rates = sorted({rate, *map(float, context_rates)})
    sampled = {}
    for law in ("dsc-ppc", "dsc"):
        sampled[law] = {f"{f:g}": stability_limit(scn, law, f, inertia=inertia, faults=True,
                                                  observer=observer).as_dict()
                        for f in rates}
    limit = sampled["dsc-ppc"][f"{rate:g}"]
    rep = {
        "scenario": scn.name,
        "scenario_path": str(scn.path),
        "rate_hz": rate,
        "latency_s": latency,
        "pd": asdict(pd),
        "pd_in_scenario": vars(pd_gains(scn)),
        "closed_form": {inertia_: [closed_form_pd_margins(pd.beta1, pd.beta2, m, rate)
                                   for m in np.diag(input_matrices(scn, inertia_).M)]
                        for inertia_ in INERTIAS},
        "coupling": {i: coupling(scn, i) for i in INERTIAS},
        "margins_loop": MARGINS_LOOP,
        "margins": rows,
        "sampled_data": {"inertia": inertia, "faults": True, "observer": observer,
                         "limits": sampled},
        "chiinf_check": chiinf_check(scn, limit),
        "noise_floor": noise_floor_report(scn, rate),  # sc_rt.studies.design.noise
    }
    if simulate:
        sim = simulated_loss_of_stability(scn, "dsc-ppc", rate)
        tb, tl = sim["first_bound_violation_s"], limit["t_loss_s"]
        free = None
        if tb is not None and (tl is None or tb < tl):  # broken before the predicted loss
            free = simulated_loss_of_stability(without_wheel_limits(scn), "dsc-ppc", rate)
        rep["loss_of_stability"] = compare_loss_of_stability(limit, sim, free)
    return rep


def format_margins_table(rows: list[dict[str, Any]], title: str | None = MARGINS_LOOP) -> str:
    """The margins as a fixed-width text table, under a line saying whose loop they are."""

    def f(v, fmt):
        width = int(fmt.split(".")[0])
        if v is None:
            return "-".rjust(width)
        if isinstance(v, float) and math.isinf(v):
            return "inf".rjust(width)
        return format(v, fmt)

    head = (f"{'inertia':<8} {'case':<10} {'axis':<4} {'GM':>9} {'GM[dB]':>7} {'PM[deg]':>8} "
            f"{'wgc[rad/s]':>10} {'DM[s]':>8} {'Ms':>6} {'stable':>6}")
    lines = [title] if title else []
    lines += [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['inertia']:<8} {r['case']:<10} {r['axis']:<4} {f(r['gm'], '9.4g')} "
                     f"{f(r['gm_db'], '7.1f')} {f(r['pm'], '8.3f')} {f(r['wgc'], '10.5f')} "
                     f"{f(r['delay_margin'], '8.4f')} {f(r['ms'], '6.4f')} {str(r['stable']):>6}")
    return "\n".join(lines)


def _num(v, fmt="8.3f"):
    if v is None:
        return "-"
    if isinstance(v, float) and math.isinf(v):
        return "inf"
    return format(v, fmt)


def format_sampled_table(report: dict[str, Any]) -> str:
    """The sampled-data predictions of a :func:`design_report` as a text table."""
    f = _num
    head = (f"{'law':<8} {'rate[Hz]':>8} {'t_loss[s]':>9} {'axis':>4} {'mode[Hz]':>8} "
            f"{'rho(0)':>9} {'chiinf_min x/y/z (= critical chi)':>36} {'t_crit x/y/z [s]':>24}")
    lines = [head, "-" * len(head)]
    for law, by_rate in report["sampled_data"]["limits"].items():
        for key, lim in sorted(by_rate.items(), key=lambda kv: float(kv[0])):
            cc = " ".join(f(c, "11.3e") for c in lim["chi_crit"]) if lim["chi_crit"] else "-"
            tc = " ".join(f(c, "7.2f") for c in lim["t_crit_s"]) if lim["t_crit_s"] else "-"
            lines.append(f"{law:<8} {float(key):>8g} {f(lim['t_loss_s'], '9.2f'):>9} "
                         f"{lim['axis'] or '-':>4} {f(lim['mode_hz'], '8.3f'):>8} "
                         f"{f(lim['rho_at_0'], '9.6f')} {cc:>36} {tc:>24}")
    return "\n".join(lines)


def format_chiinf_check(check: dict[str, Any]) -> str:
    """The scenario's chiinf, the smallest stable one at the rate, and their ratio, per axis."""
    lines = [f"chiinf of the scenario against the smallest stable chiinf of DSC+PPC at "
             f"{check['rate_hz']:g} Hz:"]
    for i, ax in enumerate(AXES):
        r = check["ratio"][i]
        verdict = "-" if r is None else ("stable at the end of the envelope" if r >= 1.0 else
                                         "unstable before the envelope ends")
        lines.append(f"  {ax}: chiinf = {check['chiinf'][i]:.3e}, chiinf_min = "
                     f"{_num(check['chiinf_min'][i], '.3e')}, ratio chiinf/chiinf_min = "
                     f"{_num(r, '.2e')} ({verdict})")
    return "\n".join(lines)


def format_loss_of_stability(cmp: dict[str, Any]) -> str:
    """The predicted loss of stability, the run's first bound violation, and why they differ."""
    tl, tb, ax, axb = (cmp["t_loss_s"], cmp["first_bound_violation_s"], cmp["axis"],
                       cmp["first_bound_violation_axis"])
    pred = "none to the horizon" if tl is None else f"{tl:.2f} s (axis {ax})"
    run = "none" if tb is None else f"{tb:.2f} s (axis {axb})"
    return (f"loss of stability, DSC+PPC at {cmp['rate_hz']:g} Hz: predicted (linearised sampled "
            f"loop) {pred}; the run (cpp engine, {cmp['duration_s']:g} s): first bound violation "
            f"{run}\n  {cmp['explanation']}")


def format_design_text(rep: dict[str, Any], out: Path | None = None,
                       paths: list[Path] = ()) -> str:
    """What ``sc-rt design`` prints for a :func:`design_report`."""
    pd = rep["pd"]
    lines = [f"sc-rt design: {rep['scenario']} at {rep['rate_hz']:g} Hz"
             + (f" -> {out}/" if out is not None else ""),
             f"PD: beta1 = {pd['beta1']:.4g} 1/s^2, beta2 = {pd['beta2']:.4g} 1/s "
             f"(wn = {pd['wn']:.4g} rad/s; {pd['rule']}); scenario has "
             f"{rep['pd_in_scenario']['beta1']:g}, {rep['pd_in_scenario']['beta2']:g}",
             "",
             f"margins of the PD baseline loop, not of DSC+PPC "
             f"(pade: latency {rep['latency_s'] * 1e3:.3g} ms):",
             format_margins_table(rep["margins"], rep.get("margins_loop", MARGINS_LOOP)),
             "",
             "sampled-data stability of the linearised DSC+PPC and DSC loops "
             "(r frozen at chi(t), true inertia, faults' effectiveness, observer's linear part):",
             format_sampled_table(rep)]
    if "chiinf_check" in rep:
        lines += ["", format_chiinf_check(rep["chiinf_check"])]
    if "loss_of_stability" in rep:
        lines += ["", format_loss_of_stability(rep["loss_of_stability"])]
    if "noise_floor" in rep:
        lines += ["", rep["noise_floor"]["text"]]
    lines += [f"  {p}" for p in paths]
    return "\n".join(lines)


def write_design(report: dict[str, Any], scn: Scenario, out: Path, plots: bool = True) -> list[Path]:
    """design.json and the figures (bode.png, nichols.png, spectral_radius.png) into out/."""
    from sc_rt.results.judge.metrics import json_safe

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    if plots:
        pd = PdDesign(**report["pd"])
        paths += plot_loops(scn, pd, report["rate_hz"], report["latency_s"], out)
        paths.append(plot_spectral(scn, report, out))
    report = dict(report, figures=[p.name for p in paths])
    path = out / "design.json"
    path.write_text(json.dumps(json_safe(report), indent=2) + "\n")
    return [path, *paths]
