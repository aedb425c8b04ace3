"""The pointing errors and the window statistics the requirements are
built from (docs/REQUIREMENTS.md, section 2): attitude errors as rotation
vectors, the error a requirement's ``axis`` selects, the nearest-rank
quantile, non-overlapping windows with their means (MPE) and the relative
error of each instant in them (RPE), pairs of windows (PDE, PRE), the settling time and the
wheels' momentum. Pure numpy, vectorised over rows; nothing here knows
about a run or a scenario.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["dcm_rows", "cone_vector", "error_signal", "mrp_subtract", "mrp_to_rotvec", "nearest_rank",
           "pair_differences", "relative_errors", "settling_time", "wheel_momentum", "window_means", "windows"]


# --------------------------------------------------------------------------- #
# Attitude errors as rotation vectors.


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


def dcm_rows(sigma: np.ndarray) -> np.ndarray:
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
    d = dcm_rows(sigma) @ b  # the desired direction in B
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
    """RPE per instant (ECSS-E-ST-60-10C 3.2.12): |error - the mean of the
    window that contains it|, (n_windows, n_per) for the windows ``w``
    (n_windows, n_per, d). Its largest value per window (``.max(axis=1)``)
    bounds every instant of that window."""
    return np.linalg.norm(w - w.mean(axis=1, keepdims=True), axis=2)


def pair_differences(e: np.ndarray, n_first: int, n_per: int, shift: int) -> tuple[np.ndarray, np.ndarray]:
    """PDE/PRE per pair of windows: the first windows tile ``e[:n_first]``
    (non-overlapping, ``n_per`` rows each, from row 0), each compared with
    the window of ``n_per`` rows that starts ``shift`` rows after it (inside
    ``e``); the value is |mean of the later window - mean of the first|.
    Returns (the first windows' start rows, the values), for the pairs whose
    later window ends within ``e``."""
    e = np.asarray(e, float)
    e = e.reshape(len(e), -1)
    starts = np.arange(0, n_first - n_per + 1, n_per) if n_first >= n_per else np.zeros(0, int)
    starts = starts[starts + shift + n_per <= len(e)]
    if starts.size == 0:
        return starts, np.zeros(0)
    c = np.vstack([np.zeros((1, e.shape[1])), np.cumsum(e, axis=0)])  # window sums from the running sum

    def mean_at(s: np.ndarray) -> np.ndarray:
        return (c[s + n_per] - c[s]) / n_per

    return starts, np.linalg.norm(mean_at(starts + shift) - mean_at(starts), axis=1)


def settling_time(t: np.ndarray, magnitude: np.ndarray, band: float) -> float | None:
    """The first instant from which every later sample is within ``band``
    (<=); a non-finite sample counts as outside. None: the last one is outside."""
    inside = np.isfinite(magnitude) & (magnitude <= band)
    if len(inside) == 0 or not inside[-1]:
        return None
    outside = np.flatnonzero(~inside)
    return float(t[outside[-1] + 1]) if outside.size else float(t[0])


def wheel_momentum(wheel_speed: np.ndarray, Cbar: Any, Jw: Any) -> np.ndarray:
    """The wheels' total angular momentum in the body frame, h_w = Cbar
    (Jw Omega) [N m s] per row (N, 3), of the wheel speeds relative to the
    body (N, 4) [rad/s], the spin axes ``Cbar`` (3, 4) and inertias ``Jw`` (4,)."""
    return (np.asarray(wheel_speed, float) * np.asarray(Jw, float)) @ np.asarray(Cbar, float).T


#: The core's ctrl_mode of a row whose law commanded, and the flag of a
#: degraded navigation (sc_rt._core.MODE_NORMAL, FLAG_NAV_DEGRADED;
#: tests/test_requirements.py checks they agree).
MODE_NORMAL = 1
FLAG_NAV_DEGRADED = 2048


def mode_mask(run: Any, mode: str) -> np.ndarray:
    """The rows (bool, N) inside a requirement's ``mode`` window: "normal"
    (the law commanded: ctrl_mode NORMAL), "nav_ok" (no FLAG_NAV_DEGRADED),
    "" (every row)."""
    n = len(run["t"])
    if mode == "normal":
        return np.asarray(run["ctrl_mode"]) == MODE_NORMAL
    if mode == "nav_ok":
        return (np.asarray(run["flags"]) & FLAG_NAV_DEGRADED) == 0
    if mode:
        raise ValueError(f"unknown requirement mode {mode!r}")
    return np.ones(n, bool)


def outside_mode(sigma: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """``sigma`` with the rows outside the mode window set to NaN: the
    indices leave them out as they leave out non-finite samples (an
    instantaneous index its samples, a windowed one every window or pair
    that touches them)."""
    out = np.array(sigma, float, copy=True)
    out[~np.asarray(inside, bool)] = np.nan
    return out

