"""The marks every time plot of a run shares: its title (``run_title``; what,
then which run: ``_two_line``), the events on its time axis (fault onsets,
the first bound violation where the scenario asks for the envelope, SAFE
spans, spans without a command: ``mark_events``), limit lines with the y axis
fit to the data (``limit_lines``) and the legend outside the axes. Pure
annotation of matplotlib axes; the figures themselves are drawn and saved by
figures.py and the other figure modules of results/present/."""

from __future__ import annotations

from typing import Any

import numpy as np

from sc_rt.results.judge.verdict import asks_envelope
from sc_rt.results.record.run import Run

__all__ = ["run_title", "fault_onsets", "shows_envelope", "mark_events", "limit_lines", "NEAR"]


def run_title(run: Run) -> str:
    """"scenario, law, engine" of a run, for figure titles."""
    m = run.meta
    how = {"python": "offline", "cpp": "offline (C++ loop)", "unsampled": "unsampled reference",
           "hil-lockstep": "HIL lockstep", "hil-realtime": "HIL real time",
           "report": f"from its log ({m.mode})"}
    return f"{m.scenario}, {m.law}, {how.get(m.engine, m.engine)}"


def _two_line(what: str, run: Run, title: str = "") -> str:
    return f"{what}\n{title or run_title(run)}"


def _safe_mask(run: Run) -> np.ndarray:
    from sc_rt.results.judge.verdict import MODE_SAFE, SAFE_FLAGS

    known = run["ctrl_mode"] >= 0
    return np.where(known, run["ctrl_mode"] == MODE_SAFE, (run["flags"] & sum(SAFE_FLAGS)) != 0)


def _spans(t: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    edge = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    starts, ends = np.nonzero(edge == 1)[0], np.nonzero(edge == -1)[0]
    return [(float(t[a]), float(t[min(b, len(t) - 1)])) for a, b in zip(starts, ends)]


def fault_onsets(run: Run) -> list[tuple[float, int]]:
    """(time, wheel) of every wheel fault onset: scheduled in the scenario or
    injected live (as the emulator applied them; a rod's, ``"rod"``, is not a wheel's)."""
    out = [(float(f["onset"]), int(f["wheel"])) for f in run.meta.faults]
    for f in run.faults_applied:  # the emulator's record, or the commands a log holds
        if f.get("action") != "inject" or f.get("wheel") is None:
            continue
        onset = f.get("t_sim_at_receipt") if f.get("now") else f.get("onset", f.get("t_onset"))
        if onset is not None:
            out.append((float(onset), int(f["wheel"])))
    return sorted(set(out))


def shows_envelope(run: Run) -> bool:
    """The run's figures show the prescribed envelope (its bounds, its first
    violation): only when its scenario asks for it (``asks_envelope``)."""
    return asks_envelope(run.metrics.get("requirements"))


def mark_events(ax, run: Run, *, labels: bool = False, bound: bool = True) -> None:
    """Fault onsets (red dashed), the first bound violation (black; with
    ``bound``, where the scenario asks for the envelope), SAFE spans (grey)
    and spans without a command (orange) on a time axis."""
    t = run["t"]
    if len(t) == 0:
        return
    for j, (onset, _wheel) in enumerate(fault_onsets(run)):
        if onset <= t[-1]:
            ax.axvline(onset, color="r", ls="--", lw=0.7, label="fault onset" if labels and j == 0 else None)
    first = run.metrics.get("first_bound_violation_s")
    if first is not None and bound and shows_envelope(run):
        ax.axvline(first, color="k", lw=0.9, label="first bound violation" if labels else None)
    for j, (a, b) in enumerate(_spans(t, _safe_mask(run))):
        ax.axvspan(a, b, color="0.5", alpha=0.2, lw=0, label="SAFE" if labels and j == 0 else None)
    for j, (a, b) in enumerate(run.gaps):
        ax.axvspan(a, b, color="orange", alpha=0.2, lw=0, label="no command" if labels and j == 0 else None)


#: A limit is drawn inside the axis when it is within this factor of the data's extent.
NEAR = 3.0


def limit_lines(ax, data: np.ndarray, limits: list[tuple[Any, ...]], color: str = "r") -> None:
    """Horizontal lines at each (value, label) or (value, label, (t0, t1))
    of ``limits`` (the last: drawn over that span only), the y axis fit to
    ``data`` and to the limits within ``NEAR`` times its extent; a limit
    beyond that stays a line off the axis, its label saying so."""
    d = np.asarray(data, float)
    d = d[np.isfinite(d)]
    lo, hi = (float(d.min()), float(d.max())) if d.size else (0.0, 1.0)
    extent = max(abs(lo), abs(hi), 1e-300)
    shown = [x[0] for x in limits if np.isfinite(x[0]) and abs(x[0]) <= NEAR * extent]
    lo, hi = min([lo, *shown]), max([hi, *shown])
    pad = 0.08 * (hi - lo) if hi > lo else 0.1 * max(abs(hi), 1e-12)
    seen = set()
    for v, label, *span in limits:
        if not np.isfinite(v):
            continue
        text = label + (f" (off scale: {v:.4g})" if v not in shown and label else "")
        kw = dict(color=color, ls="--" if v in shown else ":", lw=0.9, label=None if text in seen or not text else text)
        seen.add(text)
        if span and span[0] is not None:
            ax.hlines(v, span[0][0], span[0][1], **kw)
        else:
            ax.axhline(v, **kw)
    ax.set_ylim(lo - pad, hi + pad)


def _legend_outside(ax, **kw) -> None:
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, borderaxespad=0.0, **kw)
