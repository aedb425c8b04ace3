"""magnetic_control.png: the controller's magnetic part over a run (issue 43
item 8; docs/MODEL.md section 17): the wheels' momentum |h_wheels_B| and the
momentum manager's fill with its on/off band and unloading state, the rod
dipole commands with their limits and, where a fault made a rod's applied
dipole (the record's ``rod_dipole``) differ from its clipped command, the
applied one dashed beside it, B-dot's mode when it ran, and the rods'
faults, scheduled and live (results/present/rod_faults.py), each marked
"rod N" on every panel. Units come from the run (``RunMeta.unit``), the band
and limits from ``RunMeta.magnetic``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sc_rt.results.present.figure_marks import mark_events, run_title
from sc_rt.results.present.figures import save_figure
from sc_rt.results.present.rod_faults import RodFaultSpan, rod_fault_spans
from sc_rt.results.record.run import Run

__all__ = ["magnetic_figure", "magnetic_series", "has_magnetic_control", "FILE", "HOURS_AFTER_S"]

#: the figure's file name
FILE = "magnetic_control.png"
#: [s] a run longer than this is drawn against hours
HOURS_AFTER_S = 3.0 * 3600.0


def has_magnetic_control(run: Run) -> bool:
    """The run had magnetic control: its record's rod commands are not all NaN."""
    return "rod_dipole_cmd" in run and bool(np.isfinite(np.asarray(run["rod_dipole_cmd"], float)).any())


def magnetic_series(run: Run) -> dict:
    """What the figure draws, from the record and its meta.

    Returns
    -------
    dict
        "t" (the time axis in "t_unit": "s", or "h" for a run longer than
        ``HOURS_AFTER_S``), "h_norm" (|h_wheels_B| per row, in "h_unit"),
        "fill" [-], "unloading" (1 on, 0 off, -1 none), "band" (the
        manager's on/off fractions [-] and the same in "h_unit", or None),
        "dipole" (the rods' commands (rows, n_rods) in "dipole_unit"),
        "limits" (per rod, or ()), "applied" (the rods' applied dipoles
        (rows, n_rods) in "dipole_unit", NaN for a rod whose applied dipole
        equals its clipped command on every row; None when every rod's does),
        "detumble" (0/1 per row, or None when
        B-dot did not run), "rod_faults" (``RodFaultSpan`` of the rods,
        scheduled in ``RunMeta.rod_faults`` and live in
        ``Run.faults_applied``; their times in s).
    """
    meta, mag = run.meta, dict(run.meta.magnetic or {})
    t = np.asarray(run["t"], float)
    hours = t.size > 0 and t[-1] > HOURS_AFTER_S
    h = np.asarray(run["h_wheels_B"], float)
    limits = tuple(mag.get("rod_max_dipole") or ())
    d = np.asarray(run["rod_dipole_cmd"], float)
    n_rods = len(limits) or int(np.sum(np.any(np.isfinite(d) & (d != 0.0), axis=0))) or d.shape[1]
    applied = np.asarray(run["rod_dipole"], float)[:, :n_rods].copy()
    clipped = np.clip(d[:, :n_rods], -np.asarray(limits), np.asarray(limits)) if limits else d[:, :n_rods]
    same = np.all((applied == clipped) | np.isnan(applied), axis=0)  # no fault acted on the rod
    applied[:, same] = np.nan
    mom = mag.get("momentum")
    band = None
    if mom:
        on, off, cap = mom["on_fraction"], mom["off_fraction"], mom["capacity"]
        band = {"on_fraction": on, "off_fraction": off, "on_h": on * cap, "off_h": off * cap}
    det = np.asarray(run["detumble_mode"])
    return {"t": t / 3600.0 if hours else t, "t_unit": "h" if hours else "s",
            "h_norm": np.linalg.norm(h, axis=1), "h_unit": meta.unit("h_wheels_B"),
            "fill": np.asarray(run["wheel_fill"], float), "fill_unit": meta.unit("wheel_fill"),
            "unloading": np.asarray(run["unloading"]), "band": band,
            "dipole": d[:, :n_rods], "dipole_unit": meta.unit("rod_dipole_cmd"), "limits": limits,
            "applied": None if same.all() else applied,
            "detumble": det if bool(np.any(det >= 0)) else None,
            "rod_faults": rod_fault_spans(meta.rod_faults, run.faults_applied)}


def _shade(ax, t: np.ndarray, on: np.ndarray, label: str) -> None:
    """Spans where ``on`` (unloading) holds, shaded."""
    edges = np.diff(np.r_[0, on.astype(int), 0])
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    for i, (a, b) in enumerate(zip(starts, ends)):
        ax.axvspan(t[a], t[min(b, t.size - 1)], color="#fdd0a2", alpha=0.5, lw=0, label=label if i == 0 else None)


def _mark_rod_faults(axs: list, dipole_ax, faults: list[RodFaultSpan], t_last: float, scale: float) -> None:
    """Each rod fault within the run: its span hatched in its rod's colour on
    the dipole panel (labelled with what, where from and when), its onset
    (dash-dot) and end (dotted) on every panel; ``scale``: [s] per unit of
    the time axis. Every artist's gid is "rod-fault-N"."""
    for f in faults:
        if f.onset > t_last:
            continue
        a, b = f.onset / scale, (t_last if f.end is None else min(f.end, t_last)) / scale
        colour, gid = f"C{(f.rod - 1) % 10}", f"rod-fault-{f.rod}"
        dipole_ax.axvspan(a, b, fill=False, hatch="//", edgecolor=colour, alpha=0.4, lw=0, label=f.text(), gid=gid)
        for ax in axs:
            ax.axvline(a, color=colour, ls="-.", lw=1.0, gid=gid)
            if f.end is not None and f.end <= t_last:
                ax.axvline(b, color=colour, ls=":", lw=1.0, gid=gid)


def magnetic_figure(run: Run, out: Path, title: str = "") -> Path | None:
    """magnetic_control.png in ``out``: |h_wheels| with the manager's band,
    its fill, the rod dipole commands with their limits (and B-dot's mode
    when it ran); unloading spans shaded; the rods' faults marked. None
    without magnetic control."""
    import matplotlib.pyplot as plt

    if not has_magnetic_control(run):
        return None
    s = magnetic_series(run)
    t, unl = s["t"], s["unloading"] == 1
    manager = bool(np.isfinite(s["h_norm"]).any())  # the momentum manager ran (else: B-dot alone)
    n = 1 + 2 * manager + (s["detumble"] is not None)
    fig, axs = plt.subplots(n, 1, figsize=(9, 2.3 * n + 1.0), sharex=True, squeeze=False)
    axs = list(axs[:, 0])
    rest = list(axs)
    if manager:
        ax, ax2 = rest.pop(0), rest.pop(0)
        ax.plot(t, s["h_norm"], lw=1, label="|h_wheels_B|")
        ax2.plot(t, s["fill"], lw=1, color="C1", label="fill")
        if s["band"] is not None:
            ax.axhline(s["band"]["on_h"], ls="--", lw=0.8, color="C3", label="unloading on")
            ax.axhline(s["band"]["off_h"], ls=":", lw=0.8, color="C2", label="unloading off")
            ax2.axhline(s["band"]["on_fraction"], ls="--", lw=0.8, color="C3")
            ax2.axhline(s["band"]["off_fraction"], ls=":", lw=0.8, color="C2")
        ax.set_ylabel(f"|h_wheels| [{s['h_unit']}]")
        ax2.set_ylabel(f"fill [{s['fill_unit']}]")
        for a in (ax, ax2):
            _shade(a, t, unl, "unloading")
    ax3 = rest.pop(0)
    for j in range(s["dipole"].shape[1]):
        line, = ax3.plot(t, s["dipole"][:, j], lw=0.9, label=f"rod {j + 1}")
        if s["applied"] is not None and np.isfinite(s["applied"][:, j]).any():
            ax3.plot(t, s["applied"][:, j], lw=1.2, ls="--", color=line.get_color(), label=f"rod {j + 1} applied",
                     gid=f"rod-applied-{j + 1}")
        if j < len(s["limits"]):
            for sign in (1.0, -1.0):
                ax3.axhline(sign * s["limits"][j], ls="--", lw=0.6, color=line.get_color())
    ax3.set_ylabel(f"rod dipole [{s['dipole_unit']}]")
    if s["detumble"] is not None:
        ax4 = rest.pop(0)
        ax4.step(t, s["detumble"], where="post", lw=1)
        ax4.set_yticks([0, 1], ["detumble", "attitude"])
        ax4.set_ylabel("B-dot mode")
    if t.size:
        _mark_rod_faults(axs, ax3, s["rod_faults"], float(run["t"][-1]), 3600.0 if s["t_unit"] == "h" else 1.0)
    for a in axs:
        a.grid(alpha=0.3)
        if a.get_legend_handles_labels()[0]:
            a.legend(loc="upper right", fontsize=8, ncol=3)
        if s["t_unit"] == "s":
            mark_events(a, run)
    axs[-1].set_xlabel(f"t [{s['t_unit']}]")
    head = ("Wheel momentum, the momentum manager and the rod dipoles (shaded: unloading)" if manager
            else "The rod dipoles and B-dot's mode")
    if s["rod_faults"]:
        head += "\nrod faults hatched in the rod's colour: dash-dot onset, dotted end"
    axs[0].set_title(f"{head}\n{title or run_title(run)}", fontsize=10)
    path = save_figure(fig, Path(out) / FILE)
    plt.close(fig)
    return path
