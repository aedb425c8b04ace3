"""A run judged against its scenario's ``[[requirements]]`` (docs/REQUIREMENTS.md).

Pure numpy on a finished ``Run`` (sc_rt.results.run): the rows come from
``run.meta.requirements`` (the scenario's, as plain dicts), the signals from
the run's fields:

- performance indices APE, MPE, RPE: the true tracking error, the MRP
  ``sigma_BD`` of the body relative to the desired frame (with sensors in
  the loop ``sigma_BD_true``, the truth against the reference, not what the
  law saw);
- knowledge indices AKE, MKE, RKE: the estimate against the truth, the MRP
  of the true body attitude relative to the estimated one,
  ``sigma_BN (-) sigma_BN_est`` (runs with sensors only; otherwise "not
  applicable");
- settling: the time the chosen error enters its band for good;
- wheel_speed_margin, max_command: max |wheel_speed|, max |u_cmd|;
- envelope: the prescribed-performance bound (29) of ``[controller.ppc]``,
  judged exactly as the metrics' ``first_bound_violation_s``.

The temporal interpretation (the only one evaluated yet): the value at the
stated confidence p is the nearest-rank empirical p-quantile (the smallest
sample that at least a fraction p of the samples do not exceed, numpy's
``method="inverted_cdf"``) over the samples in the span (APE, AKE) or over
the windows in the span (MPE, RPE, MKE, RKE: non-overlapping windows of
``window`` seconds laid from the span's start, a last partial window left
out). Per window, MPE is |mean of the error| and RPE the largest |error -
its window mean|.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sc_rt.scenario.requirements import ANGLE_UNITS, UNITS

__all__ = ["ANGLE_UNITS", "cone_vector", "error_signal", "evaluate_requirements", "mrp_subtract",
           "mrp_to_rotvec", "nearest_rank", "relative_errors", "settling_time", "window_means", "windows", "worst"]

#: Unit -> its value in SI (rad, rad/s, rad/s^2), the scenario's units (sc_rt.scenario.requirements.UNITS).
_SI = {u: f for units in UNITS.values() for u, f in units.items()}
_PERFORMANCE = ("APE", "MPE", "RPE")
_KNOWLEDGE = ("AKE", "MKE", "RKE")
_WINDOWED = ("MPE", "RPE", "MKE", "RKE")
_EPS_T = 1e-9  # [s] time comparisons on the control grid


# --------------------------------------------------------------------------- #
# Attitude errors as rotation vectors (numpy, vectorised over rows).


def mrp_to_rotvec(sigma: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) [rad] of MRPs (N, 3): axis times the angle 4 atan|sigma|."""
    s = np.asarray(sigma, float).reshape(-1, 3)
    n = np.linalg.norm(s, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(n > 1e-12, 4.0 * np.arctan(n) / np.where(n > 1e-12, n, 1.0), 4.0)
    return s * scale


def mrp_subtract(s1: np.ndarray, s2: np.ndarray) -> np.ndarray:
    """The MRP of frame 1 relative to frame 2 given both relative to N
    (rows), mapped to the short set |sigma| <= 1 (Schaub & Junkins)."""
    a, b = np.asarray(s1, float).reshape(-1, 3), np.asarray(s2, float).reshape(-1, 3)
    na, nb = np.sum(a * a, axis=1, keepdims=True), np.sum(b * b, axis=1, keepdims=True)
    num = (1.0 - nb) * a - (1.0 - na) * b + 2.0 * np.cross(a, b)
    den = 1.0 + na * nb + 2.0 * np.sum(a * b, axis=1, keepdims=True)
    s = num / den
    n2 = np.sum(s * s, axis=1, keepdims=True)
    return np.where(n2 > 1.0, -s / np.where(n2 > 0, n2, 1.0), s)


def _dcm(sigma: np.ndarray) -> np.ndarray:
    """DCMs (N, 3, 3) of MRPs: C = I + (8 [s]^2 - 4 (1 - s's) [s]) / (1 + s's)^2."""
    s = np.asarray(sigma, float).reshape(-1, 3)
    n2 = np.sum(s * s, axis=1)[:, None, None]
    x = np.zeros((len(s), 3, 3))
    x[:, 0, 1], x[:, 0, 2], x[:, 1, 2] = -s[:, 2], s[:, 1], -s[:, 0]
    x[:, 1, 0], x[:, 2, 0], x[:, 2, 1] = s[:, 2], -s[:, 1], s[:, 0]
    return np.eye(3) + (8.0 * x @ x - 4.0 * (1.0 - n2) * x) / (1.0 + n2) ** 2


def cone_vector(sigma: np.ndarray, boresight: Any) -> np.ndarray:
    """Per row, the rotation vector (N, 3) [rad] that takes the boresight b
    (in B) to where it should point, C(sigma) b: perpendicular to b, its
    length the half-cone angle between the two; a rotation about b has none."""
    b = np.asarray(boresight, float)
    b = b / np.linalg.norm(b)
    d = _dcm(sigma) @ b  # the desired direction in B
    axis = np.cross(b, d)
    s = np.linalg.norm(axis, axis=1, keepdims=True)
    angle = np.arctan2(s, (d @ b)[:, None])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(s > 1e-15, axis * angle / np.where(s > 1e-15, s, 1.0), 0.0 * axis)


def error_signal(sigma: np.ndarray, axis: str, boresight: Any = None) -> np.ndarray:
    """The error (N, d) [rad] a requirement judges: the rotation vector's
    component on a body axis ("x", "y", "z"; d = 1), the rotation vector
    ("norm"; d = 3, its length the full angle 4 atan|sigma|), or the cone
    vector about ``boresight`` ("cone"; d = 3, its length the half-cone angle)."""
    if axis == "cone":
        return cone_vector(sigma, boresight)
    phi = mrp_to_rotvec(sigma)
    if axis == "norm":
        return phi
    i = "xyz".index(axis)
    return phi[:, i:i + 1]


# --------------------------------------------------------------------------- #
# Statistics.


def nearest_rank(x: Any, p: float) -> float:
    """The nearest-rank p-quantile of the samples ``x``: the k-th smallest
    with k = ceil(p n), the smallest value that at least a fraction p of the
    samples do not exceed (numpy's ``quantile(method="inverted_cdf")``)."""
    v = np.sort(np.asarray(x, float).ravel())
    if v.size == 0:
        raise ValueError("no samples")
    k = min(v.size, max(1, math.ceil(p * v.size - 1e-9)))  # 1e-9: p n = 19.000000000000004 is rank 19
    return float(v[k - 1])


def windows(e: np.ndarray, n_per: int) -> np.ndarray:
    """``e`` (N, d) cut into non-overlapping windows of ``n_per`` rows from
    its first row, (N // n_per, n_per, d); the last partial window left out."""
    e = np.asarray(e, float)
    e = e.reshape(len(e), -1)
    n_win = len(e) // n_per
    return e[: n_win * n_per].reshape(n_win, n_per, e.shape[1])


def window_means(w: np.ndarray) -> np.ndarray:
    """MPE per window: |the error's mean over the window| (n_windows,)."""
    return np.linalg.norm(w.mean(axis=1), axis=1)


def relative_errors(w: np.ndarray) -> np.ndarray:
    """RPE per window: the largest |error - its window mean| in the window (n_windows,)."""
    return np.linalg.norm(w - w.mean(axis=1, keepdims=True), axis=2).max(axis=1)


def settling_time(t: np.ndarray, magnitude: np.ndarray, band: float) -> float | None:
    """The first instant from which every later sample is within ``band``
    (<=); a non-finite sample counts as outside. None: the last one is outside."""
    inside = np.isfinite(magnitude) & (magnitude <= band)
    if len(inside) == 0 or not inside[-1]:
        return None
    outside = np.flatnonzero(~inside)
    return float(t[outside[-1] + 1]) if outside.size else float(t[0])


# --------------------------------------------------------------------------- #
# Evaluation.


def _result(req: dict[str, Any], **kw: Any) -> dict[str, Any]:
    out = {"name": req["name"], "kind": req["kind"], "axis": req.get("axis", ""),
           "interpretation": req.get("interpretation", ""), "confidence": req.get("confidence"),
           "value": None, "bound": req.get("bound"), "unit": req.get("unit", "-"), "margin": None,
           "relative_margin": None, "passed": None, "status": "not evaluated", "note": ""}
    out.update(kw)
    if out["passed"] is not None:
        out["status"] = "pass" if out["passed"] else "fail"
        if out["value"] is not None and out["bound"] is not None:
            out["margin"] = out["bound"] - out["value"]
            out["relative_margin"] = out["margin"] / out["bound"]
    return out


def _rows(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    return np.flatnonzero((t >= t0 - _EPS_T) & (t <= t1 + _EPS_T))


def _span_text(t: np.ndarray, idx: np.ndarray) -> str:
    return f"{t[idx[0]]:g}-{t[idx[-1]]:g} s"


def _pointing(req: dict[str, Any], t: np.ndarray, sigma: np.ndarray, idx: np.ndarray) -> dict[str, Any]:
    """APE/AKE or a windowed index at the requirement's confidence, temporal."""
    unit = ANGLE_UNITS[req["unit"]]
    p = float(req["confidence"])
    e = error_signal(sigma[idx], req["axis"], req.get("boresight"))
    span = _span_text(t, idx)
    if req["kind"] in ("APE", "AKE"):
        ok = np.all(np.isfinite(e), axis=1)
        mag = np.linalg.norm(e[ok], axis=1)
        if mag.size == 0:
            return _result(req, note=f"no finite error in the span {span}")
        value = nearest_rank(mag, p) / unit
        note = f"nearest-rank p{p:g} of {mag.size} samples, {span}"
        if math.ceil(p * mag.size - 1e-9) >= mag.size:
            note += " (fewer than 1/(1-p) samples: the maximum)"
        if mag.size < ok.size:
            note += f"; {ok.size - mag.size} non-finite samples left out"
        return _result(req, value=value, passed=value <= req["bound"], note=note, samples=int(mag.size),
                       span_s=[float(t[idx[0]]), float(t[idx[-1]])])
    dt = float(np.median(np.diff(t[idx]))) if idx.size > 1 else math.nan
    window = float(req["window"])
    n_per = int(round(window / dt)) if math.isfinite(dt) and dt > 0 else 0
    if n_per < 2:
        return _result(req, note=f"the window {window:g} s holds fewer than 2 samples of the span {span}")
    w = windows(e, n_per)
    if len(w) == 0:
        return _result(req, note=f"the span {span} is shorter than one window of {window:g} s")
    good = np.all(np.isfinite(w), axis=(1, 2))
    if not np.any(good):
        return _result(req, note=f"no window of the span {span} without a non-finite sample")
    per = window_means(w[good]) if req["kind"] in ("MPE", "MKE") else relative_errors(w[good])
    value = nearest_rank(per, p) / unit
    note = f"nearest-rank p{p:g} over {int(good.sum())} windows of {n_per * dt:g} s (non-overlapping), {span}"
    if math.ceil(p * per.size - 1e-9) >= per.size:
        note += " (fewer than 1/(1-p) windows: the maximum)"
    if abs(n_per * dt - window) > 1e-6 * window:
        note += f"; the window is {n_per} samples = {n_per * dt:g} s, the nearest to {window:g} s"
    if not np.all(good):
        note += f"; {int((~good).sum())} windows with non-finite samples left out"
    left = len(idx) - len(w) * n_per
    if left:
        note += f"; the last {left} sample{'s' if left > 1 else ''} (less than a window) left out"
    return _result(req, value=value, passed=value <= req["bound"], note=note, windows=int(good.sum()),
                   window_s=round(n_per * dt, 9), span_s=[float(t[idx[0]]), float(t[idx[-1]])])


def _peak(req: dict[str, Any], t: np.ndarray, values: np.ndarray, idx: np.ndarray, what: str) -> dict[str, Any]:
    """max |values| over the span (per wheel), against the bound."""
    v = np.abs(values[idx])
    if not np.any(np.isfinite(v)):
        return _result(req, note=f"no finite {what} in the span")
    k, wheel = np.unravel_index(int(np.nanargmax(v)), v.shape)
    value = float(v[k, wheel]) / _SI[req["unit"]]
    note = f"max over {_span_text(t, idx)}: wheel {wheel + 1} at {t[idx[k]]:g} s"
    return _result(req, value=value, passed=value <= req["bound"], note=note,
                   span_s=[float(t[idx[0]]), float(t[idx[-1]])])


def _ppc_ratio(ppc: dict[str, Any], t: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """|sigma_BD| as a fraction of the side of the envelope it is on (29):
    sigma / (dmax chi) above 0, -sigma / (dmin chi) below; chi(t) as
    sc_rt.results.metrics.prescribed_chi."""
    chi0, chiinf, gamma, dmin, dmax = (np.asarray(ppc[k], float) for k in ("chi0", "chiinf", "gamma", "dmin", "dmax"))
    chi = (chi0 - chiinf) * np.exp(-np.outer(np.asarray(t, float), gamma)) + chiinf
    return np.where(sigma >= 0, sigma / (dmax * chi), -sigma / (dmin * chi))


def _envelope(req: dict[str, Any], run: Any, sigma: np.ndarray) -> dict[str, Any]:
    t, ok = run["t"], run["bound_ok"]
    if len(t) == 0:
        return _result(req, note="the run has no rows")
    bad = ~ok
    first = first_axis = None
    if np.any(bad):
        k = int(np.argmax(np.any(bad, axis=1)))
        first, first_axis = float(t[k]), int(np.argmax(bad[k])) + 1
    ratio = _ppc_ratio(run.meta.ppc, t, sigma)
    finite = ratio[np.isfinite(ratio)]
    value = float(finite.max()) if finite.size else None
    note = ("inside the prescribed bound the whole run" if first is None
            else f"left the prescribed bound at {first:.2f} s (axis {'xyz'[first_axis - 1]})")
    r = _result(req, value=value, bound=1.0, unit="-", passed=first is None, note=note,
                first_violation_s=first, first_violation_axis=first_axis)
    if value is None:
        r["margin"] = r["relative_margin"] = None
    return r


def _span(req: dict[str, Any], t: np.ndarray, end: float, settled: dict[str, float | None]
          ) -> tuple[float | None, float, str]:  # fmt: skip
    """(start, end, why there is none) of the requirement's span [s]."""
    t_from = req.get("t_from", 0.0)
    if t_from == "after_settling":
        start = settled.get(req.get("settling", ""))
        if start is None:
            return None, end, f"its settling requirement {req.get('settling')!r} never settled: no span"
    else:
        start = float(t_from)
    t_to = req.get("t_to")
    stop = end if t_to is None else min(float(t_to), end)
    return start, stop, ""


def evaluate_requirements(run: Any, sensed: bool) -> list[dict[str, Any]]:
    """Each of ``run.meta.requirements`` evaluated on ``run`` (its fields
    filled, ``bound_ok`` judged): a dict per requirement with name, kind,
    axis, interpretation, confidence, value, bound, unit, margin (bound -
    value, in the unit), relative_margin (margin / bound), passed (True,
    False, None: not evaluated), status ("pass", "fail", "not evaluated",
    "not applicable") and a note saying how the value was found.

    ``sensed``: the run had the estimator in the loop (its performance error
    is ``sigma_BD_true``, its knowledge error defined)."""
    reqs = list(getattr(run.meta, "requirements", ()) or ())
    t = np.asarray(run["t"], float)
    end = float(t[-1]) if len(t) else 0.0
    perf = run["sigma_BD_true"] if sensed else run["sigma_BD"]
    know = mrp_subtract(run["sigma_BN"], run["sigma_BN_est"]) if sensed else None
    settled: dict[str, float | None] = {}
    results: dict[str, dict[str, Any]] = {}
    # settling first: an "after_settling" span starts at its time
    for req in sorted(reqs, key=lambda r: r["kind"] != "settling"):
        results[req["name"]] = r = _evaluate(req, run, t, end, perf, know, settled)
        if req["kind"] == "settling":
            settled[req["name"]] = r["value"]
        _short_run(req, r, run, end)
    return [results[r["name"]] for r in reqs]


def _short_run(req: dict[str, Any], r: dict[str, Any], run: Any, end: float) -> None:
    """A span that reaches past the run's last row: cut there (a run
    shortened on purpose, said in the note), or failed when the run
    diverged before it (what it did after is unknown)."""
    if req["kind"] == "envelope" or r["status"] == "not applicable":
        return
    wanted = req.get("t_to")
    wanted = float(run.meta.duration_s) if wanted is None else float(wanted)
    if end >= wanted - _EPS_T:
        return
    if run.diverged:
        r.update(passed=False, status="fail")
        r["note"] = (r["note"] + "; " if r["note"] else "") + f"the run diverged at {end:g} s, before {wanted:g} s"
    elif r["status"] != "not evaluated":
        r["note"] += f"; the span cut at the run's end, {end:g} s (asked: {wanted:g} s)"


def _evaluate(req: dict[str, Any], run: Any, t: np.ndarray, end: float, perf: np.ndarray,
              know: np.ndarray | None, settled: dict[str, float | None]) -> dict[str, Any]:
    kind = req["kind"]
    if kind == "envelope":
        return _envelope(req, run, perf)
    if req.get("interpretation", "temporal") not in ("", "temporal"):
        return _result(req, note=f'the "{req["interpretation"]}" interpretation is a statistic across the runs '
                                 "of a campaign: not yet supported (only temporal, within one run)")
    if kind in _KNOWLEDGE and know is None:
        return _result(req, status="not applicable",
                       note="the run has no estimator ([sensors]): no knowledge error")
    start, stop, why = _span(req, t, end, settled)
    if start is None:
        return _result(req, note=why)
    idx = _rows(t, start, stop)
    if idx.size == 0:
        return _result(req, note=f"the run ({end:g} s) has no row in the span {start:g}-{stop:g} s")
    if kind in _PERFORMANCE + _KNOWLEDGE:
        return _pointing(req, t, perf if kind in _PERFORMANCE else know, idx)
    if kind == "settling":
        band = float(req["bound"]) * ANGLE_UNITS[req["unit"]]
        mag = np.linalg.norm(error_signal(perf[idx], req["axis"], req.get("boresight")), axis=1)
        ts = settling_time(t[idx], mag, band)
        base = dict(bound=float(req["settle_by"]), unit="s", band=req["bound"], band_unit=req["unit"],
                    span_s=[float(t[idx[0]]), float(t[idx[-1]])])
        if ts is None:
            return _result(req, passed=False, **base,
                           note=f"never settled: outside {req['bound']:g} {req['unit']} at {t[idx[-1]]:g} s")
        return _result(req, value=ts, passed=ts <= float(req["settle_by"]) + _EPS_T, **base,
                       note=f"within {req['bound']:g} {req['unit']} ({req['axis']}) from {ts:g} s on")
    if kind == "wheel_speed_margin":
        return _peak(req, t, run["wheel_speed"], idx, "wheel speed")
    if kind == "max_command":
        return _peak(req, t, run["u_cmd"], idx, "command")
    raise ValueError(f"unknown requirement kind {kind!r}")


def worst(results: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The evaluated requirement with the smallest relative margin (a failed
    one without a value first), None when none was evaluated."""
    judged = [r for r in results if r.get("passed") is not None]
    if not judged:
        return None

    def key(r: dict[str, Any]) -> tuple[float, int]:
        m = r.get("relative_margin")
        return (-math.inf if m is None else float(m), 0 if r["passed"] is False else 1)

    return min(judged, key=key)
