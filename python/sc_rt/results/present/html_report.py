"""``report.html``: a run's report for a person, in one self-contained file.

Built from the run's output directory alone (``metrics.json``, and when
present ``timing.json``, ``trajectory.arrow``, ``report.json`` and the PNG
figures), so ``sc-rt sim``, ``sc-rt hil`` and ``sc-rt report`` write the
same page. The figures are embedded (base64 PNG), the style is inline,
nothing is fetched. Order: the verdict (the requirements, or the bound where the scenario asks
for the envelope; SAFE, faults, timing), the timeline of modes, faults and
(where asked for) the envelope's violations (inline SVG), the figures, then
every metric with its unit (the envelope's only where asked for). The
sections' tables are modules of their own: html_requirements.py,
html_timeline.py, html_telemetry.py and html_metrics.py (the metrics, timing
and inputs tables, and the page's number format ``fmt``).
"""

from __future__ import annotations

import base64
import json
from html import escape
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.results.present.html_metrics import fmt, inputs_table, metrics_table, timing_table
from sc_rt.results.present.output import run_files
from sc_rt.results.present.html_telemetry import telemetry_table
from sc_rt.results.present.html_requirements import requirements_table
from sc_rt.results.present.html_timeline import spans, timeline_of_stored, timeline_section
from sc_rt.results.present.rod_faults import live_fault_records, rod_fault_line, rod_fault_spans
from sc_rt.results.judge.verdict import asks_envelope
from sc_rt.results.record.jsonsafe import atomic_path

__all__ = ["write_html_report", "render_html", "verdict_items", "timing_text"]

#: known figures, in reading order, with a caption
FIGURES = {
    "requirements.png": ("Each requirement's values over the run, its bound over its span (shaded) and the value at "
                         "its probability; with sensors the knowledge index beside the performance one"),
    "attitude_error.png": ("True attitude tracking error sigma_BD per axis (the truth against the reference) and "
                           "the prescribed bounds dmax chi(t), -dmin chi(t); a law fed the estimate: its own "
                           "beside it"),
    "attitude_error_log.png": "The same on a log scale; dots: outside the bound",
    "pointing_error.png": ("True pointing error 4 atan|sigma_BD| [arcsec]; a law fed the estimate: its own "
                           "and the knowledge error beside it"),
    "rate_error.png": "True angular-rate tracking error omega_BD_B [rad/s]; a law fed the estimate: its own beside it",
    "wheel_commands.png": "Wheel acceleration commands after saturation [rad/s^2] and the limits",
    "wheel_speeds.png": ("Wheel speeds [rad/s] and the wheels' total momentum [N m s] against the requirements' "
                         "bounds and the actuator's speed limit"),
    "disturbance_observer.png": "Lumped disturbance delta_2, its estimate z2 and the observer error [rad/s^2]",
    "faults.png": "Wheel faults as the plant reported them",
    "timing.png": "Timing: state-to-command latency, compute and wake lateness [us]",
    "law_telemetry.png": "The law's own telemetry: its named values and the fixed slots it fills (x2d, rho_hat)",
    "magnetic_control.png": ("Magnetic control: the wheels' momentum |h_wheels_B| with the momentum manager's "
                             "on/off band, its fill, the rod dipole commands with their limits and B-dot's mode "
                             "when it ran; shaded: unloading; hatched, dash-dot to dotted: a rod's fault"),
    "gyro_calibration.png": ("The calibrating filter's gyro scale factors [ppm] and misalignments [arcsec] "
                             "with their 3 sigma (gyro_cal_est, gyro_cal_3sigma)"),
}
#: the captions of a run whose scenario does not ask for the envelope (its bounds are not drawn)
FIGURES_WITHOUT_ENVELOPE = {**FIGURES,
                            "attitude_error.png": ("True attitude tracking error sigma_BD per axis (the truth "
                                                   "against the reference); a law fed the estimate: its own "
                                                   "beside it"),
                            "attitude_error_log.png": "The same on a log scale"}
CSS = """tr.pass td { background: #e6f4ea } tr.fail td { background: #fde7e9 }
tr.not-evaluated td, tr.not-applicable td { color: #666 }

body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:24px auto;max-width:1100px;
color:#222;line-height:1.4;padding:0 16px}
h1{font-size:1.5em;margin-bottom:0.2em}
h2{font-size:1.2em;border-bottom:1px solid #ddd;padding-bottom:4px;margin-top:1.6em}
.sub{color:#666;margin-top:0}
#verdict{border:2px solid #999;border-radius:8px;padding:12px 18px;background:#fafafa}
#verdict.ok{border-color:#31a354;background:#f1faf2}#verdict.bad{border-color:#cb181d;background:#fdf1f1}
#verdict ul{margin:0.3em 0 0 0;padding-left:1.2em}#verdict-bound{font-size:1.25em;font-weight:600;margin:0}
table{border-collapse:collapse;margin:0.5em 0;font-size:0.92em}
td,th{border:1px solid #ddd;padding:3px 8px;text-align:left;vertical-align:top}th{background:#f0f0f0}
td.num{text-align:right;font-variant-numeric:tabular-nums}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #eee}figcaption{color:#555;font-size:0.9em}
.legend span{display:inline-block;margin-right:14px;font-size:0.85em}
.legend i{display:inline-block;width:14px;height:10px;margin-right:4px;vertical-align:middle}
"""
def _load(run_dir: Path) -> dict[str, Any]:
    def js(name):
        p = run_dir / name
        return json.loads(p.read_text()) if p.exists() else None

    metrics = js("metrics.json")
    if metrics is None:
        raise FileNotFoundError(f"{run_dir}: no metrics.json (not a run's output directory)")
    traj: dict[str, np.ndarray] = {}
    meta: dict[str, Any] = {}
    p = run_dir / "trajectory.npz"  # a run written before trajectory.arrow was the one format
    if (run_dir / "trajectory.arrow").exists():
        traj, meta = timeline_of_stored(run_dir / "trajectory.arrow")
    elif p.exists():
        with np.load(p, allow_pickle=False) as z:
            for k in ("t", "bound_ok", "ctrl_mode", "flags", "fault_Y", "cmd_stale"):
                if k in z.files:
                    traj[k] = z[k]
            if "meta_json" in z.files:
                meta = json.loads(str(z["meta_json"]))
    own = run_files(run_dir)  # only this run's figures, never a previous run's or yours
    figs = sorted((q for q in run_dir.glob("*.png") if own is None or q.name in own),
                  key=lambda q: (list(FIGURES).index(q.name) if q.name in FIGURES else len(FIGURES), q.name))
    return {"metrics": metrics, "timing": js("timing.json"), "report": js("report.json"), "traj": traj,
            "meta": meta, "figures": figs}


def _scheduled(d: dict[str, Any]) -> list[dict[str, Any]]:
    return list(d["meta"].get("faults") or [])


def _fault_texts(d: dict[str, Any]) -> list[str]:
    out = []
    for f in _scheduled(d):
        end = f.get("end")
        out.append(f"wheel {f['wheel']}: effectiveness L {fmt(f.get('effectiveness'))}, bias "
                   f"{fmt(f.get('bias'))} rad/s^2{', stuck' if f.get('stuck') else ''}, from {fmt(f['onset'])} s"
                   + ("" if end is None else f" to {fmt(end)} s"))
    from_log = d["meta"].get("engine") == "report" or d["report"] is not None
    sched = "Faults scheduled: " + ("; ".join(out) if out else
                                    "not known from a log (it holds what the plant applied)" if from_log else "none")
    applied = []
    Y, t = d["traj"].get("fault_Y"), d["traj"].get("t")
    if Y is not None and t is not None and np.isfinite(Y).any():
        for w in range(Y.shape[1]):
            on = np.nonzero(np.nan_to_num(Y[:, w]) > 0)[0]
            if on.size:
                applied.append(f"wheel {w + 1} from {fmt(float(t[on[0]]), 's')} s")
        live = live_fault_records(d["report"], d["timing"])  # one record of each command (not both files)
        text = "Faults applied (plant truth): " + ("; ".join(applied) if applied else "none")
        if live:
            text += f"; {len(live)} live fault command{'s' if len(live) > 1 else ''} on the bus"
        return [sched, text]
    return [sched, "Faults applied: not recorded by this engine (the plant applies the scheduled ones)"]


def _safe_text(d: dict[str, Any]) -> str:
    m, traj = d["metrics"], d["traj"]
    modes = traj.get("ctrl_mode")
    n_spans = None
    if modes is not None and np.any(modes >= 0):
        n_spans = len(spans(traj["t"], modes == 2))
    steps = m.get("safe_steps")
    if steps is None and modes is not None:
        steps = int(np.sum(modes == 2))
    if not steps:
        return "SAFE: never" if steps == 0 else "SAFE: not recorded"
    why = "; ".join(f"{k}: {v} steps" for k, v in (m.get("safe_reasons") or {}).items())
    s = f"SAFE: {steps} steps"
    if m.get("safe_from_s") is not None:
        s += f" from {fmt(m.get('safe_from_s'), 's')} s"
    if n_spans:
        s += f" in {n_spans} span{'s' if n_spans > 1 else ''}"
    return s + (f" ({why})" if why else "")


def timing_text(timing: dict[str, Any] | None) -> str:
    if not timing:
        return "Timing: offline run (no bus, no timing.json)"
    lat = timing.get("state_to_cmd_latency_us") or {}
    s = (f"Timing ({timing.get('mode', '?')}): {fmt(timing.get('steps'), 'int')} steps"
         + (f", {fmt(timing.get('steps_per_s'))} steps/s" if timing.get("steps_per_s") else "")
         + f"; state-to-command latency p50 {fmt(lat.get('p50'))} us, p99 {fmt(lat.get('p99'))} us, "
           f"max {fmt(lat.get('max'))} us; deadline misses {fmt(timing.get('deadline_misses'), 'int')}, "
           f"dropped {fmt(timing.get('dropped'), 'int')}, malformed {fmt(timing.get('malformed'), 'int')}")
    return s + "; " + _floor_text(timing, lat)


def _floor_text(timing: dict[str, Any], lat: dict[str, Any]) -> str:
    """The bench floor (LCM round trip) when timing.json carries one (a key
    with "floor": percentiles, per-series numbers or one number [us])."""
    over = timing.get("over_floor")
    if isinstance(over, dict) and over.get("line"):  # sc-rt hil's own comparison with its floor
        return str(over["line"])
    key, floor = next(((k, v) for k, v in timing.items() if "floor" in k and v), (None, None))
    if key == "floor" and isinstance(floor, dict):  # sc-rt hil's floor record: its latency series only
        for series, what in (("latency_us", "null-controller latency"), ("lcm_rtt_us", "LCM round trip")):
            v = floor.get(series)
            if isinstance(v, dict) and isinstance(v.get("p50"), (int, float)) and v["p50"] > 0:
                out = f"bench floor: {what} p50 {fmt(v['p50'])} us, p99 {fmt(v.get('p99'))} us"
                if lat.get("p50"):
                    out += f": latency p50 is {lat['p50'] / v['p50']:.2g}x the floor"
                return out
        return "bench floor: no latency series in timing.json's floor"
    if isinstance(floor, (int, float)) and not isinstance(floor, bool):
        floor = {"p50": floor}
    if isinstance(floor, dict):
        for q in ("p50", "p99"):
            if isinstance(floor.get(q), (int, float)) and floor[q] > 0:
                out = f"bench floor ({key}) {q} {fmt(floor[q])} us"
                if lat.get(q):
                    out += f": latency {q} is {lat[q] / floor[q]:.2g}x the floor"
                return out
        nums = {k: v for k, v in floor.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
        if nums:
            return f"bench floor ({key}): " + ", ".join(f"{k} {fmt(v)} us" for k, v in nums.items())
    return "no bench floor in timing.json (bench/bench_hil.py measures the LCM round trip)"


def verdict_items(d: dict[str, Any]) -> tuple[bool, str, list[tuple[str, str]]]:
    """(held, headline, [(id, text)]) of the verdict block. With requirements
    other than the prescribed envelope, the headline is theirs (how many met,
    the worst margin) and the run is judged by them; a run without any gets
    "no requirements stated", never a red failure; with the envelope alone
    (the paper's scenarios) or no requirements entry (older metrics), the
    envelope is the verdict, as before."""
    m = d["metrics"]
    first = m.get("first_bound_violation_s")
    reqs = m.get("requirements")
    by_requirements = reqs is not None and not (reqs and all(r.get("kind") == "envelope" for r in reqs))
    if by_requirements:
        from sc_rt.results.judge.verdict import requirements_summary

        head = requirements_summary(reqs)
        held = all(r.get("passed") is not False for r in reqs)
    elif first is None and m.get("steps"):
        head = f"Bound held for the whole run ({fmt(m.get('duration_s'))} s, {fmt(m.get('steps'), 'int')} steps)"
        if m.get("max_abs_lambda") is not None:  # the controller's: from its estimate when fed one
            head += f", worst |lambda| {fmt(m['max_abs_lambda'], 'lam')}"
            head += " (the law's)" if m.get("measurement") == "estimate" else ""
        held = True
    elif first is None:
        head, held = "No steps: nothing to judge", False
    else:
        head = (f"Bound violated: first at {fmt(first, 's')} s "
                f"on axis {fmt(m.get('first_bound_violation_axis'), 'axis')}")
        ok = d["traj"].get("bound_ok")
        if ok is not None and len(ok):
            head += f"; outside the bound {100.0 * float(np.mean(~np.all(ok, axis=1))):.1f} % of the run"
        held = False
    items = [("verdict-safe", _safe_text(d))]
    items += [(f"verdict-faults-{i}", s) for i, s in enumerate(_fault_texts(d))]
    rods = rod_fault_spans((d["meta"] or {}).get("rod_faults") or (), live_fault_records(d["report"], d["timing"]))
    if rods:  # the magnetorquer rods' faults, scheduled and live (results/present/rod_faults.py)
        t = d["traj"].get("t")
        items.append(("verdict-rod-faults", rod_fault_line(rods, float(t[-1]) if t is not None and len(t) else None)))
    items.append(("verdict-timing", timing_text(d["timing"])))
    if m.get("diverged") or m.get("finite") is False:
        after = m.get("diverged_after_s")
        since = f" after {fmt(after, 's')} s" if after is not None else ""
        items.append(("verdict-diverged",
                      "The run diverged" + since if m.get("diverged") else "Some values are not finite"))
        held = False
    if m.get("valid") is False:  # not a run of its law: said first, whatever it measured
        head = f"INVALID: {m.get('invalid_reason') or 'see metrics.json'}. What it measured: {head}"
        held = False
    pe = m.get("max_pointing_error_arcsec_after_30s")
    if pe is not None and not by_requirements:  # the envelope's own figure; requirements state theirs
        law = m.get("law_max_pointing_error_arcsec_after_30s")
        items.append(("verdict-pointing", f"Max true pointing error after 30 s: {fmt(pe, 'arcsec')} arcsec"
                      + ("" if law is None else f" (the law's, from its estimate: {fmt(law, 'arcsec')} arcsec)")))
    return held, head, items


def render_html(run_dir: str | Path) -> str:
    """The page for ``run_dir`` (see the module's docstring)."""
    run_dir = Path(run_dir)
    d = _load(run_dir)
    m = d["metrics"]
    held, head, items = verdict_items(d)
    title = f"{m.get('scenario', '?')}, {m.get('controller', '?')}, {m.get('engine', '?')}"
    parts = [f"<!DOCTYPE html><html lang=en><head><meta charset=utf-8><title>sc-rt run report: {escape(title)}</title>"
             f"<style>{CSS}</style></head><body>",
             f"<h1>Run report: {escape(title)}</h1>",
             f'<p class=sub>{fmt(m.get("duration_s"))} s at {fmt(m.get("control_rate_hz"))} Hz; '
             f"from {escape(run_dir.name)}/ (metrics.json{', timing.json' if d['timing'] else ''}"
             f"{', report.json' if d['report'] else ''})</p>",
             f'<section id="verdict" class="{"ok" if held else "bad"}"><p id="verdict-bound">{escape(head)}</p><ul>'
             + "".join(f'<li id="{i}">{escape(s)}</li>' for i, s in items) + "</ul></section>",
             "<h2>Requirements</h2>" + requirements_table(m.get("requirements"))]
    traj = d["traj"]
    envelope = asks_envelope(m.get("requirements"))  # its bands only where the scenario asks for it
    parts.append('<h2>Timeline</h2><section id="timeline">')
    parts.append(timeline_section(traj, d["meta"] or {}, d["report"], d["timing"], envelope))
    parts.append('</section><h2>Figures</h2><section id="figures">')
    captions = dict(FIGURES if envelope else FIGURES_WITHOUT_ENVELOPE)
    if m.get("wheel_command") == "torque":  # the wheels take motor torques: the commands' unit is N m
        captions["wheel_commands.png"] = ("Wheel torque commands after saturation [N m] and the limits; the actual "
                                          "wheel accelerations [rad/s^2] on the right axis")
    for p in d["figures"]:
        b64 = base64.b64encode(p.read_bytes()).decode()
        parts.append(f'<figure data-file="{escape(p.name)}">'
                     f'<img alt="{escape(p.name)}" src="data:image/png;base64,{b64}">'
                     f"<figcaption>{escape(p.name)}: {escape(captions.get(p.name, ''))}</figcaption></figure>")
    if not d["figures"]:
        parts.append("<p>No figures (run with plots to get them).</p>")
    parts.append('</section><h2>Law telemetry</h2><section id="telemetry">'
                 + telemetry_table(m.get("law_telemetry")) + "</section>")
    parts.append("<h2>Metrics</h2>" + metrics_table(m))
    if d["timing"]:
        parts.append("<h2>Timing</h2>" + timing_table(d["timing"]))
    parts.append(inputs_table((d["meta"] or {}).get("inputs") or {}))
    rep = d["report"]
    if rep:
        log_rows = []
        for k in ("events", "rows", "undecodable", "mode", "prefix", "parameters_from", "read_decode_s"):
            if k in rep:
                value = fmt(rep.get(k), "text" if k in ("prefix", "mode", "parameters_from") else "num")
                log_rows.append(f"<tr><td>{escape(k)}</td><td class=num>{escape(value)}</td></tr>")
        parts.append("<h2>Log</h2><table id=log><tr><th>log</th><th>value</th></tr>" + "".join(log_rows) + "</table>")
    parts.append("</body></html>\n")
    return "\n".join(parts)


def write_html_report(run_dir: str | Path, out: str | Path | None = None) -> Path:
    """Write ``report.html`` into ``run_dir`` (or ``out``), atomically."""
    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir / "report.html"
    text = render_html(run_dir)
    with atomic_path(out) as part:  # whole or not at all, like the run's other files
        part.write_text(text, encoding="utf-8")
    return out
