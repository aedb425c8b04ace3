"""Metrics of a closed-loop trajectory (offline or rebuilt from an LCM log).

One function computes ``metrics.json`` for every producer (``sc-rt sim``,
``sc-rt hil``, ``sc-rt report``), so their numbers can be compared exactly.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sc_rt.results.estimation import estimation_metrics, fill_estimation_error, fill_true_tracking_error
from sc_rt.results.requirements import evaluate_requirements
from sc_rt.results.run import CORE_FIELDS, Run, json_safe
from sc_rt.results.verdict import pointing_arcsec, safe_summary

__all__ = ["METRIC_TIMES", "mark_invalid", "record_law_failures", "bound_ok", "compute_metrics", "fill_tracking_errors",
           "prescribed_chi", "finish_run", "json_safe"]

#: Times [s] at which the error norms are reported (those within the run;
#: the run's end is always added).
METRIC_TIMES = (30, 70, 100, 200, 300)

#: Laws whose z2 is a disturbance estimate (the observer error is reported).
LAWS_WITH_OBSERVER = ("dsc-ppc", "dsc")

#: Controller-internal telemetry: in a real-time run a state the controller
#: never used has none (its row is all NaN: missing, not non-finite).
CONTROLLER_TELEMETRY = ("z1", "z2", "chi", "lam")


def fill_tracking_errors(run: Run, guidance) -> int:
    """Rows without controller telemetry (real time: states the controller
    never used) get sigma_DN, sigma_BD and omega_BD_B from the plant state and
    the desired trajectory, computed as the controller does (guidance
    integrated with RK4 steps of at most one control period, (8), (11)).
    ``guidance`` is a ``_core.GuidanceParams``. Returns the rows filled."""
    from sc_rt import _core

    missing = np.flatnonzero(np.isnan(run["sigma_BD"]).any(axis=1))
    if missing.size == 0:
        return 0
    g = _core.Guidance(guidance, 1.0 / run.meta.control_rate_hz)
    g.reset(0.0)
    t_all, s_bn, w_bn = run["t"], run["sigma_BN"], run["omega_BN_B"]
    s_dn, s_bd, w_bd = run["sigma_DN"], run["sigma_BD"], run["omega_BD_B"]
    for k in missing:  # increasing times: the guidance only moves forward
        t = float(t_all[k])
        g.advance(t)
        sd = np.asarray(g.sigma_DN)
        x1 = np.asarray(_core.mrp_subtract(s_bn[k], sd))
        s_dn[k] = sd
        s_bd[k] = x1
        w_bd[k] = w_bn[k] - _core.mrp_to_dcm(x1) @ _core.omega_d(guidance, t)
    return int(missing.size)


def _ppc_arrays(ppc) -> tuple[np.ndarray, ...]:
    """(chi0, chiinf, gamma, dmin, dmax) of a PpcParams-like object or a dict."""
    get = ppc.get if isinstance(ppc, dict) else (lambda k: getattr(ppc, k))
    return tuple(np.asarray(get(k), float) for k in ("chi0", "chiinf", "gamma", "dmin", "dmax"))


def prescribed_chi(ppc, t: np.ndarray) -> np.ndarray:
    """chi(t) of (29) for each axis, shape (len(t), 3), vectorised over t
    (tests check it against the core's ``_core.ppc_chi``). ``ppc``: the
    scenario's PpcParams or a run's ``meta.ppc``."""
    chi0, chiinf, gamma, _, _ = _ppc_arrays(ppc)
    return (chi0 - chiinf) * np.exp(-np.outer(np.asarray(t, float), gamma)) + chiinf


def bound_ok(ppc, t: np.ndarray, sigma_BD: np.ndarray) -> np.ndarray:
    """Per axis, whether -dmin chi(t) < sigma_BD < dmax chi(t) (29); (N, 3) bool.

    Computed from the envelope's parameters, independently of the
    controller's own flags, and for every law (the bound is the paper's
    performance claim, whatever the law).
    """
    chi = prescribed_chi(ppc, t)
    _, _, _, dmin, dmax = _ppc_arrays(ppc)
    return (sigma_BD > -dmin * chi) & (sigma_BD < dmax * chi)


def _at(t: np.ndarray, values: np.ndarray, when: float) -> float | None:
    if len(t) == 0 or when > t[-1] + 1e-9:
        return None
    k = int(np.argmin(np.abs(t - when)))
    return float(np.linalg.norm(values[k]))


def _max_after(t: np.ndarray, values: np.ndarray, after: float) -> float | None:
    if len(t) == 0:  # a run stopped before its first row
        return None
    sel = (t >= after - 1e-9) & ~np.all(np.isnan(values.reshape(len(t), -1)), axis=1)
    if not np.any(sel):
        return None
    return float(np.nanmax(np.abs(values[sel])))


def checkpoints(duration: float) -> tuple[float, ...]:
    """The times the error norms are reported at: the standard ones within
    the run, and its end."""
    ts = [float(s) for s in METRIC_TIMES if s <= duration + 1e-9]
    if not ts or abs(ts[-1] - duration) > 1e-9:
        ts.append(float(duration))
    return tuple(ts)


def _key(s: float) -> str:
    return str(int(s)) if float(s).is_integer() else f"{s:g}"


def compute_metrics(run: Run) -> dict[str, Any]:
    """The metrics of one run (keys as documented in README, "metrics.json")."""
    m = run.meta
    t = run["t"]
    ok = run["bound_ok"]
    finite = all(bool(np.all(np.isfinite(run[k]))) for k in CORE_FIELDS
                 if k != "bound_ok" and k not in CONTROLLER_TELEMETRY)
    for k in CONTROLLER_TELEMETRY:  # missing rows are all NaN; anything else counts
        v = run[k]
        present = ~np.all(np.isnan(v), axis=1) if v.ndim == 2 else np.ones(len(v), bool)
        finite = finite and bool(np.all(np.isfinite(v[present])))
    first_s = first_axis = None
    bad = ~ok
    if np.any(bad):
        k = int(np.argmax(np.any(bad, axis=1)))
        first_s = float(t[k])
        first_axis = int(np.argmax(bad[k])) + 1  # 1-based axis
    sat = np.any(run["u_cmd"] != run["u_sat"], axis=1) if len(t) else np.zeros(0, bool)
    obs = None
    z2 = run["z2"]
    if m.law in LAWS_WITH_OBSERVER or bool(np.any(np.nan_to_num(z2) != 0.0)):  # any law that reports an observer
        obs = _max_after(t, run["z2"] - run["delta2"], 30.0)
    marks = checkpoints(m.duration_s)
    return {
        "scenario": m.scenario,
        "controller": m.law,
        "law": m.law_identity,
        "engine": m.engine,
        "control_rate_hz": float(m.control_rate_hz),
        "duration_s": float(m.duration_s),
        "steps": int(len(t)),
        "wall_s": float(m.wall_s),
        "finite": finite,
        "first_bound_violation_s": first_s,
        "first_bound_violation_axis": first_axis,
        "sigma_e_norm": {_key(s): _at(t, run["sigma_BD"], s) for s in marks},
        "omega_e_norm": {_key(s): _at(t, run["omega_BD_B"], s) for s in marks},
        "max_abs_omega_e_after_70s": _max_after(t, run["omega_BD_B"], 70.0),
        "max_observer_error_after_30s": obs,
        "max_abs_u_cmd": float(np.max(np.abs(run["u_cmd"]))) if len(t) else None,
        "max_abs_wheel_accel": float(np.max(np.abs(run["wheel_accel"]))) if len(t) else None,
        "saturated_fraction": float(np.mean(sat)) if len(t) else 0.0,
        "final_wheel_speed": [float(v) for v in run["wheel_speed"][-1]] if len(t) else None,
    }


def finish_run(run: Run) -> Run:
    """The derived fields and the metrics of a run its producer has filled:
    ``bound_ok`` from the envelope in ``run.meta``, then ``run.metrics``,
    with the scenario's requirements judged (``metrics["requirements"]``)."""
    # a producer that ran the sensors filled the estimator's fields (offline, or the bench from
    # controller_status_t)
    sensed = bool(getattr(run.meta, "sensors", False)) and bool(run.present("sigma_BN_est").any())
    if sensed:  # with sensors the bound is judged on the true attitude (sc_rt.results.estimation)
        fill_true_tracking_error(run)
        if not run.present("att_est_error").any():  # the bench: the estimate came over the bus
            fill_estimation_error(run)
    run["bound_ok"][:] = bound_ok(run.meta.ppc, run["t"], run["sigma_BD_true"] if sensed else run["sigma_BD"])
    metrics = compute_metrics(run)
    metrics.update(safe_summary(run["t"], run["ctrl_mode"], run["flags"]))
    # steps where the law failed (FLAG_LAW_INVALID, wheel_cmd_t): SAFE zeros instead
    metrics["law_invalid_steps"] = int(np.sum((np.asarray(run["flags"]) & 1024) != 0))
    lam = run["lam"]
    ok_lam = np.isfinite(lam)
    # |lambda| = |sigma_BD| / chi of the controller; its worst value says how close the bound came
    metrics["max_abs_lambda"] = float(np.max(np.abs(lam[ok_lam]))) if np.any(ok_lam) else None
    metrics["max_pointing_error_arcsec_after_30s"] = (
        float(np.max(pointing_arcsec(run["sigma_BD"][run["t"] >= 30.0 - 1e-9])))
        if np.any(run["t"] >= 30.0 - 1e-9) else None)
    if sensed:
        metrics.update(estimation_metrics(run))
        metrics["max_pointing_error_arcsec_after_30s"] = metrics["pointing_error_arcsec"]["true"]["max"]
    if run.diverged:
        metrics["diverged"] = True
        metrics["diverged_after_s"] = float(run["t"][-1]) if len(run) else 0.0
        metrics["finite"] = False
    if run.partial:
        metrics["partial"] = True
    # the scenario's [[requirements]], each judged (sc_rt.results.requirements); [] none stated
    metrics["requirements"] = evaluate_requirements(run, sensed)
    metrics.update({k: v for k, v in run.metrics.items() if k not in metrics})
    run.metrics = metrics
    return run


def mark_invalid(run: Run, why: str) -> None:
    """The run is not a valid run of its law (metrics.json ``valid`` false);
    the first reason given is kept (``invalid_reason``)."""
    run.metrics["valid"] = False
    run.metrics.setdefault("invalid_reason", why)


def record_law_failures(run: Run, failures: dict[str, Any] | None) -> None:
    """The law's contained failures (``_core.Controller.law_failures`` or
    the controller's summary: counts per call and the newest) into the run's
    metrics; a run whose law failed at all is not a valid run of that law
    (``valid`` false, ``invalid_reason`` naming the call, the time and the
    message), whatever else it shows."""
    if failures is None:
        return
    run.metrics["law_failures"] = failures
    counts = {k: int(failures.get(k) or 0) for k in ("reset", "step", "after")}
    n = sum(counts.values())
    if n == 0:
        return
    last = failures.get("last") or {}
    why = (f"the law failed {n} time{'s' if n > 1 else ''} ("
           + ", ".join(f"{k} {v}" for k, v in counts.items() if v) + ")"
           + (f"; last: {last.get('call')} at t = {float(last.get('t', 0.0)):.4g} s: {last.get('what')}"
              if last else ""))
    mark_invalid(run, why)
