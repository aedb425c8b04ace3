"""What one run of a campaign keeps for its ensemble and mixed requirements
(docs/REQUIREMENTS.md, section 4), so that ``sc-rt montecarlo`` can take
statistics across runs without holding every trajectory.

Per pointing requirement with ``interpretation = "ensemble"`` or
``"mixed"``, a run keeps:

- ``bins``: the index's values (sc_rt.results.judge.indices: samples, RPE's
  instants, windows or pairs) as the largest value in each bin of a time grid common to every
  run of the campaign (bins of ``bin_width`` seconds from t = 0, about
  ``MAX_BINS`` over the run), in the bound's unit. A value that stands for
  an interval (a window) counts in every bin it touches. NaN: no value of
  the span in that bin; +inf: the run stopped (diverged) before the span's
  end, or never settled when its span starts at a settling: it fails there.
  The largest value of a bin bounds every value in it, so a statistic of
  the bins is conservative (never optimistic) for every instant in them.
- ``within``: the fraction of the index's values within the bound (exact,
  not binned), the run's share of the mixed probability.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sc_rt.results.judge.indices import index_values
from sc_rt.results.judge.pointing import mode_mask, outside_mode
from sc_rt.results.judge.requirements import is_sensed, knowledge_error, requirement_span
from sc_rt.scenario.tables.requirements import ANGLE_UNITS, KNOWLEDGE, PERFORMANCE

__all__ = ["MAX_BINS", "bin_width", "campaign_series", "n_bins"]

#: The most bins a run's series has (a 10^5-run campaign keeps 300 floats per row and requirement).
MAX_BINS = 300
_EPS = 1e-9


def bin_width(duration_s: float, control_rate_hz: float, max_bins: int = MAX_BINS) -> float:
    """[s] the width of the campaign's time bins: the fewest whole control
    periods that cut the run's duration into at most ``max_bins`` bins (the
    last instant, t = duration, opens one more)."""
    dt = 1.0 / float(control_rate_hz)
    periods = max(1, int(round(float(duration_s) * control_rate_hz)))
    return math.ceil(periods / max_bins) * dt


def n_bins(duration_s: float, width: float) -> int:
    """The number of bins of ``width`` [s] from 0 that hold every instant up to ``duration_s``."""
    return int(math.floor(float(duration_s) / width + _EPS)) + 1


def _bin_of(t: np.ndarray, width: float) -> np.ndarray:
    return np.floor(np.asarray(t, float) / width + _EPS).astype(int)


def campaign_series(run: Any, results: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """The ensemble and mixed requirements' series of ``run`` (finished:
    ``results`` are its ``metrics["requirements"]``), by requirement name:
    {"bins": list of float (``n_bins`` long), "within": float or None,
    "count": int}. Knowledge rows of a run without sensors are left out
    (not applicable)."""
    meta = run.meta
    reqs = [r for r in getattr(meta, "requirements", ()) or ()
            if r.get("interpretation") in ("ensemble", "mixed") and r["kind"] in PERFORMANCE + KNOWLEDGE]
    if not reqs:
        return {}
    width = bin_width(meta.duration_s, meta.control_rate_hz)
    nb = n_bins(meta.duration_s, width)
    t = np.asarray(run["t"], float)
    end = float(t[-1]) if len(t) else 0.0
    sensed = is_sensed(run)
    perf = run["sigma_BD_true"] if sensed else run["sigma_BD"]
    know = knowledge_error(run) if sensed else None
    settled = {r["name"]: r.get("value") for r in results if r["kind"] == "settling"}
    settle_by = {r["name"]: r.get("settle_by") for r in meta.requirements if r["kind"] == "settling"}
    out = {}
    for req in reqs:
        if req["kind"] in KNOWLEDGE and know is None:
            continue
        sigma = perf if req["kind"] in PERFORMANCE else know
        if req.get("mode"):  # as evaluate_requirements: only the rows in the mode's windows
            sigma = outside_mode(sigma, mode_mask(run, req["mode"]))
        out[req["name"]] = _series(req, run, t, end, sigma, settled, settle_by.get(req.get("settling", "")), width, nb)
    return out


def _series(req: dict[str, Any], run: Any, t: np.ndarray, end: float, sigma: np.ndarray,
            settled: dict[str, Any], settle_by: float | None, width: float, nb: int) -> dict[str, Any]:
    bins = np.full(nb, np.nan)
    unit = ANGLE_UNITS[req["unit"]]
    start, stop, _why = requirement_span(req, end, settled)
    wanted = float(run.meta.duration_s) if req.get("t_to") is None else float(req["t_to"])
    if start is None:  # never settled: from the time it should have, the run fails it
        bins[_bin_of(float(settle_by or 0.0), width):_bin_of(wanted, width) + 1] = np.inf
        return {"bins": bins.tolist(), "within": 0.0, "count": 0}
    idx = np.flatnonzero((t >= start - _EPS) & (t <= stop + _EPS))
    within, count = None, 0
    if idx.size:
        iv = index_values(req, t, sigma, idx)
        if not iv.problem:
            v = iv.values / unit
            b0, b1 = _bin_of(iv.t0, width), _bin_of(iv.t1, width)
            n_cover = b1 - b0 + 1
            at = np.repeat(b0, n_cover) + np.arange(int(n_cover.sum())) - np.repeat(np.cumsum(n_cover) - n_cover,
                                                                                     n_cover)
            np.fmax.at(bins, np.clip(at, 0, nb - 1), np.repeat(v, n_cover))
            within, count = float(np.mean(v <= float(req["bound"]))), int(v.size)
    if run.diverged and end < wanted - _EPS:  # what the run did after it stopped is unknown: failed there
        lo = _bin_of(max(end, start), width) + (1 if idx.size else 0)
        bins[lo:_bin_of(wanted, width) + 1] = np.inf
        covered = max(0.0, end - start) / max(wanted - start, _EPS)  # the share of the span the run lived
        within = 0.0 if within is None else within * min(1.0, covered)
    return {"bins": bins.tolist(), "within": within, "count": count}
