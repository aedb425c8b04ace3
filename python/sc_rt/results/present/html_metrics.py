"""The tables of numbers that close ``report.html`` (sc_rt.results.present.html_report):
every metric of metrics.json with its label and unit (the envelope's only
where the scenario asks for it), the timing of timing.json, the run's inputs
(``RunMeta.inputs``), and ``fmt``, the one number format of the page."""

from __future__ import annotations

import json
import math
from html import escape
from typing import Any

from sc_rt.results.judge.verdict import asks_envelope

__all__ = ["fmt", "metrics_table", "timing_table", "inputs_table", "pointing_arcsec_of_mrp_norm", "METRIC_ROWS",
           "ENVELOPE_METRICS"]

AXES = "xyz"
ARCSEC = 180.0 / math.pi * 3600.0
#: metrics.json keys about the envelope: shown only where the scenario asks for it (asks_envelope)
ENVELOPE_METRICS = ("first_bound_violation_s", "first_bound_violation_axis", "max_abs_lambda")
#: metrics.json keys: (label, unit, kind); kind: s (time), pct, axis, num, arcsec
METRIC_ROWS = {
    "scenario": ("scenario", "", "text"), "controller": ("control law", "", "text"),
    "engine": ("engine", "", "text"), "control_rate_hz": ("control rate", "Hz", "num"),
    "duration_s": ("duration", "s", "num"), "steps": ("steps", "", "int"), "wall_s": ("wall time", "s", "num"),
    "finite": ("all values finite", "", "bool"),
    "first_bound_violation_s": ("first bound violation", "s", "s"),
    "first_bound_violation_axis": ("axis of the first violation", "", "axis"),
    "measurement": ("what the law was fed (truth: its errors are the true ones)", "", "text"),
    "max_pointing_error_arcsec_after_30s": ("max true pointing error after 30 s", "arcsec", "arcsec"),
    "law_max_pointing_error_arcsec_after_30s": ("max pointing error after 30 s, the law's (its estimate)",
                                                "arcsec", "arcsec"),
    "max_abs_omega_e_after_70s": ("max true |omega_BD_B| after 70 s", "rad/s", "num"),
    "law_max_abs_omega_e_after_70s": ("max |omega_BD_B| after 70 s, the law's (its estimate)", "rad/s", "num"),
    "max_observer_error_after_30s": ("max observer error |z2 - delta_2| after 30 s", "rad/s^2", "num"),
    "max_abs_u_cmd": ("max |u_cmd| before saturation", "rad/s^2", "num"),
    "max_abs_wheel_accel": ("max |wheel acceleration| applied", "rad/s^2", "num"),
    "saturated_fraction": ("steps with a saturated command", "%", "pct"),
    "final_wheel_speed": ("final wheel speeds", "rad/s", "list"),
    "safe_steps": ("steps in SAFE", "", "int"), "safe_from_s": ("SAFE from", "s", "s"),
    "max_abs_lambda": ("max |lambda| (sigma_BD / chi, the controller's)", "-", "lam"),
    "diverged_after_s": ("diverged after", "s", "s"),
}


def pointing_arcsec_of_mrp_norm(n: float) -> float:
    """Principal rotation angle 4 atan|sigma| of an MRP norm, in arcsec."""
    return 4.0 * math.atan(n) * ARCSEC


def fmt(v: Any, kind: str = "num") -> str:
    """A value rounded to what is meaningful (3 significant digits)."""
    if v is None:
        return "–"
    if kind == "bool" or isinstance(v, bool):
        return "yes" if v else "no"
    if kind == "axis":
        return AXES[int(v) - 1] if isinstance(v, int) and 1 <= v <= 3 else str(v)
    if kind == "text":
        return str(v)
    if kind == "list":
        return ", ".join(fmt(x) for x in v)
    if kind == "lam" and isinstance(v, float):  # how close to the bound (1): more digits
        return f"{v:.6g}"
    if kind == "pct":
        return f"{100.0 * v:.1f}"
    if isinstance(v, int) or kind == "int":
        return f"{int(v):,}".replace(",", " ")
    if not isinstance(v, (int, float)):
        return escape(json.dumps(v))
    if not math.isfinite(v):
        return str(v)
    if kind == "s":
        return f"{v:.2f}"
    if kind == "arcsec" and abs(v) >= 100:
        return f"{v:,.0f}".replace(",", " ")
    if v != 0 and (abs(v) >= 1e6 or abs(v) < 1e-3):
        return f"{v:.3g}"
    return f"{v:.4g}" if abs(v) >= 1000 else f"{v:.3g}"


def metrics_table(m: dict[str, Any]) -> str:
    rows = []
    envelope = asks_envelope(m.get("requirements"))
    for k, v in m.items():
        if k in ENVELOPE_METRICS and not envelope:  # not what this scenario asks: metrics.json keeps it
            continue
        if k in ("sigma_e_norm", "omega_e_norm", "law_sigma_e_norm", "law_omega_e_norm") and isinstance(v, dict):
            # the true errors (the truth against the reference); law_*: the law's, from its estimate
            who, whose = ("", ", the law's (its estimate)") if k.startswith("law_") else ("true ", "")
            for tk, x in v.items():
                if k.endswith("sigma_e_norm"):
                    rows.append((f"{who}pointing error 4 atan|sigma_BD| at {tk} s{whose}",
                                 fmt(None if x is None else pointing_arcsec_of_mrp_norm(x), "arcsec"), "arcsec"))
                    rows.append((f"{who}|sigma_BD| at {tk} s{whose}", fmt(x), "-"))
                else:
                    rows.append((f"{who}|omega_BD_B| at {tk} s{whose}", fmt(x), "rad/s"))
            continue
        if k == "law_telemetry":  # its own section
            continue
        if k == "safe_reasons":
            rows.append(("SAFE reasons", escape("; ".join(f"{a}: {b}" for a, b in v.items())) or "–", "steps"))
            continue
        if k in ("units", "wheel_command", "law_command"):  # the units column; the command line below
            continue
        label, unit, kind = METRIC_ROWS.get(k, (k, "", "num"))
        unit = (m.get("units") or {}).get(k, unit)  # the run's own (a wheel command: rad/s^2 or N m)
        rows.append((label, escape(fmt(v, kind)) if kind == "text" else fmt(v, kind), unit))
    if m.get("wheel_command"):
        rows.append(("wheel command (what the wheels take; the law's, converted when it differs)",
                     escape(f"{m['wheel_command']}" + (f", law: {m['law_command']}" if m.get("law_command") else "")),
                     (m.get("units") or {}).get("max_abs_u_cmd", "")))
    body = "".join(f"<tr><td>{escape(a)}</td><td class=num>{b}</td><td>{escape(c)}</td></tr>" for a, b, c in rows)
    return f'<table id="metrics"><tr><th>metric</th><th>value</th><th>unit</th></tr>{body}</table>'


def timing_table(t: dict[str, Any]) -> str:
    rows = []
    for k, v in t.items():
        unit = ("us" if k.endswith("_us") else "1/s" if k.endswith("_per_s") else "s" if k.endswith("_s")
                else "Hz" if k.endswith("_hz") else "")
        if isinstance(v, dict) and {"p50", "p99", "max"} <= set(v):
            val = " / ".join(fmt(v[q]) for q in ("p50", "p99", "max"))
            rows.append((f"{k} (p50 / p99 / max)", val, unit))
        elif isinstance(v, (dict, list)):
            rows.append((k, escape(json.dumps(v))[:300] if v else "–", ""))
        else:
            rows.append((k, escape(fmt(v, "text" if isinstance(v, str) else "num")), unit))
    body = "".join(f"<tr><td>{escape(a)}</td><td class=num>{b}</td><td>{escape(c)}</td></tr>" for a, b, c in rows)
    return f'<table id="timing"><tr><th>timing</th><th>value</th><th>unit</th></tr>{body}</table>'


def inputs_table(inputs: dict) -> str:
    """What the run was made from (RunMeta.inputs): the scenario file and its
    SHA-256, the overrides, the law's parameters as run, sc-rt's version and commit."""
    if not inputs:
        return "<h2>Inputs</h2><p>Not recorded (a run of an older sc-rt).</p>"
    rows = []
    for k in ("scenario_file", "scenario_sha256", "sc_rt_version", "sc_rt_commit"):
        rows.append(f"<tr><td>{escape(k)}</td><td>{escape(str(inputs.get(k) if inputs.get(k) is not None else '-'))}"
                    "</td></tr>")
    for k, v in (inputs.get("overrides") or {}).items():
        rows.append(f"<tr><td>override {escape(k)}</td><td>{escape(str(v))}</td></tr>")
    for k, v in (inputs.get("law_params") or {}).items():
        rows.append(f"<tr><td>law parameter {escape(k)}</td><td class=num>{escape(str(v))}</td></tr>")
    return "<h2>Inputs</h2><table id=inputs><tr><th>input</th><th>value</th></tr>" + "".join(rows) + "</table>"
