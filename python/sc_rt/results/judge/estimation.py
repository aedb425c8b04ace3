"""Metrics of a run with sensors (a ``[sensors]`` table): the true tracking
errors (attitude and rate: the truth against the reference) the bound and
the headline numbers are judged on, the MEKF's estimation (knowledge) error,
its bias error, and the pointing error true and the law's (what it computed
from its measurement; docs/MODEL.md section 10)."""

from __future__ import annotations

from typing import Any

import numpy as np

from sc_rt import _core
from sc_rt.results.judge.pointing import dcm_rows
from sc_rt.results.record.run import Run

__all__ = ["ARCSEC", "mrp_subtract_rows", "fill_true_tracking_error", "fill_true_rate_error",
           "fill_estimation_error", "estimation_metrics", "true_error_fields", "flies_on_estimate", "AFTER_S"]

ARCSEC = np.pi / 180.0 / 3600.0  #: [rad]
DEG_PER_H = np.pi / 180.0 / 3600.0  #: [rad/s]
AFTER_S = 30.0  #: [s] statistics over t >= this (the estimator and the loop have settled)


def _compose8(s: np.ndarray, sd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ss = np.sum(s * s, axis=1, keepdims=True)
    dd = np.sum(sd * sd, axis=1, keepdims=True)
    den = 1.0 + ss * dd + 2.0 * np.sum(sd * s, axis=1, keepdims=True)
    num = sd * (ss - 1.0) + s * (1.0 - dd) - 2.0 * np.cross(sd, s)
    return num, den


def _short(s: np.ndarray) -> np.ndarray:
    n2 = np.sum(s * s, axis=1, keepdims=True)
    return np.where(n2 > 1.0, -s / np.where(n2 > 0, n2, 1.0), s)


def mrp_subtract_rows(sigma_BN: np.ndarray, sigma_DN: np.ndarray) -> np.ndarray:
    """sigma_BD of (8) per row, short set (the core's mrp_subtract, vectorised)."""
    s, sd = np.asarray(sigma_BN, float), np.asarray(sigma_DN, float)
    num, den = _compose8(s, sd)
    n2 = np.sum(s * s, axis=1, keepdims=True)
    shadow = -s / np.where(n2 > 0, n2, 1.0)
    num2, den2 = _compose8(shadow, sd)
    use2 = (den < 0.25) & (n2 > 0) & (den2 > den)
    with np.errstate(invalid="ignore", divide="ignore"):
        return _short(np.where(use2, num2 / den2, num / den))


def true_error_fields(sensed: bool) -> tuple[str, str]:
    """The run's true tracking errors (attitude, rate): the truth against
    the reference. With sensors the derived ``sigma_BD_true``,
    ``omega_BD_B_true``; without, the law's own ``sigma_BD``, ``omega_BD_B``
    (it was fed the truth: they are the true errors)."""
    return ("sigma_BD_true", "omega_BD_B_true") if sensed else ("sigma_BD", "omega_BD_B")


def flies_on_estimate(meta: Any) -> bool:
    """The law was fed the estimate ([sensors] with [controller] measurement =
    "estimate"): its own error (``sigma_BD``) is not the true one."""
    return bool(getattr(meta, "sensors", False)) and getattr(meta, "measurement", "truth") == "estimate"


def fill_true_tracking_error(run: Run) -> None:
    """sigma_BD_true from the plant's attitude and the guidance's sigma_DN."""
    run["sigma_BD_true"][:] = mrp_subtract_rows(run["sigma_BN"], run["sigma_DN"])


def fill_true_rate_error(run: Run, guidance: Any) -> None:
    """omega_BD_B_true = omega_BN_B - [BD] omega_DN_D(t) (8), from the
    plant's rate, ``sigma_BD_true`` (filled first) and the reference's rate
    ``_core.omega_d(guidance, t)`` (closed form in t for every guidance
    kind); ``guidance``: the run's ``_core.GuidanceParams``."""
    t = run["t"]
    wd = np.array([_core.omega_d(guidance, float(tk)) for tk in t], float).reshape(-1, 3)
    C = dcm_rows(run["sigma_BD_true"])
    run["omega_BD_B_true"][:] = run["omega_BN_B"] - np.einsum("nij,nj->ni", C, wd)


def fill_estimation_error(run: Run) -> None:
    """att_est_error of the rows with an estimate: the rotation vector of the
    truth relative to the estimate, by the core's function the offline loop
    uses (so a bench run that got its estimates over the bus fills the same
    numbers bit for bit)."""
    est, truth, out = run["sigma_BN_est"], run["sigma_BN"], run["att_est_error"]
    f = _core.mrp_error_vector
    for k in np.flatnonzero(np.all(np.isfinite(est), axis=1) & np.all(np.isfinite(truth), axis=1)):
        out[k] = f(truth[k], est[k])


def _angle_arcsec(sigma: np.ndarray) -> np.ndarray:
    return np.degrees(4.0 * np.arctan(np.linalg.norm(sigma, axis=1))) * 3600.0


def _stats(x: np.ndarray) -> dict[str, Any]:
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {"rms": None, "max": None}
    return {"rms": float(np.sqrt(np.mean(x * x))), "max": float(np.max(np.abs(x)))}


def estimation_metrics(run: Run) -> dict[str, Any]:
    """Estimation and pointing errors over t >= AFTER_S [arcsec, deg/h]."""
    sel = run["t"] >= AFTER_S - 1e-9
    err = run["att_est_error"][sel] / ARCSEC  # [arcsec] per axis
    berr = (run["bias_est"][sel] - run["bias_true"][sel]) / DEG_PER_H
    nis = run["nis"][sel]
    nis = nis[np.isfinite(nis)]
    sig3 = 3.0 * np.sqrt(run["P_diag"][sel][:, 0:3]) / ARCSEC
    within = np.abs(err) <= sig3
    total = np.linalg.norm(err, axis=1) if len(err) else np.zeros(0)
    out: dict[str, Any] = {
        "estimation_error_arcsec": {
            "after_s": AFTER_S,
            "rms_axis": [_stats(err[:, i])["rms"] for i in range(3)] if len(err) else None,
            "max_axis": [_stats(err[:, i])["max"] for i in range(3)] if len(err) else None,
            "rms_total": _stats(total)["rms"],
            "max_total": _stats(total)["max"],
            "within_3sigma_fraction": float(np.mean(within)) if within.size else None,
        },
        "bias_error_deg_h": {
            "rms_axis": [_stats(berr[:, i])["rms"] for i in range(3)] if len(berr) else None,
            "final": [float(v) for v in berr[-1]] if len(berr) else None,
        },
        "nis_mean": float(np.mean(nis)) if nis.size else None,
        "star_updates": int(np.isfinite(run["nis"]).sum()),
        "nav_degraded_rows": int(np.sum((run["flags"] & 2048) != 0)),
    }
    true_pt = _angle_arcsec(run["sigma_BD_true"][sel]) if np.any(sel) else np.zeros(0)
    law_pt = _angle_arcsec(run["sigma_BD"][sel]) if np.any(sel) else np.zeros(0)
    # "true": the truth against the reference; "law": the law's own sigma_BD, what it computed from its
    # measurement (the estimate or, with measurement = "truth", the truth again)
    out["pointing_error_arcsec"] = {"after_s": AFTER_S, "true": _stats(true_pt), "law": _stats(law_pt)}
    tb = run["sigma_BD_true"][sel]
    out["pointing_error_arcsec"]["true_rms_axis"] = (
        [float(np.sqrt(np.mean((4 * np.arctan(tb[:, i]) / ARCSEC) ** 2))) for i in range(3)] if len(tb) else None)
    return out
