"""Metrics of a closed-loop trajectory (offline or rebuilt from an LCM log).

One function computes ``metrics.json`` for every producer (``sc-rt sim``,
``sc-rt hil``, ``sc-rt report``), so their numbers can be compared exactly.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sc_rt.results.judge.estimation import (estimation_metrics, fill_estimation_error, fill_true_rate_error,
                                            fill_true_tracking_error, flies_on_estimate, true_error_fields)
from sc_rt.results.judge.law_telemetry import TelemetryAcc
from sc_rt.results.judge.requirements import evaluate_requirements
from sc_rt.results.judge.gate import expect_result
from sc_rt.results.record.run import CORE_FIELDS, Run, json_safe
from sc_rt.results.judge.verdict import SAFE_FLAGS, pointing_arcsec, safe_summary

__all__ = ["METRIC_TIMES", "mark_invalid", "mark_partial", "stopped_reason", "record_law_failures", "bound_ok",
           "compute_metrics", "fill_tracking_errors",
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
    ``guidance`` is a ``_core.GuidanceParams``. Returns the rows filled. A
    run on disk is read (and, when a row lacks them, rewritten) a chunk at a time."""
    from sc_rt import _core

    if not any(bool(np.isnan(c["sigma_BD"]).any()) for c in run.chunks()):
        return 0
    g = _core.Guidance(guidance, 1.0 / run.meta.control_rate_hz)
    g.reset(0.0)
    filled = 0

    def fill(c: Run) -> None:
        nonlocal filled
        missing = np.flatnonzero(np.isnan(c["sigma_BD"]).any(axis=1))
        t_all, s_bn, w_bn = c["t"], c["sigma_BN"], c["omega_BN_B"]
        s_dn, s_bd, w_bd = c["sigma_DN"], c["sigma_BD"], c["omega_BD_B"]
        for k in missing:  # increasing times: the guidance only moves forward
            t = float(t_all[k])
            g.advance(t)
            sd = np.asarray(g.sigma_DN)
            x1 = np.asarray(_core.mrp_subtract(s_bn[k], sd))
            s_dn[k] = sd
            s_bd[k] = x1
            w_bd[k] = w_bn[k] - _core.mrp_to_dcm(x1) @ _core.omega_d(guidance, t)
        filled += int(missing.size)

    run.map_chunks(fill)
    return filled


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


def _max_abs_present(t: np.ndarray, values: np.ndarray, after: float) -> float | None:
    """max |values| over the rows at or after ``after`` [s] that are not all NaN (None: none)."""
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


def _max(a: float | None, b: float | None) -> float | None:
    """The larger (NaN wins, as numpy's max); None: nothing yet."""
    return b if a is None else a if b is None else float(np.max([a, b]))


class _Metrics:
    """compute_metrics and finish_run's reductions over a run's chunks, in
    order (results/record/run.py ``Run.chunks``): every one is a max, a sum, a
    first or a last, so a run read a batch at a time gives the numbers of
    the run held whole."""

    def __init__(self, run: Run, sensed: bool):
        m = run.meta
        self.run, self.sensed = run, sensed
        # the headline errors are the true ones (the truth against the reference); a law fed the
        # estimate has its own beside them (law_*: what it computed from the estimate)
        self.sigma, self.omega = true_error_fields(sensed)
        self.law = sensed and flies_on_estimate(m)
        self.law_w70 = self.law_point_max = None
        self.observer = m.law in LAWS_WITH_OBSERVER
        self.marks = checkpoints(m.duration_s)
        self.near: dict[tuple[str, float], tuple[float, np.ndarray]] = {}  # (field, mark) -> (|t - mark|, row)
        self.rows = 0
        self.finite = True
        self.first_s = self.first_axis = None
        self.saturated = 0
        self.obs = self.w70 = self.u_max = self.acc_max = self.lam_max = self.point_max = None
        self.final_speed = None
        self.t_last = None
        self.safe_steps = 0
        self.safe_from = None
        self.reasons = {text: 0 for text in SAFE_FLAGS.values()}
        self.law_invalid = 0

    def add(self, c: Run) -> None:
        t = c["t"]
        n = len(t)
        if n == 0:
            return
        self.rows += n
        self.t_last = float(t[-1])
        for k in CORE_FIELDS:
            if k != "bound_ok" and k not in CONTROLLER_TELEMETRY:
                self.finite = self.finite and bool(np.all(np.isfinite(c[k])))
        for k in CONTROLLER_TELEMETRY:  # missing rows are all NaN; anything else counts
            v = c[k]
            present = ~np.all(np.isnan(v), axis=1) if v.ndim == 2 else np.ones(len(v), bool)
            self.finite = self.finite and bool(np.all(np.isfinite(v[present])))
        bad = ~c["bound_ok"]
        if self.first_s is None and np.any(bad):
            k = int(np.argmax(np.any(bad, axis=1)))
            self.first_s, self.first_axis = float(t[k]), int(np.argmax(bad[k])) + 1  # 1-based axis
        u_cmd = c["u_cmd"]
        self.saturated += int(np.sum(np.any(u_cmd != c["u_sat"], axis=1)))
        z2 = c["z2"]
        # reported for any law that reports an observer (decided over the whole run)
        self.observer = self.observer or bool(np.any(np.nan_to_num(z2) != 0.0))
        self.obs = _max(self.obs, _max_abs_present(t, z2 - c["delta2"], 30.0))
        for name in {self.sigma, self.omega, *(("sigma_BD", "omega_BD_B") if self.law else ())}:
            v = c[name]
            for mark in self.marks:
                k = int(np.argmin(np.abs(t - mark)))
                d = abs(float(t[k]) - mark)
                if (name, mark) not in self.near or d < self.near[(name, mark)][0]:
                    self.near[(name, mark)] = (d, v[k].copy())
        self.w70 = _max(self.w70, _max_abs_present(t, c[self.omega], 70.0))
        if self.law:
            self.law_w70 = _max(self.law_w70, _max_abs_present(t, c["omega_BD_B"], 70.0))
        self.u_max = _max(self.u_max, float(np.max(np.abs(u_cmd))))
        self.acc_max = _max(self.acc_max, float(np.max(np.abs(c["wheel_accel"]))))
        self.final_speed = [float(v) for v in c["wheel_speed"][-1]]
        s = safe_summary(t, c["ctrl_mode"], c["flags"])
        self.safe_steps += s["safe_steps"]
        if self.safe_from is None:
            self.safe_from = s["safe_from_s"]
        for text, v in s["safe_reasons"].items():
            self.reasons[text] += v
        # steps where the law failed (FLAG_LAW_INVALID, wheel_cmd_t): SAFE zeros instead
        self.law_invalid += int(np.sum((np.asarray(c["flags"]) & 1024) != 0))
        lam = c["lam"]
        ok_lam = np.isfinite(lam)
        # |lambda| = |sigma_BD| / chi of the controller; its worst value says how close the bound came
        if np.any(ok_lam):
            self.lam_max = _max(self.lam_max, float(np.max(np.abs(lam[ok_lam]))))
        after = t >= 30.0 - 1e-9
        if np.any(after):
            self.point_max = _max(self.point_max, float(np.max(pointing_arcsec(c[self.sigma][after]))))
            if self.law:
                self.law_point_max = _max(self.law_point_max,
                                          float(np.max(pointing_arcsec(c["sigma_BD"][after]))))

    def metrics(self) -> dict[str, Any]:
        m = self.run.meta

        def at(name: str, mark: float) -> float | None:
            if self.t_last is None or mark > self.t_last + 1e-9:
                return None
            return float(np.linalg.norm(self.near[(name, mark)][1]))

        out = {
            "scenario": m.scenario,
            "controller": m.law,
            "law": m.law_identity,
            "engine": m.engine,
            "control_rate_hz": float(m.control_rate_hz),
            "duration_s": float(m.duration_s),
            "steps": int(self.rows),
            "wall_s": float(m.wall_s),
            "finite": self.finite,
            "first_bound_violation_s": self.first_s,
            "first_bound_violation_axis": self.first_axis,
            # what the law was fed: "truth" (its errors are the true ones) or "estimate" (law_* below)
            "measurement": m.measurement,
            # what the wheels take and what the law commanded (converted when they differ), and the
            # unit of each metric whose unit is the run's (the wheel command's: rad/s^2 or N m)
            "wheel_command": m.wheel_command,
            "law_command": m.law_command,
            "units": {"max_abs_u_cmd": m.unit("u_cmd")},
            # the true errors: the truth against the reference (with sensors sigma_BD_true, omega_BD_B_true)
            "sigma_e_norm": {_key(s): at(self.sigma, s) for s in self.marks},
            "omega_e_norm": {_key(s): at(self.omega, s) for s in self.marks},
            "max_abs_omega_e_after_70s": self.w70,
            "max_observer_error_after_30s": self.obs if self.observer else None,
            "max_abs_u_cmd": self.u_max,
            "max_abs_wheel_accel": self.acc_max,
            "saturated_fraction": self.saturated / self.rows if self.rows else 0.0,
            "final_wheel_speed": self.final_speed,
        }
        if self.law:  # the law's own errors, from the estimate it was fed
            out["law_sigma_e_norm"] = {_key(s): at("sigma_BD", s) for s in self.marks}
            out["law_omega_e_norm"] = {_key(s): at("omega_BD_B", s) for s in self.marks}
            out["law_max_abs_omega_e_after_70s"] = self.law_w70
        return out

    def finish_keys(self) -> dict[str, Any]:
        return {"safe_steps": self.safe_steps, "safe_from_s": self.safe_from,
                "safe_reasons": {k: v for k, v in self.reasons.items() if v},
                "law_invalid_steps": self.law_invalid, "max_abs_lambda": self.lam_max,
                "max_pointing_error_arcsec_after_30s": self.point_max,
                **({"law_max_pointing_error_arcsec_after_30s": self.law_point_max} if self.law else {})}


def compute_metrics(run: Run) -> dict[str, Any]:
    """The metrics of one run (keys as documented in README, "metrics.json"),
    read a chunk at a time (a run on disk: any length)."""
    acc = _Metrics(run, False)
    for c in run.chunks():
        acc.add(c)
    return acc.metrics()


def _any_present(run: Run, name: str) -> bool:
    return any(bool(c.present(name).any()) for c in run.chunks())


def finish_run(run: Run, guidance=None) -> Run:
    """The derived fields and the metrics of a run its producer has filled:
    ``bound_ok`` from the envelope in ``run.meta``, then ``run.metrics``,
    with the scenario's requirements judged (``metrics["requirements"]``).
    A run on disk is rewritten once (the derived fields) and read once.

    ``guidance`` (the run's ``_core.GuidanceParams``): with sensors, the
    reference's rate for the true rate error ``omega_BD_B_true`` (without
    it that field, and the true rate metrics, stay NaN)."""
    # a producer that ran the sensors filled the estimator's fields (offline, or the bench from
    # controller_status_t)
    sensed = bool(getattr(run.meta, "sensors", False)) and _any_present(run, "sigma_BN_est")
    fill_est = sensed and not _any_present(run, "att_est_error")  # the bench: the estimate came over the bus

    def derive(c: Run) -> None:
        if sensed:  # with sensors the bound is judged on the true attitude (sc_rt.results.judge.estimation)
            fill_true_tracking_error(c)
            if guidance is not None:
                fill_true_rate_error(c, guidance)
            if fill_est:
                fill_estimation_error(c)
        c["bound_ok"][:] = bound_ok(run.meta.ppc, c["t"], c["sigma_BD_true"] if sensed else c["sigma_BD"])

    run.map_chunks(derive)
    acc, tel = _Metrics(run, sensed), TelemetryAcc(run)
    for c in run.chunks():
        acc.add(c)
        tel.add(c)
    metrics = acc.metrics()
    metrics.update(acc.finish_keys())
    if sensed:
        metrics.update(estimation_metrics(run))
        metrics["max_pointing_error_arcsec_after_30s"] = metrics["pointing_error_arcsec"]["true"]["max"]
    if run.diverged:
        metrics["diverged"] = True
        metrics["diverged_after_s"] = acc.t_last if acc.t_last is not None else 0.0
        metrics["finite"] = False
    if run.partial:
        metrics["partial"] = True
    # the scenario's [[requirements]], each judged (sc_rt.results.judge.requirements); [] none stated
    metrics["requirements"] = evaluate_requirements(run, sensed)
    # the file's expect against the run's verdict, stated or not (sc_rt.results.judge.gate)
    metrics["expect"] = expect_result(metrics["requirements"], getattr(run.meta, "expect", ""))
    metrics["law_telemetry"] = tel.summary()  # the law's own values (results/judge/law_telemetry.py)
    metrics.update({k: v for k, v in run.metrics.items() if k not in metrics})
    run.metrics = metrics
    metrics.setdefault("valid", True)  # every run says whether it is valid (reasons: invalid_reason)
    if run.partial:  # a run that stopped before its end is not a run of its scenario
        mark_invalid(run, stopped_reason(run))
    return run


def stopped_reason(run: Run) -> str:
    """Why a partial run is invalid, in one line: what stopped it and when."""
    why = run.metrics.get("stopped") or run.message or "it ended before its duration"
    t = run.metrics.get("t_reached_s")
    at = f" at t = {t:.6g} s" if isinstance(t, (int, float)) else ""
    return f"the run stopped before its end{at} of {run.meta.duration_s:g} s: {why}"


def mark_partial(run: Run, why: str) -> None:
    """A finished run record that ends before its duration: partial, why,
    the time reached, and invalid (``stopped_reason``)."""
    run.partial = True
    run.metrics.update(partial=True, stopped=why, t_reached_s=float(run.t[-1]) if len(run) else None)
    mark_invalid(run, stopped_reason(run))


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
