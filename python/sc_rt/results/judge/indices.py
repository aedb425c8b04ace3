"""The values a pointing index takes over a requirement's span, each with
the time interval it stands for (docs/REQUIREMENTS.md, section 2):

- APE, AKE: one value per sample, the length of the error;
- MPE, MKE: one per non-overlapping window, |the error's mean over it|
  (ECSS-E-ST-60-10C 3.2.7, 3.2.6: a value of the window);
- RPE, RKE: one per instant of the windows, |error - the mean of the window
  that contains it| (3.2.12, 3.2.11: a value of the instant), and beside
  them each window's largest, whose quantile bounds theirs (``window_max``);
- PDE, KDE (drift, within one observation) and PRE, KRE (reproducibility,
  between observations): one per pair of windows ``separation`` apart,
  |mean over the later window - mean over the first|. The first windows tile
  the span; for PDE/KDE the later window lies in the span too, for PRE/KRE
  anywhere later in the run (another observation).

A run's temporal value is a quantile of these (sc_rt.results.judge.requirements);
a campaign's ensemble and mixed statistics gather them across runs
(sc_rt.results.judge.ensemble).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sc_rt.results.judge.pointing import error_signal, pair_differences, relative_errors, window_means, windows
from sc_rt.scenario.tables.requirements import PAIRED

__all__ = ["IndexValues", "index_values"]

#: Indices whose later window may lie past the span (another observation).
_REPRODUCIBILITY = ("PRE", "KRE")


@dataclass
class IndexValues:
    """The values of one index over a span, and what they are.

    Attributes
    ----------
    values : numpy.ndarray
        (m,) [rad] the index's values (samples, windows or pairs).
    t0, t1 : numpy.ndarray
        (m,) [s] the first and last instant each value stands for (a sample:
        its own time; a window: its first and last sample; a pair: its first window).
    unit : str
        What one value is: "samples", "instants" (RPE, RKE: a sample's
        relative error in its window), "windows" or "pairs".
    info : dict
        Result fields: samples or windows / pairs, window_s, separation_s.
    notes : list of str
        What was left out or rounded, for the result's note.
    problem : str
        Non-empty: why there is no value.
    window_max : numpy.ndarray or None
        RPE, RKE: (n_windows,) [rad] each window's largest relative error,
        whose quantile bounds the index's (a fraction p of the windows within
        it puts at least a fraction p of their instants within it). None otherwise.
    """

    values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    t0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    t1: np.ndarray = field(default_factory=lambda: np.zeros(0))
    unit: str = "samples"
    info: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    problem: str = ""
    window_max: np.ndarray | None = None


def _span_text(t: np.ndarray, idx: np.ndarray) -> str:
    return f"{t[idx[0]]:g}-{t[idx[-1]]:g} s"


def index_values(req: dict[str, Any], t: np.ndarray, sigma: np.ndarray, idx: np.ndarray) -> IndexValues:
    """The values of the pointing index ``req["kind"]`` (with its axis,
    boresight, window and separation) over the rows ``idx`` of the run's
    times ``t`` and error MRPs ``sigma`` (the whole run: a reproducibility
    index's later windows may lie past the span)."""
    kind = req["kind"]
    span = _span_text(t, idx)
    if kind in ("APE", "AKE"):
        e = error_signal(sigma[idx], req["axis"], req.get("boresight"))
        ok = np.all(np.isfinite(e), axis=1)
        mag = np.linalg.norm(e[ok], axis=1)
        if mag.size == 0:
            return IndexValues(problem=f"no finite error in the span {span}")
        notes = [f"{ok.size - mag.size} non-finite samples left out"] if mag.size < ok.size else []
        tt = t[idx][ok]
        return IndexValues(mag, tt, tt, "samples", {"samples": int(mag.size)}, notes)
    dt = float(np.median(np.diff(t[idx]))) if idx.size > 1 else math.nan
    window = float(req["window"])
    n_per = int(round(window / dt)) if math.isfinite(dt) and dt > 0 else 0
    if n_per < 2:
        return IndexValues(problem=f"the window {window:g} s holds fewer than 2 samples of the span {span}")
    notes = []
    if abs(n_per * dt - window) > 1e-6 * window:
        notes.append(f"the window is {n_per} samples = {n_per * dt:g} s, the nearest to {window:g} s")
    info: dict[str, Any] = {"window_s": round(n_per * dt, 9)}
    if kind in PAIRED:
        return _pairs(req, t, sigma, idx, n_per, dt, info, notes)
    e = error_signal(sigma[idx], req["axis"], req.get("boresight"))
    w = windows(e, n_per)
    if len(w) == 0:
        return IndexValues(problem=f"the span {span} is shorter than one window of {window:g} s")
    good = np.all(np.isfinite(w), axis=(1, 2))
    if not np.any(good):
        return IndexValues(problem=f"no window of the span {span} without a non-finite sample")
    if not np.all(good):
        notes.append(f"{int((~good).sum())} windows with non-finite samples left out")
    left = len(idx) - len(w) * n_per
    if left:
        notes.append(f"the last {left} sample{'s' if left > 1 else ''} (less than a window) left out")
    first = np.flatnonzero(good) * n_per
    info["windows"] = int(good.sum())
    if kind in ("MPE", "MKE"):
        return IndexValues(window_means(w[good]), t[idx][first], t[idx][first + n_per - 1], "windows", info, notes)
    # RPE, RKE: every instant of a window against that window's mean (3.2.12)
    rel = relative_errors(w[good])
    at = t[idx][(first[:, None] + np.arange(n_per)).ravel()]
    info["samples"] = int(rel.size)
    return IndexValues(rel.ravel(), at, at, "instants", info, notes, window_max=rel.max(axis=1))


def _pairs(req: dict[str, Any], t: np.ndarray, sigma: np.ndarray, idx: np.ndarray, n_per: int, dt: float,
           info: dict[str, Any], notes: list[str]) -> IndexValues:
    """PDE, PRE, KDE, KRE: pairs of windows ``separation`` apart."""
    sep = float(req["separation"])
    shift = int(round(sep / dt))
    if abs(shift * dt - sep) > 1e-6 * sep:
        notes.append(f"the separation is {shift} samples = {shift * dt:g} s, the nearest to {sep:g} s")
    info["separation_s"] = round(shift * dt, 9)
    last = len(t) - 1 if req["kind"] in _REPRODUCIBILITY else int(idx[-1])
    rows = np.arange(int(idx[0]), last + 1)
    e = error_signal(sigma[rows], req["axis"], req.get("boresight"))
    bad = ~np.all(np.isfinite(e), axis=1)
    starts, values = pair_differences(np.where(bad[:, None], 0.0, e), len(idx), n_per, shift)
    if starts.size == 0:
        where = "in the span" if req["kind"] not in _REPRODUCIBILITY else "in the run"
        return IndexValues(problem=f"no pair of {n_per * dt:g} s windows {shift * dt:g} s apart fits {where} "
                                   f"{_span_text(t, rows)}")
    c = np.concatenate(([0], np.cumsum(bad)))  # non-finite rows before each row
    clean = (c[starts + n_per] == c[starts]) & (c[starts + shift + n_per] == c[starts + shift])
    if not np.any(clean):
        return IndexValues(problem="no pair of windows without a non-finite sample")
    if not np.all(clean):
        notes.append(f"{int((~clean).sum())} pairs with non-finite samples left out")
    s = starts[clean]
    info["pairs"] = int(clean.sum())
    return IndexValues(values[clean], t[rows][s], t[rows][s + n_per - 1], "pairs", info, notes)
