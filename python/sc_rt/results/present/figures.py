"""Paper-style figures of a run (matplotlib, Agg backend, PNG) and
``save_figure``, which writes every figure of results/present/; the marks
the time plots share (titles, events, limit lines) are figure_marks.py's."""

from __future__ import annotations

from pathlib import Path
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sc_rt.results.judge.metrics import LAWS_WITH_OBSERVER, prescribed_chi  # noqa: E402
from sc_rt.results.present.figure_marks import (  # noqa: E402
    _legend_outside, _two_line, fault_onsets, limit_lines, mark_events, shows_envelope)
from sc_rt.results.record.jsonsafe import atomic_path  # noqa: E402
from sc_rt.results.record.run import Run  # noqa: E402

__all__ = ["tracking_figures", "timing_figures", "fault_figure", "estimation_figure", "save_figure", "has_observer"]

AXES = ("x", "y", "z")


def save_figure(fig, path: Path, dpi: int = 110) -> Path:
    """Lay a figure out, write it to ``path`` (PNG at ``dpi``, whole or not at
    all: a full disk leaves no truncated figure) and close it; returns ``path``."""
    try:
        fig.tight_layout()
        with atomic_path(Path(path)) as part:
            fig.savefig(part, dpi=dpi, format="png")
    finally:
        plt.close(fig)
    return path


def has_observer(run: Run) -> bool:
    """The run's law has a disturbance observer to draw: a law known to have
    one, or a z2 that is not all zero or missing."""
    return run.meta.law in LAWS_WITH_OBSERVER or bool(np.any(np.nan_to_num(run["z2"]) != 0.0))


def tracking_figures(run: Run, out: Path, title: str = "") -> list[Path]:
    """Attitude error (linear and log), pointing error in arcsec, rate
    error, wheel commands per wheel with the limits, lumped disturbance and
    the observer's error (the paper's figures 4-15; only for a law with an
    observer, ``has_observer``), and the faults when there are any. The
    errors are the true ones (the truth against the reference), a law fed
    the estimate its own beside them. Every time plot marks fault onsets and
    SAFE spans. Where the scenario asks for the prescribed envelope
    (``shows_envelope``), its bounds are drawn and its first violation
    marked. The envelope and the wheel limits come from ``run.meta``."""
    from sc_rt.results.judge.estimation import ARCSEC, flies_on_estimate, true_error_fields
    from sc_rt.results.judge.verdict import pointing_arcsec

    out.mkdir(parents=True, exist_ok=True)
    t = run["t"]
    ppc = run.meta.ppc
    chi = prescribed_chi(ppc, t)
    dmin, dmax = np.asarray(ppc["dmin"]), np.asarray(ppc["dmax"])
    # the true errors (the truth against the reference: with sensors the derived fields), and the
    # law's own beside them when it was fed the estimate (what it computed from it)
    sensed = _sensed(run)
    sig_name, rate_name = true_error_fields(sensed)
    sig = run[sig_name]
    law = run["sigma_BD"] if sensed and flies_on_estimate(run.meta) else None
    paths = []
    env = shows_envelope(run)  # the envelope only where the scenario asks for it

    fig, axs = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for i, ax in enumerate(axs):
        ax.plot(t, sig[:, i], label=f"sigma_BD,{AXES[i]} (true)")
        if law is not None:
            ax.plot(t, law[:, i], color="0.6", lw=0.7, label=f"sigma_BD,{AXES[i]} (the law's, its estimate)")
        if env:
            ax.plot(t, dmax[i] * chi[:, i], "r--", lw=0.8, label="dmax chi(t)")
            ax.plot(t, -dmin[i] * chi[:, i], "r:", lw=0.8, label="-dmin chi(t)")
        mark_events(ax, run, labels=i == 0)
        ax.set_ylabel(f"sigma_BD,{AXES[i]} [-]")
        ax.grid(alpha=0.3)
    _legend_outside(axs[0])
    axs[0].set_title(_two_line("True attitude tracking error (MRP)" + (" and prescribed bounds" if env else ""),
                               run, title))
    axs[-1].set_xlabel("t [s]")
    paths.append(save_figure(fig, out / "attitude_error.png"))

    fig, axs = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for i, ax in enumerate(axs):
        ax.semilogy(t, np.abs(sig[:, i]) + 1e-300, label=f"|sigma_BD,{AXES[i]}| (true)")
        if law is not None:
            ax.semilogy(t, np.abs(law[:, i]) + 1e-300, color="0.6", lw=0.7, label="the law's (its estimate)")
        if env:
            ax.semilogy(t, dmax[i] * chi[:, i], "r--", lw=0.8, label="dmax chi(t) (bound for > 0)")
            if dmin[i] != dmax[i]:
                ax.semilogy(t, dmin[i] * chi[:, i], "m:", lw=0.9, label="dmin chi(t) (bound for < 0)")
        ax.set_ylabel(f"|sigma_BD,{AXES[i]}| [-]")
        floor = np.nanmin(chi) if env and chi.size else _positive_floor(sig)
        ax.set_ylim(max(1e-12, floor * 1e-3), 1.0)
        ax.grid(alpha=0.3, which="both")
        viol = ~run["bound_ok"][:, i]
        if env and np.any(viol):
            ax.plot(t[viol], np.abs(sig[viol, i]) + 1e-300, "k.", ms=2, label="outside the bound")
        mark_events(ax, run, labels=i == 0)
        _legend_outside(ax)
    axs[0].set_title(_two_line("True attitude tracking error, log scale", run, title))
    axs[-1].set_xlabel("t [s]")
    paths.append(save_figure(fig, out / "attitude_error_log.png"))

    fig, ax = plt.subplots(figsize=(9, 4))
    ang = pointing_arcsec(sig)
    corner = pointing_arcsec(dmax * chi)  # the angle of the envelope's corner (all axes at dmax chi)
    ax.semilogy(t, ang + 1e-300, lw=0.9, label="true pointing error 4 atan|sigma_BD|")
    if law is not None:
        ax.semilogy(t, pointing_arcsec(law) + 1e-300, lw=0.9, label="the law's (its estimate)")
    if sensed:  # the estimate against the truth: the rotation angle of att_est_error
        ax.semilogy(t, np.linalg.norm(run["att_est_error"], axis=1) / ARCSEC + 1e-300, lw=0.7,
                    label="knowledge error (the estimate against the truth)")
    if env:
        ax.semilogy(t, corner, "r--", lw=0.8, label="envelope corner 4 atan|dmax chi(t)|")
    _pointing_bounds(ax, run)
    mark_events(ax, run, labels=True)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("pointing error [arcsec]")
    ax.grid(alpha=0.3, which="both")
    _legend_outside(ax)
    ax.set_title(_two_line("True pointing error", run, title))
    paths.append(save_figure(fig, out / "pointing_error.png"))

    fig, ax = plt.subplots(figsize=(9, 4))
    for i in range(3):
        ax.plot(t, run[rate_name][:, i], label=f"omega_BD_B,{AXES[i]} (true)")
    if law is not None:
        for i in range(3):
            ax.plot(t, run["omega_BD_B"][:, i], ls=":", lw=0.8, color=f"C{i}",
                    label=f"omega_BD_B,{AXES[i]} (the law's, its estimate)")
    mark_events(ax, run, labels=True)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("rate error [rad/s]")
    ax.set_title(_two_line("True angular-rate tracking error", run, title))
    ax.grid(alpha=0.3)
    _legend_outside(ax)
    paths.append(save_figure(fig, out / "rate_error.png"))

    fig, axs = plt.subplots(4, 1, figsize=(9, 8), sharex=True)
    umin, umax = np.asarray(run.meta.umin), np.asarray(run.meta.umax)
    unit, torque = run.meta.unit("u_sat"), run.meta.torque_wheels  # what the wheels take
    for w, ax in enumerate(axs):
        ax.plot(t, run["u_sat"][:, w], lw=0.9, label="command after saturation")
        data = run["u_sat"][:, w]
        if np.any(np.isfinite(run["wheel_accel"][:, w])):
            if torque:  # the actual acceleration on its own axis: another unit than the command's
                twin = ax.twinx()
                twin.plot(t, run["wheel_accel"][:, w], lw=0.7, ls="--", color="C1")
                twin.set_ylabel(f"actual accel\n[{run.meta.unit('wheel_accel')}]", fontsize=8)
            else:
                ax.plot(t, run["wheel_accel"][:, w], lw=0.7, ls="--", label="actual (faults applied)")
                data = np.concatenate([data, run["wheel_accel"][:, w]])
        limit_lines(ax, data, [(umax[w], "limits"), (umin[w], "limits")])  # the data's scale, not the limits'
        mark_events(ax, run, labels=w == 0)
        ax.set_ylabel(f"wheel {w + 1}\n[{unit}]")
        ax.grid(alpha=0.3)
    _legend_outside(axs[0])
    kind = "torque" if torque else "acceleration"
    axs[0].set_title(_two_line(f"Wheel {kind} commands, one axis per wheel", run, title))
    axs[-1].set_xlabel("t [s]")
    paths.append(save_figure(fig, out / "wheel_commands.png"))

    if has_observer(run):
        paths.append(_observer_figure(run, out, title))
    if fault_onsets(run) or np.any(np.isfinite(run["fault_Y"])):
        paths.append(fault_figure(run, out, title))
    if sensed:
        paths.append(estimation_figure(run, out, title))
    return paths


def _positive_floor(x: np.ndarray) -> float:
    """The smallest positive finite |x| (1e-9 when there is none): a log axis's floor from the data."""
    a = np.abs(np.asarray(x, float))
    a = a[np.isfinite(a) & (a > 0)]
    return float(a.min()) if a.size else 1e-9


def _observer_figure(run: Run, out: Path, title: str) -> Path:
    """disturbance_observer.png: the lumped disturbance, the observer's estimate z2 and its error."""
    t = run["t"]
    fig, axs = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for i in range(3):
        axs[0].plot(t, run["delta2"][:, i], label=f"delta_2,{AXES[i]} (true)")
        axs[0].plot(t, run["z2"][:, i], "--", label=f"z2,{AXES[i]} (observer)")
    axs[0].set_ylabel("[rad/s^2]")
    axs[0].set_title(_two_line("Lumped disturbance and its estimate", run, title))
    axs[0].grid(alpha=0.3)
    mark_events(axs[0], run, labels=True)
    _legend_outside(axs[0], ncol=1)
    err = np.abs(run["z2"] - run["delta2"])
    for i in range(3):
        axs[1].semilogy(t, err[:, i] + 1e-300, label=f"|z2 - delta_2|,{AXES[i]}")
    mark_events(axs[1], run)
    axs[1].set_ylabel("observer error [rad/s^2]")
    axs[1].set_xlabel("t [s]")
    axs[1].grid(alpha=0.3, which="both")
    _legend_outside(axs[1])
    return save_figure(fig, out / "disturbance_observer.png")


def _pointing_bounds(ax, run: Run) -> None:
    """The bounds of the APE requirements on the full angle or a cone, in
    arcsec, over their spans (requirements.png draws every requirement)."""
    from sc_rt.scenario.tables.requirements import ANGLE_UNITS

    results = {r["name"]: r for r in run.metrics.get("requirements") or []}
    for j, q in enumerate(q for q in getattr(run.meta, "requirements", ()) or ()
                          if q["kind"] == "APE" and q.get("axis") in ("norm", "cone")):
        span = results.get(q["name"], {}).get("span_s")
        if span:
            b = q["bound"] * ANGLE_UNITS[q["unit"]] / ANGLE_UNITS["arcsec"]
            ax.hlines(b, span[0], span[1], color=f"C{2 + j}", ls="-.", lw=1.0,
                      label=f"{q['name']}: APE {q['axis']} bound {b:.4g} arcsec")


def _sensed(run: Run) -> bool:
    return bool(getattr(run.meta, "sensors", False)) and bool(run.present("sigma_BN_est").any())


def estimation_figure(run: Run, out: Path, title: str = "") -> Path:
    """estimation.png: the MEKF's attitude error per axis with its 3-sigma, and the bias error."""
    arcsec = np.pi / 180 / 3600
    t = run["t"]
    fig, axs = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    err, sd = run["att_est_error"] / arcsec, np.sqrt(run["P_diag"][:, 0:3]) / arcsec
    for i in range(3):
        line, = axs[0].plot(t, err[:, i], lw=0.7, label=f"dtheta_{AXES[i]}")
        axs[0].plot(t, 3 * sd[:, i], ":", lw=0.8, color=line.get_color())
        axs[0].plot(t, -3 * sd[:, i], ":", lw=0.8, color=line.get_color())
    axs[0].set_ylabel("estimation error [arcsec]\n(dotted: +-3 sigma)")
    axs[0].set_title(_two_line("Attitude estimation error (MEKF) and gyro bias error", run, title))
    axs[0].grid(alpha=0.3)
    mark_events(axs[0], run, labels=True)
    _legend_outside(axs[0])
    deg_h = np.pi / 180 / 3600
    for i in range(3):
        axs[1].plot(t, (run["bias_est"][:, i] - run["bias_true"][:, i]) / deg_h, lw=0.8,
                    label=f"b_est - b_true, {AXES[i]}")
    axs[1].set_ylabel("bias error [deg/h]")
    axs[1].set_xlabel("t [s]")
    axs[1].grid(alpha=0.3)
    _legend_outside(axs[1])
    return save_figure(fig, out / "estimation.png")


def scheduled_fault_state(run: Run) -> dict[str, np.ndarray]:
    """Y(t) (19), effectiveness, bias and stuck per wheel at the run's rows,
    from the run's own truth when it has it, else from the scheduled faults."""
    t = run["t"]
    if np.any(np.isfinite(run["fault_Y"])):
        return {k: run[k] for k in ("fault_Y", "fault_effectiveness", "fault_bias", "fault_stuck")}
    n = len(t)
    Y, L, B, K = np.zeros((n, 4)), np.ones((n, 4)), np.zeros((n, 4)), np.zeros((n, 4), np.int64)
    for f in run.meta.faults:
        w = f["wheel"] - 1
        on = (t >= f["onset"]) & (True if f["end"] is None else (t < f["end"]))
        Y[on, w] = 1.0 - np.exp(-f["rate"] * (t[on] - f["onset"]))
        L[on, w], B[on, w], K[on, w] = f["effectiveness"], f["bias"], int(f["stuck"])
    return {"fault_Y": Y, "fault_effectiveness": L, "fault_bias": B, "fault_stuck": K}


def fault_figure(run: Run, out: Path, title: str = "") -> Path:
    """Per wheel: the commanded and the actual acceleration, and the fault
    state (effectiveness L, activation Y, stuck spans, bias); red dashed at
    each onset."""
    t = run["t"]
    fs = scheduled_fault_state(run)
    fig, axs = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    for w, ax in enumerate(axs):
        if run.meta.torque_wheels:  # the command as a free wheel's acceleration, a = torque / Jw
            ax.plot(t, run["u_sat"][:, w] / run.meta.Jw[w], color="0.6", ls=":", lw=1.0,
                    label="command (saturated) / Jw")
        else:
            ax.plot(t, run["u_sat"][:, w], color="0.6", ls=":", lw=1.0, label="command (saturated)")
        ax.plot(t, run["wheel_accel"][:, w], color="C0", lw=0.9, label="actual")
        ax.set_ylabel("[rad/s^2]")
        ax2 = ax.twinx()
        ok = np.isfinite(fs["fault_effectiveness"][:, w])
        ax2.plot(t[ok], fs["fault_effectiveness"][ok, w], color="C2", lw=1.2, label="L")
        ax2.plot(t[ok], fs["fault_Y"][ok, w], color="C3", ls="--", lw=1.0, label="Y(t)")
        ax2.set_ylim(-0.05, 1.1)
        ax2.set_ylabel("L, Y [-]")
        stuck = fs["fault_stuck"][:, w].astype(bool)
        if np.any(stuck):
            ax.fill_between(t, 0, 1, where=stuck, transform=ax.get_xaxis_transform(), color="k",
                            alpha=0.12, label="stuck")
        bias = fs["fault_bias"][:, w]
        bias = bias[np.isfinite(bias)]
        bmax = float(bias[np.argmax(np.abs(bias))]) if bias.size else 0.0
        ax.set_title(f"wheel {w + 1}" + (f" (bias up to {bmax:+g} rad/s^2)" if bmax else ""),
                     fontsize=9, loc="left")
        for onset, wheel in fault_onsets(run):
            if wheel == w + 1:
                ax.axvline(onset, color="r", lw=0.9, ls="--")
        ax.grid(alpha=0.3)
        if w == 0:
            h1, l1 = ax.get_legend_handles_labels()
            h2, l2 = ax2.get_legend_handles_labels()
            ax.legend(h1 + h2, l1 + l2, fontsize=7, ncol=5, loc="lower left", bbox_to_anchor=(0.0, 1.12))
    axs[-1].set_xlabel("t [s]")
    fig.suptitle(_two_line("Wheel faults (red dashed: onset)", run, title), fontsize=10)
    return save_figure(fig, out / "faults.png", dpi=100)


def timing_figures(run: Run, out: Path, floor: dict | None = None) -> list[Path]:
    """The bench's timing over time and as histograms: state-to-command
    latency, controller compute and (real time only) the controller's wake
    lateness and the emulator's tick lateness. The control period is drawn,
    and the bench floor (``floor``: {series: p99 [us]}; by default the
    ``floor`` of ``run.timing``, hil/floor.py) when there is one, with the
    line "bench floor p99 X us; this controller added Y us" in the title."""
    out.mkdir(parents=True, exist_ok=True)
    timing = run.timing or {}
    if floor is None and timing.get("floor"):
        floor = {k: (v or {}).get("p99") for k, v in timing["floor"].items()
                 if k.endswith("_us") and isinstance(v, dict) and "p99" in v}
    t = run["t"]
    period_us = 1e6 / run.meta.control_rate_hz
    series = {"state-to-command latency [us]": "latency_us", "controller compute [us]": "compute_us"}
    if run.meta.mode == "realtime":
        series["controller wake lateness [us]"] = "wake_lateness_us"
        series["emulator tick lateness [us]"] = "tick_lateness_us"
    # no empty panels: a series with no positive value (an event-triggered
    # controller has no wake-up to be late for) has nothing to draw on a log axis
    series = {k: v for k, v in series.items() if np.any(np.asarray(run[v], float) > 0)}
    if not series:
        series = {"state-to-command latency [us]": "latency_us"}
    fig, axs = plt.subplots(len(series), 2, figsize=(11, 2.6 * len(series) + 1), squeeze=False,
                            gridspec_kw={"width_ratios": [2, 1]})
    for row, (name, key) in zip(axs, series.items()):
        v = np.asarray(run[key], float)
        ok = np.isfinite(v)
        row[0].plot(t[ok], v[ok], lw=0.5)
        row[0].axhline(period_us, color="r", ls="--", lw=0.8, label=f"period {period_us:g} us")
        if floor and floor.get(key) is not None:
            row[0].axhline(floor[key], color="g", ls=":", lw=0.9, label=f"bench floor p99 {floor[key]:.3g} us")
        row[0].set_yscale("log")
        row[0].set_xlabel("t [s]")
        row[0].set_ylabel(name)
        row[0].legend(fontsize=7, loc="upper right")
        if np.any(ok):
            row[1].hist(v[ok], bins=80)
            row[1].set_yscale("log")
        row[1].set_xlabel(name)
        row[1].set_ylabel("count")
        for a in row:
            a.grid(alpha=0.3)
    what = f"Bench timing, {run.meta.mode}, {run.meta.control_rate_hz:g} Hz"
    if timing.get("trigger") and run.meta.mode == "realtime":
        what += f", {timing['trigger']}-triggered controller"
    if timing.get("scheduler"):
        what += f", {timing['scheduler']}"
    title = _two_line(what, run)
    if (timing.get("over_floor") or {}).get("line"):
        title += "\n" + timing["over_floor"]["line"]
    axs[0][0].set_title(title, fontsize=9, loc="left")
    return [save_figure(fig, out / "timing.png")]
