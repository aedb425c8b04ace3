"""Root cause: the sampled loop's spectral radius against the simulated runs
(fault-free scenario, DSC+PPC), ``root_cause.png`` and the numbers behind it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.results.judge.metrics import prescribed_chi
from sc_rt.scenario.model import Scenario
from sc_rt.sim.engines import simulate
from sc_rt.studies.reproduce.cases import CASES, load_cases, scenario_label
from sc_rt.studies.reproduce.figures import DPI

__all__ = ["ROOT_CAUSE_RATES", "root_cause", "root_cause_figure"]

ROOT_CAUSE_RATES = (10.0, 100.0, 1000.0)


def root_cause_figure(scn: Scenario, *, engine: str = "cpp") -> tuple[dict[str, Any], Any]:
    """The numbers and the Figure of the root cause for ``scn`` (the fault-free case):
    the spectral radius of the linearised sampled loop (sc_rt.studies.design) over t per
    rate, its predicted loss of stability, the simulated growth onset and first
    violation; chi_x(t) against the critical chi per rate with the runs' |x1|;
    at 10 Hz the commanded wheel accelerations against the limits."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sc_rt.studies import design as D

    times = np.arange(0.0, 60.0 + 1e-9, 0.25)
    info: dict[str, Any] = {"scenario": scenario_label(CASES["fault_free"]), "rates": {}}
    fig, axs = plt.subplots(3, 1, figsize=(8, 9))
    for j, rate in enumerate(ROOT_CAUSE_RATES):
        c = f"C{j}"
        rho = D.spectral_radius(scn, "dsc-ppc", rate, times)
        lim = D.stability_limit(scn, "dsc-ppc", rate, horizon=60.0)
        res = simulate(scn, law="dsc-ppc", engine=engine, control_rate_hz=rate, duration=60.0)
        sim = D.simulated_loss_of_stability(scn, "dsc-ppc", rate, result=res)
        info["rates"][f"{rate:g}"] = {
            "t_loss_predicted_s": lim.t_loss_s, "axis": lim.axis, "mode_hz": lim.mode_hz,
            "r_crit": lim.r_crit, "r_crit_rule": lim.r_crit_rule_of_thumb, "chi_crit": lim.chi_crit,
            "growth_onset_s": sim["onset_s"], "lam_at_onset": sim["lam_at_onset"],
            "saturated_at_onset": sim["saturated_at_onset"],
            "first_bound_violation_s": sim["first_bound_violation_s"],
            "first_bound_violation_axis": sim["first_bound_violation_axis"]}
        axs[0].plot(times, rho, color=c, label=f"{rate:g} Hz")
        if lim.t_loss_s is not None:
            axs[0].axvline(lim.t_loss_s, color=c, ls=":", lw=0.9)
        on = sim["onset_s"][0]
        if on is not None and sim["saturated_at_onset"][0] is not None and sim["saturated_at_onset"][0] < 0.5:
            axs[0].plot([on], [1.0], "v", color=c, ms=8)
        if sim["first_bound_violation_s"] is not None:
            axs[0].plot([sim["first_bound_violation_s"]], [1.0], "x", color=c, ms=9, mew=2)
        t = res["t"]
        axs[1].semilogy(t, np.abs(res["sigma_BD"][:, 0]) + 1e-300, color=c, lw=0.7,
                        label=f"|sigma_e,x| at {rate:g} Hz")
        axs[1].axhline(lim.chi_crit[0], color=c, ls="--", lw=0.8)
        if rate == ROOT_CAUSE_RATES[0]:
            u = np.max(np.abs(res["u_cmd"]), axis=1)
            axs[2].semilogy(t, u, color=c, lw=0.8, label="max_i |u_cmd,i| (commanded), 10 Hz")
            p = scn.controller.ppc
            xz, chz = res["sigma_BD"][:, 2], prescribed_chi(p, t)[:, 2]
            ratio = np.where(xz > 0, xz / (p.dmax[2] * chz), -xz / (p.dmin[2] * chz))
            axs[2].semilogy(t, ratio, color="C3", lw=0.8,
                            label="sigma_e,z over its bound (dmax_z chi_z or dmin_z chi_z), 10 Hz")
    tt = np.linspace(0, 60, 601)
    axs[1].semilogy(tt, prescribed_chi(scn.controller.ppc, tt)[:, 0], "k", lw=1.2, label="chi_x(t)")
    axs[0].axhline(1.0, color="k", lw=0.8)
    axs[0].set_ylim(0.9, 1.3)
    axs[0].set_ylabel("spectral radius of the\nsampled loop (linearised)")
    axs[0].set_title("DSC+PPC, fault-free: dotted = predicted loss of stability, "
                     "v = simulated growth onset, x = first bound violation", fontsize=9)
    axs[0].legend(fontsize=8)
    axs[1].set_ylim(1e-10, 1.0)
    axs[1].set_ylabel("[-]")
    axs[1].set_title("chi_x(t) (black) vs the critical chi_x per rate (dashed): unstable below", fontsize=9)
    axs[1].legend(fontsize=7, ncol=2)
    axs[2].axhline(10.0, color="k", ls="--", lw=0.8, label="umax = 10")
    axs[2].axhline(1.0, color="C3", ls=":", lw=0.8, label="bound (ratio 1)")
    axs[2].set_xlim(0, 10)
    axs[2].set_xlabel("t [s]")
    axs[2].set_title("10 Hz: the wheels saturate and sigma_e,z meets its bound at 4.1 s, before the "
                     "linear loss (9.8 s)", fontsize=9)
    axs[2].legend(fontsize=7)
    for ax in axs[:2]:
        ax.set_xlim(0, 60)
    for ax in axs:
        ax.grid(alpha=0.3, which="both")
    return info, fig


def root_cause(out: Path, *, engine: str = "cpp", scenarios: dict[str, Scenario] | None = None,
               dpi: int = DPI) -> dict[str, Any]:
    """``root_cause.png`` in ``out`` (see :func:`root_cause_figure`) and its numbers."""
    from sc_rt.results.present.figures import save_figure

    scns = scenarios if scenarios is not None else load_cases()
    info, fig = root_cause_figure(scns["fault_free"], engine=engine)
    info["figure"] = save_figure(fig, Path(out) / "root_cause.png", dpi).name
    return info
