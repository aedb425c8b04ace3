"""A run judged against its scenario's ``[[requirements]]`` (docs/REQUIREMENTS.md).

Pure numpy on a finished ``Run`` (sc_rt.results.record.run): the rows come from
``run.meta.requirements`` (the scenario's, as plain dicts), the signals from
the run's fields:

- performance indices APE, MPE, RPE, PDE, PRE: the true tracking error, the
  MRP ``sigma_BD`` of the body relative to the desired frame (with sensors
  in the loop ``sigma_BD_true``, the truth against the reference, not what
  the law saw);
- knowledge indices AKE, MKE, RKE, KDE, KRE: the estimate against the
  truth, the MRP of the true body attitude relative to the estimated one,
  ``sigma_BN (-) sigma_BN_est`` (runs with sensors only; otherwise "not
  applicable"). With sensors, each pointing row also reports its
  counterpart (AKE beside an APE, APE beside an AKE, ...) at the same
  probability, span and windows (``counterpart``);
- settling: the time the chosen error enters its band for good;
- wheel_speed_margin, momentum_margin, max_command: max |wheel_speed|, max
  |Cbar Jw wheel_speed| (the wheels' total momentum), max |u_cmd| per wheel
  (in the requirement's unit: a wheel acceleration or a motor torque,
  converted with Jw from what the run's wheels take, ``RunMeta.wheel_command``);
- max_torque: max |Cbar tau_cmd|, the body torque the wheel command asks for,
  tau_cmd the command as motor torques [N m] (u_cmd on torque wheels, Jw u_cmd
  on acceleration wheels), with the applied one beside it (``applied``: the
  same of the saturated command u_sat);
- envelope: the prescribed-performance bound (29) of ``[controller.ppc]``,
  judged exactly as the metrics' ``first_bound_violation_s``.

The temporal interpretation is judged here, within the run: the value at
the stated confidence p is the nearest-rank empirical p-quantile (the
smallest value that at least a fraction p of the values do not exceed,
numpy's ``method="inverted_cdf"``) of the index's values over the span
(sc_rt.results.judge.indices: samples, windows or pairs of windows; for RPE
and RKE every instant of the windows, ECSS-E-ST-60-10C 3.2.12, with the
window-max statistic beside it as ``window_max_bound``, a bound on it). The ensemble
and mixed interpretations are statistics across the runs of a campaign
(``sc-rt montecarlo``, sc_rt.results.judge.ensemble): a single run reports them
"not evaluated".
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sc_rt.results.judge.indices import index_values
from sc_rt.results.judge.pointing import (error_signal, mode_mask, mrp_subtract, nearest_rank, outside_mode,
                                   settling_time, wheel_momentum)
from sc_rt.scenario.tables.requirements import ANGLE_UNITS, COUNTERPART, KNOWLEDGE, PERFORMANCE, UNITS

__all__ = ["body_torque", "evaluate_requirements", "is_sensed", "knowledge_error", "requirement_span", "worst"]

#: Unit -> its value in SI (rad, rad/s, N m s, rad/s^2), the scenario's units
#: (sc_rt.scenario.tables.requirements.UNITS).
_SI = {u: f for units in UNITS.values() for u, f in units.items()}
_EPS_T = 1e-9  # [s] time comparisons on the control grid


def is_sensed(run: Any) -> bool:
    """The run had the estimator in the loop and its estimates are filled
    (its performance error is ``sigma_BD_true``, its knowledge error defined)."""
    return bool(getattr(run.meta, "sensors", False)) and bool(run.present("sigma_BN_est").any())


def knowledge_error(run: Any) -> np.ndarray:
    """The knowledge error's MRPs (N, 3): the true attitude relative to the estimate."""
    return mrp_subtract(run["sigma_BN"], run["sigma_BN_est"])


# --------------------------------------------------------------------------- #
# Evaluation.


def _result(req: dict[str, Any], **kw: Any) -> dict[str, Any]:
    out = {"name": req["name"], "kind": req["kind"], "axis": req.get("axis", ""),
           "interpretation": req.get("interpretation", ""), "confidence": req.get("confidence"),
           "value": None, "bound": req.get("bound"), "unit": req.get("unit", "-"), "margin": None,
           "relative_margin": None, "passed": None, "status": "not evaluated", "note": "",
           "first_outside_s": None, "last_outside_s": None, "outside": 0}
    out.update(kw)
    if out["passed"] is not None:
        out["status"] = "pass" if out["passed"] else "fail"
        if out["value"] is not None and out["bound"] is not None:
            out["margin"] = out["bound"] - out["value"]
            out["relative_margin"] = out["margin"] / out["bound"]
    return out


def _outside(t0: np.ndarray, t1: np.ndarray, out: np.ndarray) -> dict[str, Any]:
    """When a requirement was outside its bound: the first instant of the
    first value outside (a sample, a window, a pair's first window), the last
    instant of the last one, and how many values were outside."""
    out = np.asarray(out, bool)
    if not np.any(out):
        return {"first_outside_s": None, "last_outside_s": None, "outside": 0}
    return {"first_outside_s": float(np.min(t0[out])), "last_outside_s": float(np.max(t1[out])),
            "outside": int(np.count_nonzero(out))}


def _rows(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    return np.flatnonzero((t >= t0 - _EPS_T) & (t <= t1 + _EPS_T))


def _span_text(t: np.ndarray, idx: np.ndarray) -> str:
    return f"{t[idx[0]]:g}-{t[idx[-1]]:g} s"


def _quantile_note(p: float, n: int, what: str, iv: Any, span: str) -> str:
    if what == "samples":
        note = f"nearest-rank p{p:g} of {n} samples, {span}"
    elif what == "instants":
        note = (f"nearest-rank p{p:g} of {n} instants, each against the mean of its {iv.info['window_s']:g} s "
                f"window ({iv.info['windows']} non-overlapping), {span}")
    elif what == "windows":
        note = f"nearest-rank p{p:g} over {n} windows of {iv.info['window_s']:g} s (non-overlapping), {span}"
    else:
        note = (f"nearest-rank p{p:g} over {n} pairs of {iv.info['window_s']:g} s windows "
                f"{iv.info['separation_s']:g} s apart, {span}")
    if math.ceil(p * n - 1e-9) >= n:
        note += f" (fewer than 1/(1-p) {what}: the maximum)"
    return "; ".join([note, *iv.notes])


def _pointing(req: dict[str, Any], t: np.ndarray, sigma: np.ndarray, idx: np.ndarray,
              other: np.ndarray | None) -> dict[str, Any]:
    """A pointing index at the requirement's confidence, temporal; with
    ``other`` (the other error of a sensed run) its counterpart beside it."""
    unit = ANGLE_UNITS[req["unit"]]
    p = float(req["confidence"])
    iv = index_values(req, t, sigma, idx)
    if iv.problem:
        return _result(req, note=iv.problem)
    value = nearest_rank(iv.values, p) / unit
    note = _quantile_note(p, iv.values.size, iv.unit, iv, _span_text(t, idx))
    extra: dict[str, Any] = _outside(iv.t0, iv.t1, iv.values / unit > req["bound"])
    if iv.window_max is not None:  # RPE, RKE: the window-max statistic beside the index, a bound on it
        extra["window_max_bound"] = nearest_rank(iv.window_max, p) / unit
        note += f"; window-max bound {extra['window_max_bound']:.4g} {req['unit']} (p{p:g} of the windows' largest)"
    if other is not None:
        kind = COUNTERPART[req["kind"]]
        ov = index_values(dict(req, kind=kind), t, other, idx)
        if not ov.problem:
            cv = nearest_rank(ov.values, p) / unit
            extra["counterpart"] = {"kind": kind, "value": cv, "unit": req["unit"]}
            what = "the estimate against the truth" if kind in KNOWLEDGE else "the truth against the reference"
            note += f"; beside it {kind} ({what}) {cv:.4g} {req['unit']}"
    return _result(req, value=value, passed=value <= req["bound"], note=note, **iv.info, **extra,
                   span_s=[float(t[idx[0]]), float(t[idx[-1]])])


def _peak(req: dict[str, Any], t: np.ndarray, values: np.ndarray, idx: np.ndarray, what: str,
          per_wheel: bool = True) -> dict[str, Any]:
    """max |values| over the span (per wheel, or of one column), against the bound."""
    v = np.abs(values[idx])
    if not np.any(np.isfinite(v)):
        return _result(req, note=f"no finite {what} in the span")
    k, wheel = np.unravel_index(int(np.nanargmax(v)), v.shape)
    value = float(v[k, wheel]) / _SI[req["unit"]]
    note = f"max over {_span_text(t, idx)}: " + (f"wheel {wheel + 1} " if per_wheel else "") + f"at {t[idx[k]]:g} s"
    with np.errstate(invalid="ignore"):
        over = np.any(v / _SI[req["unit"]] > req["bound"], axis=1)
    return _result(req, value=value, passed=value <= req["bound"], note=note,
                   span_s=[float(t[idx[0]]), float(t[idx[-1]])], **_outside(t[idx], t[idx], over))


def _ppc_ratio(ppc: dict[str, Any], t: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """|sigma_BD| as a fraction of the side of the envelope it is on (29):
    sigma / (dmax chi) above 0, -sigma / (dmin chi) below; chi(t) as
    sc_rt.results.judge.metrics.prescribed_chi."""
    chi0, chiinf, gamma, dmin, dmax = (np.asarray(ppc[k], float) for k in ("chi0", "chiinf", "gamma", "dmin", "dmax"))
    chi = (chi0 - chiinf) * np.exp(-np.outer(np.asarray(t, float), gamma)) + chiinf
    return np.where(sigma >= 0, sigma / (dmax * chi), -sigma / (dmin * chi))


def _envelope(req: dict[str, Any], run: Any, perf: str) -> dict[str, Any]:
    """The prescribed envelope, a chunk of the run at a time (a run on disk: any length)."""
    if len(run) == 0:
        return _result(req, note="the run has no rows")
    first = first_axis = value = last = None
    outside = 0
    for c in run.chunks():
        t, bad = c["t"], ~c["bound_ok"]
        if first is None and np.any(bad):
            k = int(np.argmax(np.any(bad, axis=1)))
            first, first_axis = float(t[k]), int(np.argmax(bad[k])) + 1
        rows = np.flatnonzero(np.any(bad, axis=1))
        if rows.size:
            last, outside = float(t[rows[-1]]), outside + int(rows.size)
        ratio = _ppc_ratio(run.meta.ppc, t, c[perf])
        finite = ratio[np.isfinite(ratio)]
        if finite.size:
            value = max(value, float(finite.max())) if value is not None else float(finite.max())
    note = ("inside the prescribed bound the whole run" if first is None
            else f"left the prescribed bound at {first:.2f} s (axis {'xyz'[first_axis - 1]})")
    r = _result(req, value=value, bound=1.0, unit="-", passed=first is None, note=note,
                first_violation_s=first, first_violation_axis=first_axis, first_outside_s=first,
                last_outside_s=last, outside=outside)
    if value is None:
        r["margin"] = r["relative_margin"] = None
    return r


def requirement_span(req: dict[str, Any], end: float, settled: dict[str, float | None]
                     ) -> tuple[float | None, float, str]:  # fmt: skip
    """(start, stop, why there is none) of the requirement's span [s] in a
    run that ends at ``end`` [s]; ``settled``: the settling requirements'
    times by name (None: never settled)."""
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
    perf_name = "sigma_BD_true" if sensed else "sigma_BD"
    if all(r["kind"] == "envelope" for r in reqs):  # read a chunk at a time: a run on disk of any length
        results = {r["name"]: _envelope(r, run, perf_name) for r in reqs}
        return [results[r["name"]] for r in reqs]
    # the other kinds read the whole columns they judge (docs/PERFORMANCE.md, "Long runs")
    t = np.asarray(run["t"], float)
    end = float(t[-1]) if len(t) else 0.0
    perf = run[perf_name]
    know = knowledge_error(run) if sensed else None
    settled: dict[str, float | None] = {}
    results = {}
    # settling first: an "after_settling" span starts at its time
    for req in sorted(reqs, key=lambda r: r["kind"] != "settling"):
        results[req["name"]] = r = _evaluate(req, run, t, end, perf, know, settled, perf_name)
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
              know: np.ndarray | None, settled: dict[str, float | None], perf_name: str) -> dict[str, Any]:
    kind = req["kind"]
    if kind == "envelope":
        return _envelope(req, run, perf_name)
    if req.get("interpretation", "temporal") not in ("", "temporal"):
        return _result(req, note=f'the "{req["interpretation"]}" interpretation is a statistic across the runs '
                                 "of a campaign: sc-rt montecarlo evaluates it (docs/REQUIREMENTS.md)")
    if kind in KNOWLEDGE and know is None:
        return _result(req, status="not applicable",
                       note="the run has no estimator ([sensors]): no knowledge error")
    start, stop, why = requirement_span(req, end, settled)
    if start is None:
        return _result(req, note=why)
    idx = _rows(t, start, stop)
    if idx.size == 0:
        return _result(req, note=f"the run ({end:g} s) has no row in the span {start:g}-{stop:g} s")
    mode = req.get("mode", "")
    if mode:  # only the span's rows inside the mode's windows are judged
        inside = mode_mask(run, mode)
        left = int((~inside[idx]).sum())
        r = _in_mode(req, run, t, idx, inside, perf, know)
        if r["status"] != "not evaluated" or left:
            r["note"] = (r["note"] + "; " if r["note"] else "") + f'{left} rows outside mode "{mode}" left out'
        return r
    return _judge(req, run, t, idx, perf, know)


def _in_mode(req: dict[str, Any], run: Any, t: np.ndarray, idx: np.ndarray, inside: np.ndarray,
             perf: np.ndarray, know: np.ndarray | None) -> dict[str, Any]:
    """A requirement judged on the rows of its span inside its mode window."""
    if req["kind"] in PERFORMANCE + KNOWLEDGE:  # out-of-mode rows as non-finite samples (windows too)
        return _judge(req, run, t, idx, outside_mode(perf, inside),
                      None if know is None else outside_mode(know, inside))
    kept = idx[inside[idx]]
    if kept.size == 0:
        return _result(req, note=f'no row of the span is in mode "{req["mode"]}"')
    return _judge(req, run, t, kept, perf, know)


def _judge(req: dict[str, Any], run: Any, t: np.ndarray, idx: np.ndarray, perf: np.ndarray,
           know: np.ndarray | None) -> dict[str, Any]:
    kind = req["kind"]
    if kind in PERFORMANCE:
        return _pointing(req, t, perf, idx, know)
    if kind in KNOWLEDGE:
        return _pointing(req, t, know, idx, perf)
    if kind == "settling":
        return _settling(req, t, perf, idx)
    if kind == "wheel_speed_margin":
        return _peak(req, t, run["wheel_speed"], idx, "wheel speed")
    if kind == "momentum_margin":
        Cbar, Jw = getattr(run.meta, "Cbar", ()), getattr(run.meta, "Jw", ())
        if len(Cbar) == 0 or len(Jw) == 0:
            return _result(req, note="the run's record has no wheel axes and inertias (Cbar, Jw)")
        h = np.linalg.norm(wheel_momentum(run["wheel_speed"], Cbar, Jw), axis=1)
        return _peak(req, t, h[:, None], idx, "wheel momentum", per_wheel=False)
    if kind == "max_command":  # per wheel, in the requirement's dimension
        u = np.asarray(run["u_cmd"], float)
        want_torque = req["unit"] in _TORQUE_UNITS
        if want_torque != run.meta.torque_wheels:  # the drive's arithmetic: torque = Jw a
            if len(getattr(run.meta, "Jw", ())) == 0:
                return _result(req, note="the run's record has no wheel inertias (Jw) to convert its command")
            Jw = np.asarray(run.meta.Jw, float)
            u = u * Jw if want_torque else u / Jw
        return _peak(req, t, u, idx, "command")
    if kind == "max_torque":
        if len(getattr(run.meta, "Cbar", ())) == 0 or len(getattr(run.meta, "Jw", ())) == 0:
            return _result(req, note="the run's record has no wheel axes and inertias (Cbar, Jw)")
        asked, applied = (body_torque(run.meta, run[k]) for k in ("u_cmd", "u_sat"))
        r = _peak(req, t, asked[:, None], idx, "commanded body torque", per_wheel=False)
        peak = applied[idx][np.isfinite(applied[idx])]
        if r["value"] is not None and peak.size:
            r["applied"] = float(peak.max()) / _SI[req["unit"]]
            r["note"] += f"; applied (after saturation) {r['applied']:.4g} {req['unit']}"
        return r
    raise ValueError(f"unknown requirement kind {kind!r}")


#: the units of a motor torque (the rest of max_command's are accelerations)
_TORQUE_UNITS = ("N m", "mN m")


def body_torque(meta: Any, u: Any) -> np.ndarray:
    """|Cbar tau| [N m] per row: the body torque of wheel commands ``u`` (N, 4)
    of the run ``meta`` (its wheels' unit), tau the motor torques
    (``RunMeta.wheel_torque``)."""
    return np.linalg.norm(meta.wheel_torque(u) @ np.asarray(meta.Cbar, float).T, axis=1)


def _settling(req: dict[str, Any], t: np.ndarray, perf: np.ndarray, idx: np.ndarray) -> dict[str, Any]:
    band = float(req["bound"]) * ANGLE_UNITS[req["unit"]]
    mag = np.linalg.norm(error_signal(perf[idx], req["axis"], req.get("boresight")), axis=1)
    ts = settling_time(t[idx], mag, band)
    # outside its bound: outside the band from the time it had to be settled by
    late = ~(np.isfinite(mag) & (mag <= band)) & (t[idx] >= float(req["settle_by"]) - _EPS_T)
    base = dict(bound=float(req["settle_by"]), unit="s", band=req["bound"], band_unit=req["unit"],
                span_s=[float(t[idx[0]]), float(t[idx[-1]])], **_outside(t[idx], t[idx], late))
    if ts is None:
        return _result(req, passed=False, **base,
                       note=f"never settled: outside {req['bound']:g} {req['unit']} at {t[idx[-1]]:g} s")
    return _result(req, value=ts, passed=ts <= float(req["settle_by"]) + _EPS_T, **base,
                   note=f"within {req['bound']:g} {req['unit']} ({req['axis']}) from {ts:g} s on")


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
