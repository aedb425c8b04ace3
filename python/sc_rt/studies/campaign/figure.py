"""``montecarlo.json`` and ``montecarlo.png`` of a campaign."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.results.metrics import json_safe

__all__ = ["figure", "write_summary"]


def write_summary(summary: dict[str, Any], rows: list[dict[str, Any]], out: Path,
                  dpi: int = 90) -> None:
    """montecarlo.json (the summary) and montecarlo.png (the final error of
    every run; when runs leave the bound, when they do; otherwise it says that
    no run left it, rather than drawing an empty histogram)."""
    from sc_rt.results import figures  # noqa: F401  (Agg backend)
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    doc = {k: v for k, v in summary.items() if k != "per_run"}  # the rows are the dataset's
    (out / "montecarlo.json").write_text(json.dumps(json_safe(doc), indent=2) + "\n")
    fig = figure(summary, rows)
    fig.savefig(out / "montecarlo.png", dpi=dpi)
    plt.close(fig)


def figure(summary: dict[str, Any], rows: list[dict[str, Any]]):
    """The campaign's figure (a matplotlib Figure)."""
    from sc_rt.results import figures  # noqa: F401  (Agg backend)
    import matplotlib.pyplot as plt

    final = summary["final_metric"]
    fin = np.array([r[final] for r in rows if final and r.get(final) is not None], float)
    viol = np.array([r["first_bound_violation_s"] for r in rows
                     if r.get("first_bound_violation_s") is not None], float)
    invalid = summary["status"]["invalid"]
    fig, axs = plt.subplots(1, 2, figsize=(10, 4))
    if fin.size:
        axs[0].hist(np.log10(np.maximum(fin, 1e-16)), bins=30)
    when = final.removeprefix("sigma_e_norm.") + " s" if final else "the end"
    axs[0].set_xlabel(f"log10 |sigma_BD| at {when}")
    axs[0].set_ylabel("runs")
    n = summary["runs"]
    if viol.size:
        axs[1].hist(viol, bins=30, color="C3")
        axs[1].set_xlabel("first bound violation [s]")
        axs[1].set_ylabel("runs")
    else:
        axs[1].set_axis_off()
        text = f"no run left the bound\n({summary.get('holds_bound', n)} of {n} runs held it)"
        if invalid:
            text += f"\n{invalid} runs had no valid draw"
        axs[1].text(0.5, 0.5, text, ha="center", va="center", fontsize=13, transform=axs[1].transAxes)
    lo, hi = summary["fraction_holding_bound_ci95"] or (float("nan"),) * 2
    frac = summary["fraction_holding_bound"]
    fig.suptitle(f"{summary['scenario']}, {summary['law']}, {n} runs: {100 * frac:.1f} % hold the "
                 f"bound (95 % CI {100 * lo:.1f}-{100 * hi:.1f} %)")
    fig.tight_layout()
    return fig
