"""The verdict of a run in words: did it hold its prescribed bound, when
did it leave it, how long was the controller in SAFE and why. One place,
used by the CLI, the demo and the reports, computed from ``metrics.json``
(so a report of a log and of a live run say the same thing)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["SAFE_FLAGS", "safe_summary", "verdict_line", "pointing_arcsec"]

#: Controller flags that put it in SAFE (zero command), from wheel_cmd_t.
SAFE_FLAGS = {128: "invalid state (non-finite or beyond the safety limits)", 256: "stale state",
              512: "time not advancing",
              1024: "the law returned a non-finite command (or threw)"}
MODE_SAFE = 2
AXES = "xyz"


def pointing_arcsec(sigma: np.ndarray) -> np.ndarray:
    """Principal rotation angle of an MRP error, 4 atan|sigma|, in arcsec."""
    n = np.linalg.norm(np.asarray(sigma, float).reshape(-1, 3), axis=1)
    return np.degrees(4.0 * np.arctan(n)) * 3600.0


def safe_summary(t: np.ndarray, ctrl_mode: np.ndarray, flags: np.ndarray) -> dict[str, Any]:
    """SAFE steps, when SAFE first began, and the reasons by flag, from the
    run's ``ctrl_mode`` (when the producer knows it) or its flags."""
    known = ctrl_mode >= 0
    safe_bits = sum(SAFE_FLAGS)
    by_flags = (flags & safe_bits) != 0
    safe = np.where(known, ctrl_mode == MODE_SAFE, by_flags)
    reasons = {text: int(np.sum(safe & ((flags & bit) != 0))) for bit, text in SAFE_FLAGS.items()}
    first = float(t[int(np.argmax(safe))]) if np.any(safe) else None
    return {"safe_steps": int(np.sum(safe)), "safe_from_s": first,
            "safe_reasons": {k: v for k, v in reasons.items() if v}}


def _s(v: float) -> str:
    return f"{v:.2f} s"


def verdict_line(m: dict[str, Any], label: str | None = None) -> str:
    """One line: "paper DSC+PPC: left its prescribed bound at 4.10 s (axis z),
    SAFE from 240.0 s" or "...: bound held 300 s, worst |lambda| 0.88".

    Parameters
    ----------
    m : dict
        A run's metrics (``run.metrics``, or metrics.json read back); missing
        keys are left out of the line.
    label : str, optional
        Who ran, the line's start. None: the metrics' "scenario" and
        "controller", space-separated ("?" for a missing one).

    Returns
    -------
    str
        The verdict: the first bound violation [s] (and axis) or how long the
        bound held and the worst |lambda|; then SAFE, divergence and a
        partial run when they apply.
    """
    who = label or f"{m.get('scenario', '?')} {m.get('controller', '?')}"
    parts = []
    first = m.get("first_bound_violation_s")
    if first is not None:
        axis = m.get("first_bound_violation_axis")
        ax = f" (axis {AXES[axis - 1]})" if axis else ""
        parts.append(f"left its prescribed bound at {_s(first)}{ax}")
    else:
        dur = m.get("duration_s")
        held = f"bound held {dur:g} s" if dur is not None else "bound held"
        lam = m.get("max_abs_lambda")
        if lam is not None and math.isfinite(lam):
            held += f", worst |lambda| {lam:.2f}"
        parts.append(held)
    if m.get("safe_steps"):
        start = m.get("safe_from_s")
        parts.append(f"SAFE from {start:.1f} s ({m['safe_steps']} steps)" if start is not None
                     else f"SAFE {m['safe_steps']} steps")
    if m.get("diverged"):
        parts.append(f"diverged after {m.get('diverged_after_s', float('nan')):.1f} s")
    if m.get("partial"):
        parts.append("PARTIAL run")
    return f"{who}: " + ", ".join(parts)
