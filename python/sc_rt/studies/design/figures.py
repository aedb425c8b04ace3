"""Figures of ``sc-rt design``: Bode and Nichols plots of the PD loops, the spectral radius over t."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.scenario.model import Scenario
from sc_rt.studies.design.linear import AXES, INERTIAS
from sc_rt.studies.design.margins import CASES, axis_loop, frequency_response
from sc_rt.studies.design.pd import PdDesign
from sc_rt.studies.design.sampled import spectral_radius

__all__ = ["plot_loops", "plot_spectral"]


def plot_loops(scn: Scenario, pd: PdDesign, rate: float, latency: float, out: Path) -> list[Path]:
    """bode.png and nichols.png: every PD loop of :func:`pd_margins`, per axis, in out/."""
    from sc_rt.results.present.figures import save_figure  # sets the Agg backend

    import matplotlib.pyplot as plt

    styles = {"continuous": "C0", "zoh": "C1", "zoh+delay": "C2", "pade": "C3"}
    loops = {}
    for inertia in INERTIAS:
        for case in CASES:
            for i in range(3):
                loops[inertia, case, i] = axis_loop(scn, pd.beta1, pd.beta2, i, case=case, rate=rate,
                                                    inertia=inertia, latency=latency)
    w = np.logspace(-3, math.log10(math.pi * rate), 800)
    resp = {k: frequency_response(L, w) for k, L in loops.items()}
    paths = []
    fig, axs = plt.subplots(2, 3, figsize=(13, 6.5), sharex=True)
    for (inertia, case, i), H in resp.items():
        ls = "-" if inertia == "nominal" else "--"
        lab = f"{case}, {inertia}" if i == 0 else None
        axs[0, i].semilogx(w, 20 * np.log10(np.abs(H)), ls, color=styles[case], lw=1, label=lab)
        axs[1, i].semilogx(w, np.degrees(np.unwrap(np.angle(H))) - 360 * (np.angle(H[0]) > 0),
                           ls, color=styles[case], lw=1)
    for i in range(3):
        axs[0, i].axhline(0, color="k", lw=0.6)
        axs[1, i].axhline(-180, color="k", lw=0.6)
        axs[0, i].set_title(f"axis {AXES[i]}: L = (beta2 s + beta1/4) M_ii / s^2")
        axs[1, i].set_xlabel("w [rad/s]")
        for ax in axs[:, i]:
            ax.grid(alpha=0.3, which="both")
    axs[0, 0].set_ylabel("|L| [dB]")
    axs[1, 0].set_ylabel("arg L [deg]")
    axs[0, 0].legend(fontsize=7)
    fig.suptitle(f"{scn.name}: PD loop at a time, beta1 = {pd.beta1:.4g}, beta2 = {pd.beta2:.4g}, "
                 f"{rate:g} Hz, latency {latency * 1e3:g} ms (pade)")
    paths.append(save_figure(fig, out / "bode.png"))

    fig, axs = plt.subplots(1, 3, figsize=(14, 4.8))
    for (inertia, case, i), H in resp.items():
        ls = "-" if inertia == "nominal" else "--"
        ph = np.degrees(np.unwrap(np.angle(H))) - 360 * (np.angle(H[0]) > 0)
        axs[i].plot(ph, 20 * np.log10(np.abs(H)), ls, color=styles[case], lw=1,
                    label=f"{case}, {inertia}" if i == 0 else None)
    for i in range(3):
        axs[i].plot([-180], [0], "rx", ms=9)
        axs[i].set_xlim(-270, -60)
        axs[i].set_ylim(-60, 60)
        axs[i].set_xlabel("arg L [deg]")
        axs[i].set_title(f"Nichols, axis {AXES[i]}")
        axs[i].grid(alpha=0.3)
    axs[0].set_ylabel("|L| [dB]")
    axs[0].legend(fontsize=7)
    paths.append(save_figure(fig, out / "nichols.png"))
    return paths


def plot_spectral(scn: Scenario, report: dict[str, Any], out: Path) -> Path:
    """spectral_radius.png: rho(t) of the sampled DSC+PPC loop per rate, chi(t) and the critical chi."""
    from sc_rt.results.present.figures import save_figure  # sets the Agg backend

    import matplotlib.pyplot as plt

    sd = report["sampled_data"]
    kw = dict(inertia=sd["inertia"], faults=sd["faults"], observer=sd["observer"])
    rate = report["rate_hz"]
    limits = sd["limits"]["dsc-ppc"]
    horizon = scn.run.duration
    ts = np.linspace(0.0, horizon, 601)
    fig, axs = plt.subplots(2, 1, figsize=(9, 7.5), sharex=True)
    for j, (key, lim) in enumerate(sorted(limits.items(), key=lambda kv: float(kv[0]))):
        f = float(key)
        rho = spectral_radius(scn, "dsc-ppc", f, ts, **kw)
        lw = 2.0 if f == rate else 1.0
        axs[0].semilogy(ts, rho, color=f"C{j}", lw=lw, label=f"DSC+PPC, {f:g} Hz")
        if lim["t_loss_s"] is not None:
            axs[0].axvline(lim["t_loss_s"], color=f"C{j}", ls=":", lw=0.8)
            axs[0].annotate(f"{lim['t_loss_s']:.1f} s", (lim["t_loss_s"], 1.0), xytext=(3, -12 - 10 * j),
                            textcoords="offset points", color=f"C{j}", fontsize=8)
        rho_dsc = sd["limits"]["dsc"][key]["rho_at_0"]
        axs[0].axhline(rho_dsc, color=f"C{j}", ls="--", lw=0.6)
    axs[0].axhline(1.0, color="k", lw=0.8)
    axs[0].set_ylim(0.9, 1e3)
    axs[0].set_ylabel("spectral radius of the sampled loop")
    axs[0].set_title(f"{scn.name}: linearised sampled loop, r frozen at chi(t) "
                     f"(dashed: DSC without PPC)")
    axs[0].legend(fontsize=8)
    axs[0].grid(alpha=0.3, which="both")
    p = scn.controller.ppc
    chi = (p.chi0 - p.chiinf) * np.exp(-np.outer(ts, p.gamma)) + p.chiinf
    lim = limits[f"{rate:g}"]
    for i in range(3):
        axs[1].semilogy(ts, chi[:, i], color=f"C{i}", label=f"chi_{AXES[i]}(t)")
        if lim["chi_crit"] is not None:
            axs[1].axhline(lim["chi_crit"][i], color=f"C{i}", ls="--", lw=0.8,
                           label=f"critical chi_{AXES[i]} at {rate:g} Hz")
    axs[1].set_xlabel("t [s]")
    axs[1].set_ylabel("chi [-]")
    axs[1].legend(fontsize=8, ncol=2)
    axs[1].grid(alpha=0.3, which="both")
    return save_figure(fig, out / "spectral_radius.png")

