"""The paper-style figures of a reproduction (its figures 4-15), per case.

:func:`claim_figures` builds them and returns the Figures (so they can be
inspected); :func:`write_figures` saves and closes them
(``sc_rt.results.present.figures.save_figure``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.results.judge.metrics import prescribed_chi
from sc_rt.studies.reproduce.cases import LAW_LABEL, Runs
from sc_rt.studies.reproduce.claims import OBSERVER_THRESHOLD, OMEGA_E_THRESHOLD

__all__ = ["COLORS", "DPI", "FIGURES", "claim_figures", "write_figures"]

DPI = 80
COLORS = {"dsc-ppc": "C0", "dsc": "C1", "pd": "C2", "rft": "C3"}
#: the figures of one case, in order: f"{case}_{name}.png"
FIGURES = ("attitude_error", "attitude_error_log", "rate_error", "wheel_commands", "disturbance_observer")


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def write_figures(figs: dict[str, Any], out: Path, dpi: int = DPI) -> list[Path]:
    """Save (and close) every figure of ``figs`` (file name -> Figure) into ``out``."""
    from sc_rt.results.present.figures import save_figure  # imports matplotlib: only when plotting

    return [save_figure(fig, Path(out) / name, dpi) for name, fig in figs.items()]


def claim_figures(runs: Runs) -> dict[str, Any]:
    """File name -> Figure, per case: attitude error with the bounds (linear, log),
    rate error, DSC+PPC's wheel commands with the limits, the lumped disturbance
    and the observer error."""
    figs: dict[str, Any] = {}
    for case, R in runs.results.items():
        tag = f"{case}, {R['dsc-ppc'].metrics['control_rate_hz']:g} Hz"
        scn = runs.scenarios[case]
        for log in (False, True):
            figs[f"{case}_attitude_error{'_log' if log else ''}.png"] = _attitude(R, scn, tag, log)
        figs[f"{case}_rate_error.png"] = _rate(R, tag, case == "fault_free")
        figs[f"{case}_wheel_commands.png"] = _wheels(R["dsc-ppc"], scn, tag)
        figs[f"{case}_disturbance_observer.png"] = _observer(R, tag, case == "fault_free")
    return figs


def _attitude(R: dict[str, Any], scn: Any, tag: str, log: bool) -> Any:
    plt = _pyplot()
    ppc = scn.controller.ppc
    dmin, dmax = np.asarray(ppc.dmin), np.asarray(ppc.dmax)
    fig, axs = plt.subplots(3, 1, figsize=(8, 7.5), sharex=True)
    for i, ax in enumerate(axs):
        for law, r in R.items():
            t, x = r["t"], r["sigma_BD"][:, i]
            y = np.abs(x) + 1e-300 if log else x
            ax.plot(t, y, color=COLORS[law], lw=0.9, label=LAW_LABEL[law])
        t = R["dsc-ppc"]["t"]
        chi = prescribed_chi(ppc, t)[:, i]
        if log:
            ax.set_yscale("log")
            ax.plot(t, dmax[i] * chi, "k--", lw=0.8, label="dmax chi (x > 0)")
            ax.plot(t, dmin[i] * chi, "k:", lw=0.8, label="dmin chi (x < 0)")
            ax.set_ylim(1e-9, 2.0)
        else:
            ax.plot(t, dmax[i] * chi, "k--", lw=0.8, label="bounds")
            ax.plot(t, -dmin[i] * chi, "k--", lw=0.8)
            lim = 1.3 * max(dmax[i], dmin[i]) * ppc.chi0[i]
            ax.set_ylim(-lim, lim)
        ax.set_ylabel(f"{'|sigma_e,' if log else 'sigma_e,'}{'xyz'[i]}{'|' if log else ''} [-]")
        ax.grid(alpha=0.3, which="both" if log else "major")
    axs[0].legend(fontsize=7, ncol=3, loc="upper right")
    axs[0].set_title(f"Attitude tracking error (MRP) and prescribed bounds, {tag}"
                     f"{', log scale' if log else ''}")
    axs[-1].set_xlabel("t [s]")
    return fig


def _rate(R: dict[str, Any], tag: str, with_claim: bool) -> Any:
    fig, ax = _pyplot().subplots(figsize=(8, 4))
    for law, r in R.items():
        ax.semilogy(r["t"], np.linalg.norm(r["omega_BD_B"], axis=1) + 1e-300,
                    color=COLORS[law], lw=0.9, label=LAW_LABEL[law])
    if with_claim:
        ax.axhline(OMEGA_E_THRESHOLD, color="k", ls=":", lw=0.8, label="claim 1e-7 after 70 s")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("|omega_e| [rad/s]")
    ax.set_title(f"Angular-rate tracking error, {tag}")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, ncol=3)
    return fig


def _wheels(r: Any, scn: Any, tag: str) -> Any:
    t = r["t"]
    fig, axs = _pyplot().subplots(2, 1, figsize=(8, 6), sharex=True)
    for j in range(4):
        axs[0].plot(t, r["u_sat"][:, j], lw=0.8, label=f"RW{j + 1}")
        axs[1].plot(t, r["u_cmd"][:, j], lw=0.8, label=f"RW{j + 1}")
    umin, umax = float(np.min(scn.actuators.umin)), float(np.max(scn.actuators.umax))
    for ax in axs:
        ax.axhline(umax, color="k", ls="--", lw=0.8, label="umax, umin")
        ax.axhline(umin, color="k", ls="--", lw=0.8)
        ax.grid(alpha=0.3)
    axs[0].set_ylabel("applied u_sat [rad/s^2]")
    axs[0].set_title(f"DSC+PPC wheel commands and saturation limits, {tag}")
    axs[0].legend(fontsize=7, ncol=5)
    axs[1].set_yscale("symlog", linthresh=10.0)
    axs[1].set_yticks([-1e12, -1e8, -1e4, -10, 0, 10, 1e4, 1e8, 1e12])
    axs[1].set_ylabel("commanded u_cmd [rad/s^2]")
    axs[1].set_xlabel("t [s]")
    return fig


def _observer(R: dict[str, Any], tag: str, with_claim: bool) -> Any:
    fig, axs = _pyplot().subplots(2, 1, figsize=(8, 6), sharex=True)
    for law in ("dsc-ppc", "dsc"):
        rr = R[law]
        tt = rr["t"]
        if law == "dsc-ppc":
            for i in range(3):
                axs[0].plot(tt, rr["delta2"][:, i], lw=0.9, label=f"delta_2,{'xyz'[i]}")
                axs[0].plot(tt, rr["z2"][:, i], "--", lw=0.9, label=f"z2,{'xyz'[i]}")
        err = np.max(np.abs(rr["z2"] - rr["delta2"]), axis=1)
        axs[1].semilogy(tt, err + 1e-300, color=COLORS[law], lw=0.9,
                        label=f"{LAW_LABEL[law]}: max_i |z2 - delta_2|")
    if with_claim:
        axs[1].axhline(OBSERVER_THRESHOLD, color="k", ls=":", lw=0.8, label="claim 2e-6 after 30 s")
    axs[0].set_ylim(-1.0, 1.0)
    axs[0].set_ylabel("DSC+PPC [rad/s^2]")
    axs[0].set_title(f"Lumped disturbance delta_2 and observer estimate z2, {tag}")
    axs[0].legend(fontsize=7, ncol=3)
    axs[1].set_ylabel("observer error [rad/s^2]")
    axs[1].set_xlabel("t [s]")
    axs[1].legend(fontsize=7)
    for ax in axs:
        ax.grid(alpha=0.3, which="both")
    return fig
