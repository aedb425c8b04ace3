"""The verdict of a run in words: did it meet its scenario's requirements
(the worst margin), or, for a scenario that asks for the prescribed envelope
only, did it hold that bound and when did it leave it; how long was the
controller in SAFE and why. One place, used by the CLI, the demo and the
reports, computed from ``metrics.json`` (so a report of a log and of a live
run say the same thing)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sc_rt.results.judge.requirements import worst

__all__ = ["SAFE_FLAGS", "asks_envelope", "safe_summary", "verdict_line", "pointing_arcsec", "requirements_summary",
           "outside_text"]

#: Controller flags that put it in SAFE (zero command), from wheel_cmd_t.
SAFE_FLAGS = {128: "invalid state (non-finite or beyond the safety limits)", 256: "stale state",
              512: "time not advancing",
              1024: "the law returned a non-finite command (or threw)",
              4096: "time stamp jumped (back, or ahead beyond 10 control periods)"}
MODE_SAFE = 2
AXES = "xyz"


def asks_envelope(reqs: Any) -> bool:
    """Whether the prescribed envelope of ``[controller.ppc]`` is part of
    what a run is judged by, and so shown (its timeline bands, its figure
    lines, its first violation, its Monte Carlo figure): the scenario asks
    for it with a ``kind = "envelope"`` requirement (the paper's files), or
    ``reqs`` is None (metrics older than requirements, whose verdict was the
    envelope). A scenario that states other requirements, or none, is not
    judged by it: its metric stays in metrics.json, nothing else shows it
    (docs/REQUIREMENTS.md, section 5). ``reqs``: a run's
    ``metrics["requirements"]`` (dicts) or a scenario's rows (dicts or
    Requirement objects)."""
    if reqs is None:
        return True
    return any((r.get("kind") if isinstance(r, dict) else getattr(r, "kind", None)) == "envelope" for r in reqs)


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


def _g(v: float) -> str:
    return f"{v:+.3g}"


def outside_text(r: dict[str, Any]) -> str:
    """When a requirement's values were outside its bound (its result's
    ``first_outside_s``, ``last_outside_s``): "12.3-45.6 s", "at 12.3 s"
    (one instant), "-" never."""
    first, last = r.get("first_outside_s"), r.get("last_outside_s")
    if first is None:
        return "-"
    return f"at {first:.6g} s" if last is None or last == first else f"{first:.6g}-{last:.6g} s"


def requirements_summary(reqs: list[dict[str, Any]]) -> str:
    """The requirements' part of the verdict: how many were met, which
    failed, and the worst margin (the smallest margin relative to its
    bound), in its own unit."""
    if not reqs:
        return "no requirements stated"
    judged = [r for r in reqs if r.get("passed") is not None]
    failed = [r["name"] for r in judged if not r["passed"]]
    head = (f"{len(judged) - len(failed)}/{len(judged)} requirements met" if not failed
            else f"{len(failed)} of {len(judged)} requirements failed ({', '.join(failed)})")
    campaign = [r for r in reqs if r.get("passed") is None and r.get("interpretation") in ("ensemble", "mixed")]
    for status in ("not evaluated", "not applicable"):
        if n := sum(r.get("status") == status and r not in campaign for r in reqs):
            head += f", {n} {status}"
    if campaign:  # statistics across runs: sc-rt montecarlo judges them
        head += f", {len(campaign)} across runs only (sc-rt montecarlo)"
    w = worst(reqs)
    if w is None:
        return f"none of the {len(reqs)} requirements evaluated"
    if w.get("margin") is None:
        return f"{head}, worst: {w['name']} ({w.get('note', '')})"
    if w.get("unit") == "-":  # the envelope: its margin is a fraction of the bound already
        return f"{head}, worst margin {w['name']} {_g(w['margin'])} of its bound"
    rel = w.get("relative_margin")
    share = f" ({rel:+.1%} of its bound)" if rel is not None else ""
    return f"{head}, worst margin {w['name']} {_g(w['margin'])} {w['unit']}{share}"


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
        The verdict: with requirements other than the envelope, how many
        were met and the worst margin ("no requirements stated" without
        any); with the envelope alone (the paper's scenarios), or metrics
        without a requirements entry (older files), the first bound
        violation [s] (and axis) or how long the bound held and the worst
        |lambda|; then SAFE, divergence and a partial run when they apply.
    """
    who = label or f"{m.get('scenario', '?')} {m.get('controller', '?')}"
    parts = []
    reqs = m.get("requirements")
    first = m.get("first_bound_violation_s")
    envelope_only = bool(reqs) and all(r.get("kind") == "envelope" for r in reqs)
    if reqs is not None and not envelope_only:
        parts.append(requirements_summary(reqs))
    elif first is not None:
        axis = m.get("first_bound_violation_axis")
        ax = f" (axis {AXES[axis - 1]})" if axis else ""
        parts.append(f"left its prescribed bound at {_s(first)}{ax}")
    else:
        dur = m.get("duration_s")
        held = f"bound held {dur:g} s" if dur is not None else "bound held"
        lam = m.get("max_abs_lambda")
        if lam is not None and math.isfinite(lam):  # the controller's lambda: from its estimate when fed one
            held += f", worst |lambda| {lam:.2f}" + (" (the law's)" if m.get("measurement") == "estimate" else "")
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
