"""The figures of a run's requirements (docs/REQUIREMENTS.md, section 5):

- ``requirements.png``: one panel per pointing or settling requirement,
  the values the requirement is judged on (the error's samples, RPE's
  relative error at each instant, or the per-window or per-pair values)
  over the run, its bound drawn over its
  span (the span shaded), the value measured at its probability and, with
  sensors, the counterpart index (knowledge beside performance);
- ``wheel_speeds.png``: the wheel speeds and the wheels' total momentum
  against the wheel speed and momentum requirements and the actuator's
  speed limit.

The y axes follow the data, not the limits (sc_rt.results.present.figure_marks.limit_lines).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.results.present import figures as _figures
from sc_rt.results.present.figure_marks import _legend_outside, _two_line, limit_lines, mark_events
from sc_rt.results.present.figures import plt
from sc_rt.results.judge.indices import index_values
from sc_rt.results.judge.pointing import error_signal, wheel_momentum
from sc_rt.results.judge.requirements import is_sensed, knowledge_error, requirement_span
from sc_rt.results.record.run import Run
from sc_rt.scenario.tables.requirements import ANGLE_UNITS, COUNTERPART, KNOWLEDGE, PERFORMANCE, UNITS

__all__ = ["requirement_figure", "requirement_figures", "wheel_figure"]

def _rows(run: Run) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    """(requirement row, its result) of the pointing and settling requirements."""
    results = {r["name"]: r for r in run.metrics.get("requirements") or []}
    return [(q, results.get(q["name"], {})) for q in getattr(run.meta, "requirements", ()) or ()
            if q["kind"] in PERFORMANCE + KNOWLEDGE + ("settling",)]


def _span(q: dict[str, Any], r: dict[str, Any], run: Run) -> tuple[float, float] | None:
    if r.get("span_s"):
        return float(r["span_s"][0]), float(r["span_s"][1])
    t = run["t"]
    settled = {x["name"]: x.get("value") for x in run.metrics.get("requirements") or [] if x["kind"] == "settling"}
    start, stop, _ = requirement_span(q, float(t[-1]) if len(t) else 0.0, settled)
    return None if start is None else (start, stop)


def _draw_values(ax, q: dict[str, Any], run: Run, sigma: np.ndarray, span: tuple[float, float], unit: float,
                 label: str, color: str) -> None:
    t = run["t"]
    idx = np.flatnonzero((t >= span[0] - 1e-9) & (t <= span[1] + 1e-9))
    if idx.size == 0:
        return
    iv = index_values(q, t, sigma, idx)
    if iv.problem:
        return
    if iv.unit in ("samples", "instants"):  # RPE, RKE: each instant against its window's mean
        ax.plot(iv.t0, iv.values / unit, lw=0.8, color=color, label=label)
    else:
        ax.hlines(iv.values / unit, iv.t0, iv.t1, color=color, lw=1.6, label=label)


def requirement_figure(run: Run, out: Path, title: str = "") -> Path | None:
    """requirements.png (see the module's docstring); None when the run has
    no pointing or settling requirement."""
    rows = _rows(run)
    if not rows or len(run["t"]) == 0:
        return None
    t = run["t"]
    sensed = is_sensed(run)
    perf = run["sigma_BD_true"] if sensed else run["sigma_BD"]
    know = knowledge_error(run) if sensed else None
    fig, axs = plt.subplots(len(rows), 1, figsize=(9, 2.4 * len(rows) + 0.8), sharex=True, squeeze=False)
    for ax, (q, r) in zip(axs[:, 0], rows):
        kind, unit_name = q["kind"], q["unit"]
        unit = ANGLE_UNITS[unit_name]
        span = _span(q, r, run)
        sigma = know if kind in KNOWLEDGE else perf
        what = f"{q['name']}: {kind} {q.get('axis', '')}"
        if kind == "settling":
            mag = np.linalg.norm(error_signal(perf, q["axis"], q.get("boresight")), axis=1) / unit
            ax.semilogy(t, mag + 1e-300, lw=0.8, color="C0", label="|error|")
            ax.axhline(q["bound"], color="r", ls="--", lw=0.9, label=f"band {q['bound']:g} {unit_name}")
            ax.axvline(q["settle_by"], color="r", lw=0.9, label=f"settle by {q['settle_by']:g} s")
            if r.get("value") is not None:
                ax.axvline(r["value"], color="g", lw=0.9, ls=":", label=f"settled at {r['value']:g} s")
        elif sigma is None or span is None:
            ax.text(0.5, 0.5, f"{q['name']}: {r.get('status', 'not evaluated')} ({r.get('note', '')})",
                    ha="center", va="center", transform=ax.transAxes, fontsize=8, wrap=True)
        else:
            what += f" p{q['confidence']:g} {q.get('interpretation', '')}"
            ax.axvspan(span[0], span[1], color="g", alpha=0.07, lw=0, label="span")
            _draw_values(ax, q, run, sigma, span, unit, f"{kind} values", "C0")
            other = perf if kind in KNOWLEDGE else know
            if other is not None:
                _draw_values(ax, dict(q, kind=COUNTERPART[kind]), run, other, span, unit,
                             f"{COUNTERPART[kind]} values (beside it)", "C1")
            ax.hlines(q["bound"], span[0], span[1], color="r", ls="--", lw=1.0, label=f"bound {q['bound']:g}")
            if r.get("value") is not None:
                ax.hlines(r["value"], span[0], span[1], color="k", ls=":", lw=1.0,
                          label=f"p{q['confidence']:g} value {r['value']:.4g}")
            if r.get("window_max_bound") is not None:  # RPE, RKE: the window-max statistic, a bound on it
                ax.hlines(r["window_max_bound"], span[0], span[1], color="0.4", ls="-.", lw=0.9,
                          label=f"window-max bound {r['window_max_bound']:.4g}")
            ax.set_ylim(bottom=0.0)
        ax.set_ylabel(f"[{unit_name}]")
        status = r.get("status", "")
        if status == "not evaluated" and q.get("interpretation") in ("ensemble", "mixed"):
            status = "judged across runs (sc-rt montecarlo)"
        ax.set_title(what + (f" -> {status.upper()}" if status else ""), fontsize=9, loc="left")
        ax.grid(alpha=0.3, which="both")
        mark_events(ax, run, bound=False)
        _legend_outside(ax)
    axs[0, 0].figure.suptitle(_two_line("Requirements: the values judged, the bound over its span", run, title),
                              fontsize=10)
    axs[-1, 0].set_xlabel("t [s]")
    return _figures.save_figure(fig, out / "requirements.png")


def wheel_figure(run: Run, out: Path, title: str = "") -> Path:
    """wheel_speeds.png: the wheel speeds [rad/s] and the wheels' total
    momentum |Cbar Jw Omega| [N m s] (when the run records the wheels'
    geometry), with the requirements' bounds over their spans and the
    actuator's speed limit."""
    t, ws = run["t"], run["wheel_speed"]
    reqs = {r["name"]: r for r in run.metrics.get("requirements") or []}
    rows = [(q, reqs.get(q["name"], {})) for q in getattr(run.meta, "requirements", ()) or ()]
    Cbar, Jw = getattr(run.meta, "Cbar", ()), getattr(run.meta, "Jw", ())
    fig, axs = plt.subplots(2 if len(Cbar) and len(Jw) else 1, 1, figsize=(9, 6), sharex=True, squeeze=False)
    ax = axs[0, 0]
    for w in range(ws.shape[1]):
        ax.plot(t, ws[:, w], lw=0.9, label=f"wheel {w + 1}")
    limits: list[tuple[Any, ...]] = [(sign * v, "actuator speed limit")
                                     for v in sorted(set(getattr(run.meta, "max_wheel_speed", ()) or ()))
                                     for sign in (1, -1)]
    for q, r in rows:
        if q["kind"] == "wheel_speed_margin" and r.get("span_s"):
            b = q["bound"] * UNITS["wheel_speed_margin"][q["unit"]]
            limits += [(b, f"{q['name']} bound", tuple(r["span_s"])), (-b, f"{q['name']} bound", tuple(r["span_s"]))]
    limit_lines(ax, ws, limits)
    ax.set_ylabel("wheel speed [rad/s]")
    ax.grid(alpha=0.3)
    mark_events(ax, run, labels=True, bound=False)
    _legend_outside(ax)
    ax.set_title(_two_line("Wheel speeds and momentum against their limits", run, title))
    if axs.shape[0] == 2:
        ax = axs[1, 0]
        h = np.linalg.norm(wheel_momentum(ws, Cbar, Jw), axis=1)
        ax.plot(t, h, lw=0.9, color="C4", label="|h_w| = |Cbar Jw Omega|")
        limits: list[tuple[Any, ...]] = []
        for q, r in rows:
            if q["kind"] == "momentum_margin" and r.get("span_s"):
                limits.append((q["bound"] * UNITS["momentum_margin"][q["unit"]], f"{q['name']} bound",
                               tuple(r["span_s"])))
        limit_lines(ax, np.concatenate([h, [0.0]]), limits)
        ax.set_ylabel("wheel momentum [N m s]")
        ax.grid(alpha=0.3)
        mark_events(ax, run, bound=False)
        _legend_outside(ax)
    axs[-1, 0].set_xlabel("t [s]")
    return _figures.save_figure(fig, out / "wheel_speeds.png")


def requirement_figures(run: Run, out: Path, title: str = "") -> list[Path]:
    """wheel_speeds.png and, with pointing or settling requirements,
    requirements.png (what ``write_run`` adds to the tracking figures)."""
    Path(out).mkdir(parents=True, exist_ok=True)
    paths = [wheel_figure(run, out, title)]
    if (p := requirement_figure(run, out, title)) is not None:
        paths.append(p)
    return paths
