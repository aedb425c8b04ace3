"""The verdict rule: whether a claim holds in a case, and the claim's verdict.

A claim is checked in every case it covers (fault-free, faults). In each case
it *holds* by a plain comparison of the measured number with the claim
(:func:`case_holds`):

- ``inside``: the law has no bound violation in the run (first violation null);
- ``leaves``: the law has a bound violation (first violation not null);
- ``below``: the measured maximum is below the claim's threshold;
- ``within_limits``: every commanded wheel acceleration u_cmd (before the
  saturation the plant applies) lies in [umin, umax].

The verdict (:func:`verdict_of`) is "reproduced" when the claim holds in
every case it covers, "not reproduced" when it holds in none, "partly"
otherwise.
"""

from __future__ import annotations

from typing import Any

__all__ = ["RULE", "case_holds", "verdict_of"]

#: The rule as the claims table states it.
RULE = ("a case holds by comparing the measured number with the claim (inside: no bound "
        "violation; leaves: a bound violation; below: value < threshold; within_limits: "
        "umin <= u_cmd <= umax at every step); verdict: reproduced if every case holds, "
        "not reproduced if none does, partly otherwise")


def case_holds(case: dict[str, Any]) -> bool:
    """Whether one case of a claim holds, from its numbers (the documented rule)."""
    kind = case["kind"]
    if kind == "inside":
        return case["first_bound_violation_s"] is None
    if kind == "leaves":
        return case["first_bound_violation_s"] is not None
    if kind == "below":
        return case["value"] is not None and case["value"] < case["threshold"]
    if kind == "within_limits":
        return case["u_cmd_min"] >= case["umin"] and case["u_cmd_max"] <= case["umax"]
    raise ValueError(f"unknown kind {kind!r}")


def verdict_of(cases: dict[str, dict[str, Any]]) -> str:
    held = [case_holds(c) for c in cases.values()]
    if all(held):
        return "reproduced"
    if not any(held):
        return "not reproduced"
    return "partly"
