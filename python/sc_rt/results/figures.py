"""Paper-style figures of a run (matplotlib, Agg backend, PNG)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sc_rt.results.metrics import prescribed_chi  # noqa: E402
from sc_rt.results.run import Run  # noqa: E402

__all__ = ["tracking_figures", "timing_figures"]

AXES = ("x", "y", "z")


def run_title(run: Run) -> str:
    """"scenario, law, engine" of a run, for figure titles."""
    m = run.meta
    how = {"python": "offline", "cpp": "offline (C++ loop)", "unsampled": "unsampled reference",
           "hil-lockstep": "HIL lockstep", "hil-realtime": "HIL real time",
           "report": f"from its log ({m.mode})"}
    return f"{m.scenario}, {m.law}, {how.get(m.engine, m.engine)}"


def save_figure(fig, path: Path, dpi: int = 110) -> Path:
    """Lay a figure out, write it to ``path`` (PNG at ``dpi``) and close it; returns ``path``."""
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def tracking_figures(run: Run, out: Path, title: str = "") -> list[Path]:
    """Attitude error with the prescribed bounds (linear and log), rate error,
    wheel commands with the saturation limits, lumped disturbance and the
    observer's error (the paper's figures 4-15). The envelope and the wheel
    limits come from ``run.meta``."""
    out.mkdir(parents=True, exist_ok=True)
    traj = run
    title = title or run_title(run)
    t = traj["t"]
    ppc = run.meta.ppc
    chi = prescribed_chi(ppc, t)
    dmin, dmax = np.asarray(ppc["dmin"]), np.asarray(ppc["dmax"])
    paths = []

    fig, axs = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for i, ax in enumerate(axs):
        ax.plot(t, traj["sigma_BD"][:, i], label=f"sigma_BD,{AXES[i]}")
        ax.plot(t, dmax[i] * chi[:, i], "r--", lw=0.8, label="dmax chi(t)")
        ax.plot(t, -dmin[i] * chi[:, i], "r--", lw=0.8, label="-dmin chi(t)")
        ax.set_ylabel(f"sigma_BD,{AXES[i]} [-]")
        ax.grid(alpha=0.3)
    axs[0].legend(loc="upper right", fontsize=8)
    axs[0].set_title(f"Attitude tracking error and prescribed bounds {title}")
    axs[-1].set_xlabel("t [s]")
    paths.append(_save(fig, out / "attitude_error.png"))

    fig, axs = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for i, ax in enumerate(axs):
        ax.semilogy(t, np.abs(traj["sigma_BD"][:, i]) + 1e-300, label=f"|sigma_BD,{AXES[i]}|")
        ax.semilogy(t, dmax[i] * chi[:, i], "r--", lw=0.8, label="dmax chi(t) (bound for > 0)")
        if dmin[i] != dmax[i]:
            ax.semilogy(t, dmin[i] * chi[:, i], "m:", lw=0.9, label="dmin chi(t) (bound for < 0)")
        ax.set_ylabel(f"|sigma_BD,{AXES[i]}| [-]")
        ax.set_ylim(max(1e-12, np.nanmin(chi) * 1e-3), 1.0)
        ax.grid(alpha=0.3, which="both")
        viol = ~traj["bound_ok"][:, i]
        if np.any(viol):
            ax.plot(t[viol], np.abs(traj["sigma_BD"][viol, i]) + 1e-300, "k.", ms=2,
                    label="outside the bound")
        ax.legend(loc="upper right", fontsize=7)
    axs[0].set_title(f"Attitude error, log scale {title}")
    axs[-1].set_xlabel("t [s]")
    paths.append(_save(fig, out / "attitude_error_log.png"))

    fig, ax = plt.subplots(figsize=(8, 4))
    for i in range(3):
        ax.plot(t, traj["omega_BD_B"][:, i], label=f"omega_BD_B,{AXES[i]}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("rate error [rad/s]")
    ax.set_title(f"Angular-rate tracking error {title}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    paths.append(_save(fig, out / "rate_error.png"))

    fig, ax = plt.subplots(figsize=(8, 4))
    for i in range(4):
        ax.plot(t, traj["u_sat"][:, i], lw=0.9, label=f"wheel {i + 1}")
    umin, umax = np.asarray(run.meta.umin), np.asarray(run.meta.umax)
    ax.axhline(umax.max(), color="r", ls="--", lw=0.8, label="umax")
    ax.axhline(umin.min(), color="r", ls=":", lw=0.8, label="umin")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("wheel acceleration command [rad/s^2]")
    ax.set_title(f"Wheel commands (after saturation) {title}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=3)
    paths.append(_save(fig, out / "wheel_commands.png"))

    fig, axs = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for i in range(3):
        axs[0].plot(t, traj["delta2"][:, i], label=f"delta_2,{AXES[i]} (true)")
        axs[0].plot(t, traj["z2"][:, i], "--", label=f"z2,{AXES[i]} (observer)")
    axs[0].set_ylabel("[rad/s^2]")
    axs[0].set_title(f"Lumped disturbance and its estimate {title}")
    axs[0].legend(fontsize=7, ncol=2)
    axs[0].grid(alpha=0.3)
    err = np.abs(traj["z2"] - traj["delta2"])
    for i in range(3):
        axs[1].semilogy(t, err[:, i] + 1e-300, label=f"|z2 - delta_2|,{AXES[i]}")
    axs[1].set_ylabel("observer error [rad/s^2]")
    axs[1].set_xlabel("t [s]")
    axs[1].grid(alpha=0.3, which="both")
    axs[1].legend(fontsize=7)
    paths.append(_save(fig, out / "disturbance_observer.png"))
    return paths


def timing_figures(run: Run, out: Path) -> list[Path]:
    """Histograms of the controller's wake lateness and the state-to-command
    latency, and both over time."""
    out.mkdir(parents=True, exist_ok=True)
    lat = run["latency_us"]
    series = {
        "state-to-command latency [us]": lat[np.isfinite(lat)],
        "controller compute [us]": run["compute_us"],
        "controller wake lateness [us]": run["wake_lateness_us"],
    }
    fig, axs = plt.subplots(len(series), 2, figsize=(10, 8))
    for row, (name, v) in zip(axs, series.items()):
        v = np.asarray(v, float)
        ok = v[np.isfinite(v)]
        if ok.size:
            row[0].hist(ok, bins=80)
            row[0].set_yscale("log")
            row[1].plot(np.arange(v.size), v, lw=0.5)
        row[0].set_xlabel(name)
        row[0].set_ylabel("count")
        row[1].set_xlabel("step")
        row[1].set_ylabel(name)
        for a in row:
            a.grid(alpha=0.3)
    return [_save(fig, out / "timing.png")]
