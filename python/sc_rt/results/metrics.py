"""Metrics of a closed-loop trajectory (offline or rebuilt from an LCM log).

One function computes ``metrics.json`` for every producer (``sc-rt sim``,
``sc-rt hil``, ``sc-rt report``), so their numbers can be compared exactly.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["METRIC_TIMES", "bound_ok", "compute_metrics", "fill_tracking_errors", "TRAJECTORY_KEYS"]

#: Times [s] at which the error norms are reported.
METRIC_TIMES = (30, 70, 100, 200, 300)

#: Arrays of trajectory.npz, one row per control instant.
TRAJECTORY_KEYS = (
    "t", "sigma_BN", "omega_BN_B", "sigma_DN", "sigma_BD", "omega_BD_B", "wheel_speed",
    "u_cmd", "u_sat", "wheel_accel", "z1", "z2", "delta2", "chi", "lam", "bound_ok",
)

LAWS_WITH_OBSERVER = ("dsc-ppc", "dsc")

#: Controller-internal telemetry: in a real-time run a state the controller
#: never used has none (its row is all NaN: missing, not non-finite).
CONTROLLER_TELEMETRY = ("z1", "z2", "chi", "lam")


def fill_tracking_errors(traj: dict[str, np.ndarray], guidance, rate: float) -> int:
    """Rows without controller telemetry (real time: states the controller
    never used) get sigma_DN, sigma_BD and omega_BD_B from the plant state and
    the desired trajectory, computed as the controller does (guidance
    integrated with RK4 steps of at most one control period, (8), (11)).
    ``guidance`` is a ``_core.GuidanceParams``. Returns the rows filled."""
    from sc_rt import _core

    missing = np.flatnonzero(np.isnan(traj["sigma_BD"]).any(axis=1))
    if missing.size == 0:
        return 0
    g = _core.Guidance(guidance, 1.0 / rate)
    g.reset(0.0)
    for k in missing:  # increasing times: the guidance only moves forward
        t = float(traj["t"][k])
        g.advance(t)
        sd = np.asarray(g.sigma_DN)
        x1 = np.asarray(_core.mrp_subtract(traj["sigma_BN"][k], sd))
        traj["sigma_DN"][k] = sd
        traj["sigma_BD"][k] = x1
        traj["omega_BD_B"][k] = traj["omega_BN_B"][k] - _core.mrp_to_dcm(x1) @ _core.omega_d(guidance, t)
    return int(missing.size)


def prescribed_chi(ppc, t: np.ndarray) -> np.ndarray:
    """chi(t) of (29) for each axis, shape (len(t), 3)."""
    chi0, chiinf, gamma = (np.asarray(v, float) for v in (ppc.chi0, ppc.chiinf, ppc.gamma))
    return (chi0 - chiinf) * np.exp(-np.outer(t, gamma)) + chiinf


def bound_ok(ppc, t: np.ndarray, sigma_BD: np.ndarray) -> np.ndarray:
    """Per axis, whether -dmin chi(t) < sigma_BD < dmax chi(t) (29); (N, 3) bool.

    Computed from the scenario's PPC parameters, independently of the
    controller's own flags, and for every law (the bound is the paper's
    performance claim, whatever the law).
    """
    chi = prescribed_chi(ppc, t)
    dmin, dmax = np.asarray(ppc.dmin, float), np.asarray(ppc.dmax, float)
    return (sigma_BD > -dmin * chi) & (sigma_BD < dmax * chi)


def _at(t: np.ndarray, values: np.ndarray, when: float) -> float | None:
    if len(t) == 0 or when > t[-1] + 1e-9:
        return None
    k = int(np.argmin(np.abs(t - when)))
    return float(np.linalg.norm(values[k]))


def _max_after(t: np.ndarray, values: np.ndarray, after: float) -> float | None:
    sel = (t >= after - 1e-9) & ~np.all(np.isnan(values.reshape(len(t), -1)), axis=1)
    if not np.any(sel):
        return None
    return float(np.nanmax(np.abs(values[sel])))


def compute_metrics(traj: dict[str, np.ndarray], *, scenario: str, controller: str, engine: str,
                    control_rate_hz: float, duration_s: float, wall_s: float) -> dict[str, Any]:
    """The metrics of one run (keys as documented in README, "metrics.json")."""
    t = traj["t"]
    ok = traj["bound_ok"]
    finite = all(bool(np.all(np.isfinite(traj[k]))) for k in TRAJECTORY_KEYS
                 if k != "bound_ok" and k not in CONTROLLER_TELEMETRY)
    for k in CONTROLLER_TELEMETRY:  # missing rows are all NaN; anything else counts
        v = traj[k]
        present = ~np.all(np.isnan(v), axis=1) if v.ndim == 2 else np.ones(len(v), bool)
        finite = finite and bool(np.all(np.isfinite(v[present])))
    first_s = first_axis = None
    bad = ~ok
    if np.any(bad):
        k = int(np.argmax(np.any(bad, axis=1)))
        first_s = float(t[k])
        first_axis = int(np.argmax(bad[k])) + 1  # 1-based axis
    sat = np.any(traj["u_cmd"] != traj["u_sat"], axis=1) if len(t) else np.zeros(0, bool)
    obs = None
    if controller in LAWS_WITH_OBSERVER:
        obs = _max_after(t, traj["z2"] - traj["delta2"], 30.0)
    return {
        "scenario": scenario,
        "controller": controller,
        "engine": engine,
        "control_rate_hz": float(control_rate_hz),
        "duration_s": float(duration_s),
        "steps": int(len(t)),
        "wall_s": float(wall_s),
        "finite": finite,
        "first_bound_violation_s": first_s,
        "first_bound_violation_axis": first_axis,
        "sigma_e_norm": {str(s): _at(t, traj["sigma_BD"], s) for s in METRIC_TIMES},
        "omega_e_norm": {str(s): _at(t, traj["omega_BD_B"], s) for s in METRIC_TIMES},
        "max_abs_omega_e_after_70s": _max_after(t, traj["omega_BD_B"], 70.0),
        "max_observer_error_after_30s": obs,
        "max_abs_u_cmd": float(np.max(np.abs(traj["u_cmd"]))) if len(t) else None,
        "max_abs_wheel_accel": float(np.max(np.abs(traj["wheel_accel"]))) if len(t) else None,
        "saturated_fraction": float(np.mean(sat)) if len(t) else 0.0,
        "final_wheel_speed": [float(v) for v in traj["wheel_speed"][-1]] if len(t) else None,
    }


def json_safe(obj: Any) -> Any:
    """NaN/inf become null so that metrics.json stays valid JSON."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    return obj
