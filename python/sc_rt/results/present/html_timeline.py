"""The timeline of a run as an inline SVG: controller modes, wheel faults
(scheduled, and active in the plant's truth), the magnetorquer rods' faults
(scheduled, and sent live: results/present/rod_faults.py), command gaps and,
when given (a scenario that asks for the envelope), the spans outside the
prescribed bound per axis. Pure data in, SVG text out; ``timeline_section``
is report.html's section of it, from a run directory's files."""

from __future__ import annotations

import json
from html import escape
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.results.present.rod_faults import (RodCommand, RodFaultSpan, live_fault_records, rod_commands,
                                              rod_fault_spans)

__all__ = ["spans", "timeline_svg", "timeline_section", "timeline_of_stored", "MODE_NAMES"]

MODE_NAMES = {-1: "unknown", 0: "INIT", 1: "NORMAL", 2: "SAFE"}
MODE_COLOURS = {-1: "#d9d9d9", 0: "#9ecae1", 1: "#74c476", 2: "#de2d26"}
#: a rod fault's outline (scheduled: dashed) and fill (sent live)
ROD_STROKE, ROD_FILL = "#1b7837", "#a6dba0"
W, LEFT, RIGHT, LANE, TOP = 1000, 150, 20, 22, 10


def spans(t: np.ndarray, on: np.ndarray) -> list[tuple[float, float]]:
    """[start, end) spans of t where ``on``; a span ends at the next row's
    time (or the last time)."""
    t = np.asarray(t, float)
    on = np.asarray(on, bool)
    if t.size == 0:
        return []
    edge = np.diff(np.concatenate(([0], on.astype(np.int8), [0])))
    starts, ends = np.nonzero(edge == 1)[0], np.nonzero(edge == -1)[0]
    return [(float(t[a]), float(t[b]) if b < t.size else float(t[-1])) for a, b in zip(starts, ends)]


def value_spans(t: np.ndarray, v: np.ndarray) -> list[tuple[float, float, int]]:
    """(start, end, value) of the runs of equal values of ``v``."""
    t, v = np.asarray(t, float), np.asarray(v)
    if t.size == 0:
        return []
    cut = np.nonzero(np.diff(v) != 0)[0] + 1
    starts = np.concatenate(([0], cut))
    ends = np.concatenate((cut, [t.size]))
    return [(float(t[a]), float(t[b]) if b < t.size else float(t[-1]), int(v[a])) for a, b in zip(starts, ends)]


def _x(t: float, t0: float, t1: float) -> float:
    return LEFT + (W - LEFT - RIGHT) * ((t - t0) / (t1 - t0) if t1 > t0 else 0.0)


def _bar(y: float, a: float, b: float, t0: float, t1: float, fill: str, title: str, **kw) -> str:
    x0, x1 = _x(a, t0, t1), _x(b, t0, t1)
    # class_ is the attribute class (a keyword in Python); fill_opacity is fill-opacity
    extra = "".join(f' {k.rstrip("_").replace("_", "-")}="{v}"' for k, v in kw.items())
    return (f'<rect x="{x0:.1f}" y="{y + 3:.1f}" width="{max(x1 - x0, 1.0):.1f}" height="{LANE - 6}" '
            f'fill="{fill}"{extra}><title>{escape(title)}</title></rect>')


def timeline_svg(t: np.ndarray, *, modes: np.ndarray | None, bound_ok: np.ndarray | None,
                 scheduled: list[dict[str, Any]], fault_Y: np.ndarray | None,
                 cmd_stale: np.ndarray | None, commands: list[dict[str, Any]],
                 rods: list[RodFaultSpan] | tuple = (), rod_cmds: list[RodCommand] | tuple = (),
                 n_rods: int = 0) -> str:
    """The SVG (one lane each: mode, wheels 1..4, the rods 1..``n_rods``
    and any other rod with a fault in ``rods`` or a command in ``rod_cmds``,
    command gaps, and with ``bound_ok`` the prescribed bound x/y/z)."""
    t = np.asarray(t, float)
    t0, t1 = (float(t[0]), float(t[-1])) if t.size else (0.0, 1.0)
    lanes: list[tuple[str, list[str]]] = []
    mode_bars = []
    if modes is not None and t.size:
        for a, b, m in value_spans(t, modes):
            name = MODE_NAMES.get(m, str(m))
            mode_bars.append(_bar(0, a, b, t0, t1, MODE_COLOURS.get(m, "#bbbbbb"), f"{name} {a:.2f}-{b:.2f} s",
                                  class_=f"mode-{name}"))
    lanes.append(("controller mode", mode_bars))
    for w in range(1, 5):
        bars = []
        for f in scheduled:
            if int(f.get("wheel", 0)) != w:
                continue
            end = f.get("end")
            b = t1 if end is None else min(float(end), t1)
            bars.append(_bar(0, float(f["onset"]), b, t0, t1, "none",
                             f"scheduled: L {f.get('effectiveness')}, bias {f.get('bias')} rad/s^2, "
                             f"from {f['onset']} s" + ("" if end is None else f" to {end} s"),
                             stroke="#6a51a3", stroke_width="2", stroke_dasharray="5,3"))
        if fault_Y is not None and t.size:
            y = np.asarray(fault_Y, float)[:, w - 1]
            for a, b in spans(t, np.nan_to_num(y) > 0):
                bars.append(_bar(0, a, b, t0, t1, "#9e9ac8", f"active in the plant (Y > 0) {a:.2f}-{b:.2f} s",
                                 fill_opacity="0.8"))
        for c in commands:
            if int(c.get("wheel", 0)) == w and c.get("t") is not None:
                bars.append(_bar(0, float(c["t"]), float(c["t"]), t0, t1, "#000000",
                                 f"fault command {c.get('action', '')} at {c['t']} s"))
        lanes.append((f"wheel {w} fault", bars))
    for r in range(1, max([n_rods, *(f.rod for f in rods), *(c.rod for c in rod_cmds)]) + 1):
        bars = [_bar(0, max(f.onset, t0), t1 if f.end is None else min(f.end, t1), t0, t1,
                     "none" if f.source == "scheduled" else ROD_FILL, f.text(), class_=f"rod-fault {f.source}",
                     stroke=ROD_STROKE, stroke_width="2", **({"stroke_dasharray": "5,3"} if f.source == "scheduled"
                                                            else {}))
                for f in rods if f.rod == r and f.onset <= t1 and (f.end is None or f.end > t0)]  # within the run
        bars += [_bar(0, c.received, c.received, t0, t1, "#000000",
                      f"rod fault command {c.action} rod {c.rod} at {c.received:g} s", class_="rod-fault-command")
                 for c in rod_cmds if c.rod == r and t0 <= c.received <= t1]
        lanes.append((f"rod {r} fault", bars))
    if cmd_stale is not None and t.size:
        lanes.append(("command gaps", [_bar(0, a, b, t0, t1, "#fd8d3c", f"no valid command {a:.2f}-{b:.2f} s")
                                       for a, b in spans(t, np.asarray(cmd_stale) != 0)]))
    if bound_ok is not None and t.size:
        ok = np.asarray(bound_ok, bool)
        for i, ax in enumerate("xyz"):
            lanes.append((f"outside bound, {ax}", [
                _bar(0, a, b, t0, t1, "#cb181d", f"outside the prescribed bound on {ax}: {a:.2f}-{b:.2f} s",
                     class_="violation") for a, b in spans(t, ~ok[:, i])]))
    h = TOP + LANE * len(lanes) + 30
    out = [f'<svg viewBox="0 0 {W} {h}" width="100%" role="img" '
           f'aria-label="timeline of modes, faults{" and bound violations" if bound_ok is not None else ""}" '
           'id="timeline-svg">']
    for k, (name, bars) in enumerate(lanes):
        y = TOP + k * LANE
        out.append(f'<rect x="{LEFT}" y="{y + 1}" width="{W - LEFT - RIGHT}" height="{LANE - 2}" fill="#f7f7f7"/>')
        out.append(f'<text x="{LEFT - 6}" y="{y + LANE / 2 + 4}" text-anchor="end" font-size="12">'
                   f'{escape(name)}</text>')
        out.append(f'<g transform="translate(0,{y})">' + "".join(bars) + "</g>")
    ya = TOP + LANE * len(lanes) + 4
    for tick in np.linspace(t0, t1, 7):
        x = _x(float(tick), t0, t1)
        out.append(f'<line x1="{x:.1f}" y1="{TOP}" x2="{x:.1f}" y2="{ya}" stroke="#cccccc" stroke-width="0.5"/>')
        out.append(f'<text x="{x:.1f}" y="{ya + 14}" text-anchor="middle" font-size="11">{tick:.4g} s</text>')
    out.append("</svg>")
    return "\n".join(out)


def timeline_of_stored(path: Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """What the timeline draws of a run on disk (trajectory.arrow), read a
    chunk at a time and kept at its change points only: the rows where the
    mode, the flags, a command gap, the bound or a fault's activity (Y > 0)
    changes, and the last row. Every span the timeline draws ends at the
    next change, so the spans are those of every row. Also the run's meta
    (``sc-rt:meta``) as JSON data."""
    from sc_rt.results.record.store import ChunkReader

    r = ChunkReader(path)
    names = ("t", "bound_ok", "ctrl_mode", "flags", "fault_Y", "cmd_stale")
    kept: dict[str, list[np.ndarray]] = {k: [] for k in names}
    prev = None
    for i in range(r.n_batches):
        c = r.batch(i, names)
        c["fault_Y"] = (np.nan_to_num(c["fault_Y"]) > 0).astype(float)  # all the timeline uses of it
        key = np.column_stack([c["bound_ok"], c["ctrl_mode"], c["flags"], c["fault_Y"], c["cmd_stale"] != 0])
        change = np.r_[True, np.any(key[1:] != key[:-1], axis=1)]
        if prev is not None:
            change[0] = bool(np.any(key[0] != prev))
        if i == r.n_batches - 1:
            change[-1] = True
        prev = key[-1]
        for k in names:
            kept[k].append(c[k][change])
    meta = json.loads(r.metadata.get("sc-rt:meta", "{}"))
    r.close()
    return ({k: np.concatenate(v) for k, v in kept.items()} if r.n_batches else {}), meta


def timeline_section(traj: dict[str, np.ndarray], meta: dict[str, Any], report: dict[str, Any] | None,
                     timing: dict[str, Any] | None, envelope: bool) -> str:
    """report.html's timeline (the SVG and its legend) of a run directory's
    rows ``traj`` (``timeline_of_stored``), its meta, report.json (a log's
    report) and timing.json; the envelope's lanes only with ``envelope``."""
    if "t" not in traj:
        return "<p>No trajectory.arrow: no timeline.</p>"
    parts = []
    modes = traj.get("ctrl_mode")
    if modes is not None and not np.any(modes >= 0):
        modes = None
        parts.append("<p>Controller mode not recorded by this engine.</p>")
    live = live_fault_records(report, timing)
    cmds = [{"wheel": c.get("wheel"), "t": c.get("t_sim_at_receipt", c.get("t")), "action": c.get("action")}
            for c in live if c.get("wheel") is not None]  # the wheels' lanes (a rod's command names a "rod")
    rods, rod_cmds = rod_fault_spans(meta.get("rod_faults") or (), live), rod_commands(live)
    n_rods = len((meta.get("magnetic") or {}).get("rod_max_dipole") or ())
    parts.append(timeline_svg(traj["t"], modes=modes, bound_ok=traj.get("bound_ok") if envelope else None,
                              scheduled=list(meta.get("faults") or []), fault_Y=traj.get("fault_Y"),
                              cmd_stale=traj.get("cmd_stale"), commands=cmds, rods=rods, rod_cmds=rod_cmds,
                              n_rods=n_rods))
    legend = [(c, f"mode {n}") for n, c in (("INIT", "#9ecae1"), ("NORMAL", "#74c476"), ("SAFE", "#de2d26"))]
    legend += [("#9e9ac8", "fault active (Y > 0)"), ("#ffffff;border:2px dashed #6a51a3", "fault scheduled"),
               ("#fd8d3c", "no valid command")]
    if rods or rod_cmds or n_rods:
        legend += [(f"#ffffff;border:2px dashed {ROD_STROKE}", "rod fault scheduled"),
                   (f"{ROD_FILL};border:2px solid {ROD_STROKE}", "rod fault sent live"),
                   ("#000000", "live fault command received")]
    if envelope:
        legend.append(("#cb181d", "outside the prescribed bound"))
    parts.append('<p class=legend>' + "".join(f'<span><i style="background:{c}"></i>{escape(n)}</span>'
                                               for c, n in legend) + "</p>")
    return "\n".join(parts)
