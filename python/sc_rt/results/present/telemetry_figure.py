"""law_telemetry.png: the control law's own telemetry over a run (its named
values and the fixed slots it fills), from sc_rt.results.judge.law_telemetry's
summary."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sc_rt.results.present.figure_marks import mark_events, run_title
from sc_rt.results.present.figures import save_figure
from sc_rt.results.judge.law_telemetry import telemetry_summary
from sc_rt.results.record.run import Run

__all__ = ["telemetry_figure"]


def telemetry_figure(run: Run, out: Path, title: str = "") -> Path | None:
    """law_telemetry.png: one panel per named value and per fixed slot the law
    filled (x2d per axis, rho_hat); None when the law reports none."""
    import matplotlib.pyplot as plt

    summary = run.metrics.get("law_telemetry") or telemetry_summary(run)
    panels: list[tuple[str, np.ndarray]] = []
    t = np.asarray(run["t"], float)
    if "x2d" in summary["fixed_slots_used"]:
        panels.append(("x2d [rad/s] (filtered virtual control)", np.asarray(run["x2d"], float)))
    if "rho_hat" in summary["fixed_slots_used"]:
        panels.append(("rho_hat (adaptive gain)", np.asarray(run["rho_hat"], float)))
    tel = np.asarray(run["telemetry"], float) if summary["names"] else None
    for i, name in enumerate(summary["names"]):
        panels.append((name, tel[:, i]))
    if not panels:
        return None
    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 1.9 + 1.6 * len(panels)), sharex=True, squeeze=False)
    for ax, (label, v) in zip(axes[:, 0], panels):
        if v.ndim == 2:
            for j in range(v.shape[1]):
                ax.plot(t, v[:, j], lw=1, label="xyz"[j])
            ax.legend(loc="upper right", fontsize=8)
        else:
            ax.plot(t, v, lw=1)
        ax.set_ylabel(label, fontsize=8)
        ax.grid(True, alpha=0.3)
        mark_events(ax, run)
    axes[-1, 0].set_xlabel("t [s]")
    fig.suptitle(f"The law's telemetry\n{title or run_title(run)}", fontsize=10)
    fig.tight_layout()
    path = save_figure(fig, Path(out) / "law_telemetry.png")
    plt.close(fig)
    return path
