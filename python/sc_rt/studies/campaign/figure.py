"""``montecarlo.json``, ``montecarlo.png`` and (with requirements)
``montecarlo_requirements.png`` of a campaign."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.results.judge.metrics import json_safe

__all__ = ["figure", "requirements_figure", "write_summary"]


def write_summary(summary: dict[str, Any], rows: list[dict[str, Any]], out: Path,
                  dpi: int = 90) -> None:
    """montecarlo.json (the summary) and montecarlo.png (the final error of
    every run, and what the runs say of the scenario's verdict: the
    prescribed bound where the scenario asks for the envelope, else its
    requirements; ``figure``)."""
    from sc_rt.results.present import figures  # noqa: F401  (Agg backend)
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    doc = {k: v for k, v in summary.items() if k != "per_run"}  # the rows are the dataset's
    (out / "montecarlo.json").write_text(json.dumps(json_safe(doc), indent=2) + "\n")
    fig = figure(summary, rows)
    fig.savefig(out / "montecarlo.png", dpi=dpi)
    plt.close(fig)
    if summary.get("requirements"):
        fig = requirements_figure(summary)
        fig.savefig(out / "montecarlo_requirements.png", dpi=dpi)
        plt.close(fig)


def figure(summary: dict[str, Any], rows: list[dict[str, Any]]):
    """The campaign's figure (a matplotlib Figure): the final error of every
    run; then, where the scenario asks for the prescribed envelope
    (``asks_envelope``), when runs leave the bound (or that none did) under
    "x % hold the bound"; otherwise the runs meeting each of its per-run
    requirements under "x % meet every per-run requirement" (or "no
    requirements stated")."""
    from sc_rt.results.present import figures  # noqa: F401  (Agg backend)
    import matplotlib.pyplot as plt

    from sc_rt.results.judge.verdict import asks_envelope

    final = summary["final_metric"]
    fin = np.array([r[final] for r in rows if final and r.get(final) is not None], float)
    fig, axs = plt.subplots(1, 2, figsize=(10, 4))
    if fin.size:
        axs[0].hist(np.log10(np.maximum(fin, 1e-16)), bins=30)
    when = final.removeprefix("sigma_e_norm.") + " s" if final else "the end"
    axs[0].set_xlabel(f"log10 true |sigma_BD| at {when}")
    axs[0].set_ylabel("runs")
    head = f"{summary['scenario']}, {summary['law']}, {summary['runs']} runs: "
    if asks_envelope(summary.get("requirements")):
        fig.suptitle(head + _envelope_panel(axs[1], summary, rows))
    else:
        fig.suptitle(head + _requirements_panel(axs[1], summary))
    fig.tight_layout()
    return fig


def _envelope_panel(ax, summary: dict[str, Any], rows: list[dict[str, Any]]) -> str:
    """When runs leave the prescribed bound (a histogram), or that none did; the title's words."""
    viol = np.array([r["first_bound_violation_s"] for r in rows
                     if r.get("first_bound_violation_s") is not None], float)
    n, invalid = summary["runs"], summary["status"]["invalid"]
    if viol.size:
        ax.hist(viol, bins=30, color="C3")
        ax.set_xlabel("first bound violation [s]")
        ax.set_ylabel("runs")
    else:
        ax.set_axis_off()
        text = f"no run left the bound\n({summary.get('holds_bound', n)} of {n} runs held it)"
        if invalid:
            text += f"\n{invalid} runs had no valid draw"
        ax.text(0.5, 0.5, text, ha="center", va="center", fontsize=13, transform=ax.transAxes)
    lo, hi = summary["fraction_holding_bound_ci95"] or (float("nan"),) * 2
    return (f"{100 * summary['fraction_holding_bound']:.1f} % hold the bound "
            f"(95 % CI {100 * lo:.1f}-{100 * hi:.1f} %)")


def _requirements_panel(ax, summary: dict[str, Any]) -> str:
    """The runs meeting each per-run requirement of the scenario (bars, k of
    n), or that it states none; the title's words."""
    reqs = [r for r in summary.get("requirements") or [] if r.get("statistic") == "runs"]
    if not summary.get("requirements"):
        ax.set_axis_off()
        ax.text(0.5, 0.5, "no requirements stated\n([[requirements]] in the scenario:\nnothing to judge the runs by)",
                ha="center", va="center", fontsize=12, transform=ax.transAxes)
        return "no requirements stated"
    n = summary["runs"]
    if reqs:
        met = [r["runs_met"] for r in reqs]
        y = np.arange(len(reqs))
        ax.barh(y, met, color=["C2" if r.get("met_at_confidence") else "C3" for r in reqs])
        ax.set_yticks(y, [r["name"] for r in reqs], fontsize=8)
        ax.invert_yaxis()
        ax.set_xlim(0, max(n, 1))
        for i, k in enumerate(met):
            ax.text(min(k, n), i, f" {k}/{n}", va="center", fontsize=8, ha="right" if k > 0.8 * n else "left")
        ax.set_xlabel("runs meeting it (green: met at the campaign's confidence)")
    else:
        ax.set_axis_off()
        ax.text(0.5, 0.5, "every requirement is judged across runs\n(montecarlo_requirements.png)",
                ha="center", va="center", fontsize=11, transform=ax.transAxes)
    if summary.get("fraction_meeting_requirements") is None:
        return "requirements across runs only"
    lo, hi = summary["fraction_meeting_requirements_ci"]
    c = 100 * summary.get("requirements_confidence", 0.95)
    return (f"{100 * summary['fraction_meeting_requirements']:.1f} % meet every per-run requirement "
            f"({c:g} % CI {100 * lo:.1f}-{100 * hi:.1f} %)")


def requirements_figure(summary: dict[str, Any]):
    """The requirements across the runs (a matplotlib Figure): per ensemble
    requirement its p-quantile across runs at each time bin, the quantile's
    upper confidence bound and the bound; then, per requirement, the fraction
    of runs (ensemble: at the worst time; mixed: of the time) with its
    two-sided interval, its one-sided lower bound and the fraction required."""
    from sc_rt.results.present import figures  # noqa: F401  (Agg backend)
    import matplotlib.pyplot as plt

    reqs = [r for r in summary["requirements"] if r.get("met_at_confidence") is not None]
    ens = [r for r in reqs if r["statistic"] == "ensemble"]
    c = f"{100 * summary.get('requirements_confidence', 0.95):g} %"
    fig, axs = plt.subplots(len(ens) + 1, 1, figsize=(10, 2.6 * (len(ens) + 1) + 0.8), squeeze=False)
    for ax, r in zip(axs[:-1, 0], ens):
        per = r["per_bin"]
        t = np.asarray(per["t_s"], float) + r["bin_s"] / 2.0
        unit = r.get("unit") or ""
        ax.step(t, per["quantile"], where="mid", lw=1.0, label=f"p{r['confidence']:g} across runs")
        ub = np.array([np.nan if u is None else u for u in per["upper_bound"]], float)
        ax.step(t, ub, where="mid", lw=0.9, ls="--", label=f"its {c} upper bound")
        ax.axhline(r["bound"], color="r", lw=0.9, label=f"bound {r['bound']:g} {unit}")
        ax.set_ylabel(f"[{unit}]")
        ax.set_title(f"{r['name']}: {r['kind']} {r.get('axis') or ''} ensemble, {summary['runs']} runs "
                     f"({'MET' if r['met_at_confidence'] else 'NOT DEMONSTRATED'} at {c})", fontsize=9, loc="left")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    if ens:
        axs[-2, 0].set_xlabel("t [s]")
    ax = axs[-1, 0]
    for i, r in enumerate(reqs):
        f = r["worst"] if r["statistic"] == "ensemble" else r
        lo, hi = (f["lower_bound"], f["mean_within"]) if r["statistic"] == "mixed" else f["interval"]
        ax.plot([lo, hi], [i, i], color="C0", lw=3, solid_capstyle="butt",
                label="two-sided interval (mixed: bound to mean)" if not i else None)
        ax.plot(f["lower_bound"], i, "k>", ms=6, label=f"one-sided {c} lower bound" if not i else None)
        ax.plot(r["required"], i, "r|", ms=14, mew=2, label="required" if not i else None)
    ax.set_yticks(range(len(reqs)), [f"{r['name']} ({r['statistic']})" for r in reqs], fontsize=8)
    ax.set_xlabel("fraction of runs meeting it (ensemble: at its worst time; mixed: of the time)")
    ax.set_xlim(min([0.9] + [r["required"] - 0.02 for r in reqs] + [(r.get("lower_bound") or 0.0) - 0.02
                                                                    for r in reqs if r["statistic"] != "ensemble"]),
                1.005)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    fig.suptitle(f"{summary['scenario']}, {summary['law']}: requirements across {summary['runs']} runs")
    fig.tight_layout()
    return fig
