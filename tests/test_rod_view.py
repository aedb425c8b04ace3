"""The magnetorquer rods' faults shown (issue 43 item 8): in report.html's
timeline and verdict, and in magnetic_control.png (the figure of wheel
momentum and dipoles), scheduled from the scenario and sent live; and the
shipped Foxglove layout's Rods tab reads fields the bus carries.

Checked against what the code under test does not compute: the scenario's
own ``[[magnetorquers.faults]]`` numbers and the timeline's geometry by
hand; the live spans against the emulator's receiver (emulator/receiver.py:
what the plant applies after each command, sampled between receipts); the
layout's paths against the JSON schemas generated from the ``.lcm`` files.
A lockstep run's log with live rod faults: tests/test_rod_fault.py.

Every test here fails on the main before this change: its report had no rod
lanes nor rod fault line, its magnetic figure marked no rod fault, there was
no results/present/rod_faults.py, and its layout had no Rods tab.
"""

from __future__ import annotations

import re
from collections import Counter

import matplotlib.pyplot as plt
import numpy as np
import pytest
import sc_rt_lcm

from magscn import H0, MOMENTUM, mag_scenario
from sc_rt import simulate
from sc_rt.emulator.receiver import Receiver
from sc_rt.emulator.state import Shared
from sc_rt.model.rods import RodFault
from sc_rt.results.present import magnetic_figure as magfig
from sc_rt.results.present.html_report import write_html_report
from sc_rt.results.present.output import write_run
from sc_rt.results.present.rod_faults import rod_fault_spans
from sc_rt.scenario.overrides import with_overrides
from sc_rt.scenario.reader import load_scenario
from sc_rt.tools.faultcmd import rod_clear_msg, rod_inject_msg

#: rod 3 stuck at 5 A m^2 on [2, 4) s of a 6 s run
FAULT = """
[[magnetorquers.faults]]
rod = 3
kind = "stuck"
dipole = 5.0
onset = 2.0
end = 4.0
"""
DURATION = 6.0
TEXT = "rod 3 stuck at 5 A m^2 (scheduled) from 2 s to 4 s"


def _run(extra: str):
    return simulate(mag_scenario(MOMENTUM + extra, duration=DURATION, wheel_speed=tuple(10 * v for v in H0)),
                    engine="cpp")


def _timeline(page: str) -> str:
    return page[page.index('<section id="timeline">'):page.index('<h2>Figures</h2>')]


def _rod_bars(page: str) -> list[tuple[str, float, float, str]]:
    """(class, x, width, title) of the timeline's rod fault bars."""
    return [(c, float(x), float(w), t) for x, w, c, t in re.findall(
        r'<rect x="([\d.]+)" y="[\d.]+" width="([\d.]+)"[^>]*class="(rod-fault (?:scheduled|live))"[^>]*>'
        r'<title>([^<]*)</title>',
        _timeline(page))]


def test_the_report_lists_a_scheduled_rod_fault_and_a_run_without_one_shows_none(tmp_path):
    for name, extra in (("fault", FAULT), ("healthy", "")):
        out = tmp_path / name
        write_run(_run(extra), out, figures=False)
        page = write_html_report(out).read_text()
        lanes = re.findall(r">(rod \d fault)</text>", _timeline(page))
        assert lanes == ["rod 1 fault", "rod 2 fault", "rod 3 fault"], lanes  # the plant's three rods
        if name == "healthy":
            assert _rod_bars(page) == [] and 'id="verdict-rod-faults"' not in page
            continue
        # one dashed bar on rod 3's lane over [2, 4) s of [0, 6] s: x = 150 + 830 t / 6 (html_timeline's frame)
        (cls, x, w, title), = _rod_bars(page)
        assert cls == "rod-fault scheduled" and title == TEXT
        assert x == pytest.approx(150 + 830 * 2 / 6, abs=0.06) and w == pytest.approx(830 * 2 / 6, abs=0.11)
        rod3 = _timeline(page).split(">rod 3 fault</text>")[1].split("</g>")[0]
        assert 'stroke-dasharray="5,3"' in rod3 and TEXT in rod3  # in rod 3's lane, drawn as scheduled
        assert f'<li id="verdict-rod-faults">Rod faults: {TEXT}</li>' in page
    # a run without rods: no rod lane, no rod line
    out = tmp_path / "no_rods"
    write_run(simulate(with_overrides(load_scenario("paper_faults"), duration=1.0), engine="cpp"), out,
              figures=False)
    page = write_html_report(out).read_text()
    assert "rod " not in _timeline(page) and "verdict-rod-faults" not in page


def _captured(run, tmp_path, monkeypatch):
    """The figure magnetic_figure draws of ``run`` (kept by its save_figure, not written: the artists
    are what is checked, and the PNG's encoding is the slow part)."""
    got = []

    def keep(fig, path, *a, **kw):
        got.append(fig)
        return path

    monkeypatch.setattr(magfig, "save_figure", keep)
    assert magfig.magnetic_figure(run, tmp_path) is not None
    return got[0]


def test_the_magnetic_figure_marks_a_rod_fault_on_every_panel(tmp_path, monkeypatch):
    for name, extra in (("fault", FAULT), ("healthy", "")):
        run = _run(extra)
        fig = _captured(run, tmp_path, monkeypatch)
        marks = [(ax, a) for ax in fig.axes for a in ax.get_children() if (a.get_gid() or "").startswith("rod-fault")]
        s = magfig.magnetic_series(run)
        plt.close(fig)
        if name == "healthy":
            assert marks == [] and s["rod_faults"] == []
            continue
        assert [f.text() for f in s["rod_faults"]] == [TEXT]
        assert {a.get_gid() for _, a in marks} == {"rod-fault-3"}
        dipole_ax = next(ax for ax in fig.axes if ax.get_ylabel().startswith("rod dipole"))
        spans = [a for ax, a in marks if ax is dipole_ax and a.get_label() == TEXT]
        assert len(spans) == 1  # the shaded span, in the legend by its text
        (x0, _), (x1, _) = spans[0].get_bbox().get_points()  # data x (axvspan: x in data, y in axes)
        assert (x0, x1) == (2.0, 4.0)
        for ax in fig.axes:  # onset and end on every panel
            lines = sorted(float(a.get_xdata()[0]) for a2, a in marks if a2 is ax and hasattr(a, "get_xdata"))
            assert lines == [2.0, 4.0], (ax.get_ylabel(), lines)


# --------------------------------------------------------------------------- #
# live commands: the spans against what the emulator applies

def _emulator(scheduled: tuple) -> Receiver:
    import lcm

    scn = load_scenario("day_hold")  # three rods
    rods = scn.plant.magnetorquers.__class__(axes=scn.plant.magnetorquers.axes,
                                             max_dipole=scn.plant.magnetorquers.max_dipole, faults=scheduled)
    return Receiver(lcm.LCM("memq://"), "", 1, 10, Shared(Counter(), scn.actuators, rods=rods), accept_faults=True)


def _as_logged(cmd, received: float) -> dict:
    """A command as sc-rt report lists it from a log (logs/faults.py fault_summary)."""
    kinds = {1: "dead", 2: "stuck", 3: "reversed"}
    return {"log_s": received, "t_sim_at_receipt": received, "rod": cmd.rod, "now": bool(cmd.now),
            "action": {1: "inject", 2: "clear"}[cmd.action], "kind": kinds.get(cmd.kind, cmd.kind),
            "t_onset": cmd.t_onset, "t_end": cmd.t_end, "dipole": cmd.dipole}


def test_live_rod_fault_spans_are_what_the_emulator_applies_between_commands():
    scheduled = (RodFault(rod=0, kind="stuck", dipole=-3.0, onset=10.0, end=50.0),
                 RodFault(rod=1, kind="reversed", onset=30.0))
    sent = [(20.0, rod_inject_msg(1, "dead", at=25.0)),  # replaces rod 1's scheduled stuck while active
            (22.0, rod_inject_msg(2, "stuck", dipole=7.5)),  # now: replaces rod 2's before its onset
            (24.0, rod_inject_msg(3, "reversed", at=26.0, until=28.0)),
            (35.0, rod_clear_msg(1)),  # ends rod 1's dead at 35 s
            (36.0, rod_inject_msg(4, "dead"))]  # the plant has 3 rods: refused, not shown
    rx = _emulator(scheduled)
    snaps = [(-np.inf, rx.shared.rods)]
    logged = []
    for t, msg in sent:
        rx.shared.t_now = t
        rx.on_rod_fault("SCRT_ROD_FAULT", msg.encode())
        snaps.append((t, rx.shared.rods))
        logged.append(_as_logged(sc_rt_lcm.rod_fault_cmd_t.decode(msg.encode()), t))
    assert rx.counters["fault_rejected"] == 1
    sched = [{"rod": f.rod + 1, "kind": f.kind, "dipole": f.dipole, "onset": f.onset,
              "end": None if np.isinf(f.end) else f.end} for f in scheduled]
    from_emulator = rod_fault_spans(sched, rx.shared.faults_applied + [{"t": 1.0, "wheel": 2, "action": "inject"}])
    from_log = rod_fault_spans(sched, logged)
    # a log holds the commands sent, not the emulator's answers: its refused rod 4 is shown as sent
    assert [s for s in from_log if s.rod != 4] == from_emulator
    assert [s.text() for s in from_log if s.rod == 4] == ["rod 4 dead (live, received at 36 s) from 36 s"]
    # sampled between receipts: each rod's active fault as the plant has it (the newest snapshot, its
    # faults' onset <= t < end) is the one span shown active then
    for t in np.arange(0.05, 60.0, 0.5):
        rods = [r for when, r in snaps if when < t][-1]
        plant = {(f.rod + 1, f.kind, f.dipole) for f in rods.faults if f.onset <= t < f.end}
        shown = {(s.rod, s.kind, s.dipole) for s in from_emulator
                 if s.onset <= t < (np.inf if s.end is None else s.end)}
        assert shown == plant, t
    assert [s.text() for s in from_emulator] == [
        "rod 1 stuck at -3 A m^2 (scheduled) from 10 s to 20 s",
        "rod 1 dead (live, received at 20 s) from 25 s to 35 s",
        "rod 2 stuck at 7.5 A m^2 (live, received at 22 s) from 22 s",
        "rod 3 reversed (live, received at 24 s) from 26 s to 28 s"]


def test_the_report_of_a_small_log_lists_its_live_rod_fault_and_counts_each_command_once(tmp_path):
    """A six-state log (the shape of tests/test_report.py's) with a wheel's
    and a rod's fault command: sc-rt report's page lists the rod's on rod 2's
    lane and in the verdict, with its receipt (the newest state logged before
    it: t = 0.1 s), and counts two live commands, not each twice (report.json
    and timing.json both hold them)."""
    import lcm

    from sc_rt.logs.report import write_report
    from sc_rt.tools.faultcmd import inject_msg

    scn = load_scenario("paper_fault_free")
    log = tmp_path / "x.lcmlog"
    w = lcm.EventLog(str(log), "w", overwrite=True)
    w.write_event(0, "SCRT_CONFIG", scn.controller_config_msg().encode())
    ts = 1000
    for k in range(6):
        for ch, m in (("SCRT_STATE", sc_rt_lcm.plant_state_t()), ("SCRT_CMD", sc_rt_lcm.wheel_cmd_t()),
                      ("SCRT_TRUTH", sc_rt_lcm.plant_truth_t())):
            m.t = k / 10
            if ch == "SCRT_STATE":
                m.seq = k
            elif ch == "SCRT_CMD":
                m.session, m.seq, m.state_seq = 1, k, k
            else:
                m.seq, m.cmd_seq_applied = k, k
            ts += 10
            w.write_event(ts, ch, m.encode())
        if k == 1:  # after state 1 (t = 0.1 s)
            ts += 10
            w.write_event(ts, "SCRT_ROD_FAULT", rod_inject_msg(2, "stuck", dipole=3.0, at=0.2, until=0.4).encode())
            ts += 10
            w.write_event(ts, "SCRT_FAULT", inject_msg(1, effectiveness=0.5, at=0.3).encode())
    w.close()
    write_report(log, tmp_path / "rep", plots=False)
    page = write_html_report(tmp_path / "rep").read_text()
    text = "rod 2 stuck at 3 A m^2 (live, received at 0.1 s) from 0.2 s to 0.4 s"
    assert f'<li id="verdict-rod-faults">Rod faults: {text}</li>' in page
    assert "; 2 live fault commands on the bus</li>" in page
    (cls, x, w_, title), = _rod_bars(page)  # on [0, 0.5] s: x = 150 + 830 t / 0.5
    assert (cls, title) == ("rod-fault live", text)
    assert x == pytest.approx(150 + 830 * 0.2 / 0.5, abs=0.06) and w_ == pytest.approx(830 * 0.2 / 0.5, abs=0.11)
    rod2 = _timeline(page).split(">rod 2 fault</text>")[1].split("</g>")[0]
    assert text in rod2 and rod2.count('class="rod-fault-command"') == 1
    wheel1 = _timeline(page).split(">wheel 1 fault</text>")[1].split("</g>")[0]
    assert wheel1.count("fault command inject at 0.1 s") == 1  # drawn once, not once per file


# --------------------------------------------------------------------------- #
# the Foxglove layout's Rods tab

def test_the_layout_reads_only_fields_of_the_schemas_of_its_channels():
    """Every message path of the shipped layout on an LCM channel names a
    field (and an index within its array) of the JSON schema generated for
    the channel's type; the Rods tab reads the status's magnetic fields."""
    import json

    from sc_rt.export.channels import channel_schema, named_type
    from sc_rt.live.layout import LAYOUT, message_paths
    from sc_rt.wire.lcmdefs import load_definitions

    paths = message_paths(json.loads(LAYOUT.read_text()))
    defs = load_definitions()
    checked = set()
    for p in paths:
        m = re.fullmatch(r'"(\w+)"\.(\w+)(?:\[(\d+)\])?', p)
        if m is None:
            continue  # a derived topic (tests/test_live.py checks it against an export)
        topic, field, index = m.groups()
        cls, prefix = named_type(topic)
        assert cls is not None and prefix == "", p
        props = channel_schema(cls, defs)[1]["properties"]
        assert field in props, p
        if index is not None:
            assert props[field]["type"] == "array" and int(index) < props[field]["maxItems"], p
        checked.add((topic, field))
    assert {("SCRT_CTRL_STATUS", f) for f in ("rod_dipole_cmd", "m_B_cmd", "wheel_fill", "unloading",
                                              "detumble_mode")} <= checked
