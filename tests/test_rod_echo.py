"""The plant's truth of the magnetorquer rods (issue 43): plant_truth_t's
``n_rods``, ``rod_dipole_cmd``, ``rod_dipole``, ``dipole_B`` and
``rod_fault``, the echo ``sc-rt fault --rod`` waits for, and the older
layout (``plant_truth_v1_t``) still read.

Checked against computations written here (the clip and the faults by hand
in numpy), never against the emulator's own output. On the main before this
change every test here fails: plant_truth_t had no rod fields (AttributeError),
``model.rods.rods_applied`` and ``plant_truth_v1_t`` did not exist, and
``sc-rt fault --rod`` exited 0 against an emulator that ignores fault
commands (test_a_rod_fault_is_echoed_by_an_emulator_that_applies_it)."""

from __future__ import annotations

import dataclasses
import math
import shlex
import sys
from pathlib import Path

import lcm
import numpy as np
import pytest
import sc_rt_lcm

from sc_rt.emulator.twin import PlantTwin, truth_bytes
from sc_rt.model.rods import Magnetorquers, RodFault, rods_applied
from sc_rt.scenario.reader import load_scenario

import lcmnet

HERE = Path(__file__).resolve().parent
PY = shlex.quote(sys.executable)


def _by_hand(axes, lim, faults, t, d_cmd):
    """Each rod's dipole, its fault state and the body dipole, from the
    definitions (docs/MODEL.md section 16) in numpy: clip, then the fault
    active on onset <= t < end (dead 0, stuck its dipole, reversed -d)."""
    d = np.clip(np.asarray(d_cmd, float), -lim, lim)
    state = np.zeros(d.size, int)
    code = {"dead": 1, "stuck": 2, "reversed": 3}
    for rod, kind, dipole, onset, end in faults:
        if onset <= t < end:
            d[rod] = {"dead": 0.0, "stuck": dipole, "reversed": -d[rod]}[kind]
            state[rod] = code[kind]
        else:
            state[rod] = -code[kind]
    return d, state, np.asarray(axes, float) @ d


def test_rods_applied_clips_then_applies_the_fault_active_at_t():
    axes = np.array([[1.0, 0.0, 0.6], [0.0, 1.0, 0.0], [0.0, 0.0, 0.8]])
    lim = np.array([5.0, 3.0, 4.0])
    spec = [(0, "reversed", 0.0, 1.0, 2.0), (2, "stuck", -2.5, 0.0, math.inf)]
    r = Magnetorquers(axes=axes, max_dipole=lim, faults=tuple(
        RodFault(rod=i, kind=k, dipole=x, onset=a, end=b) for i, k, x, a, b in spec))
    for t in (0.0, 0.5, 1.0, 1.999, 2.0, 7.0):
        for cmd in ([10.0, -1.0, 3.0], [-0.5, 9.0, -8.0]):
            d, state = rods_applied(r, t, cmd)
            want_d, want_state, _ = _by_hand(axes, lim, spec, t, cmd)
            assert d == want_d.tolist() and state == want_state.tolist(), (t, cmd)
    assert rods_applied(r, 1.5, [2.0, 0.0, 0.0]) == ([-2.0, 0.0, -2.5], [3, 0, 2])
    assert rods_applied(r, 2.0, None) == ([0.0, 0.0, -2.5], [-3, 0, 2])  # the window ended


@pytest.mark.parametrize("cpp", [True, False])
def test_the_truths_rod_fields_are_the_rows_rods_through_their_faults(cpp):
    """PlantTwin.rod_fields, C++ twin and Python model alike, with rods a
    live command left: the commands held, each rod's dipole and fault state
    by hand, the body dipole G d; and the bytes equal on either path."""
    scn = load_scenario("day_hold")
    base = scn.plant.magnetorquers
    spec = [(0, "stuck", 4.0, 0.0, math.inf), (1, "reversed", 0.0, 0.05, math.inf), (2, "dead", 0.0, 0.2, 0.3)]
    rods = dataclasses.replace(base, faults=tuple(RodFault(rod=i, kind=k, dipole=x, onset=a, end=b)
                                                  for i, k, x, a, b in spec))
    twin = PlantTwin(scn.plant, cpp)
    other = PlantTwin(scn.plant, not cpp)
    lim = np.asarray(base.max_dipole)
    for t, cmd in ((0.0, (30.0, -20.0, 10.0)), (0.1, (1e4, -1e4, 2.0)), (0.25, (-3.0, 2.0, 1.0)),
                   (0.4, (-3.0, 2.0, 1.0))):
        n, held, d, m_B, fault = twin.rod_fields(t, cmd, rods)
        want_d, want_state, want_m = _by_hand(base.axes, lim, spec, t, cmd)
        assert n == 3 and held == (*cmd, 0.0, 0.0, 0.0)
        assert list(d) == [*want_d.tolist(), 0.0, 0.0, 0.0] and list(fault) == [*want_state.tolist(), 0, 0, 0]
        np.testing.assert_allclose(m_B, want_m, rtol=1e-14, atol=1e-12)
        healthy = [1.0] * 4 + [0.0] * 4 + [0] * 4  # the wheels' effectiveness, bias, stuck
        same = [truth_bytes(0, 1, t, 1, *([0.0] * 4,) * 2, *([0.0] * 3,) * 2, [0.0] * 4, healthy, False,
                            rods=tw.rod_fields(t, cmd, rods)) for tw in (twin, other)]
        assert same[0] == same[1]  # the C++ twin's and the Python model's truth: the same bytes
    # no magnetic control (no commands): a zero command, the stuck rod's dipole still applied
    n, held, d, m_B, fault = twin.rod_fields(0.0, None, rods)
    assert held == (0.0,) * 6 and list(d[:3]) == [4.0, 0.0, 0.0]
    np.testing.assert_allclose(m_B, 4.0 * np.asarray(base.axes)[:, 0], rtol=1e-14)
    # a plant without rods
    from sc_rt.emulator.twin import NO_RODS

    no_rods = PlantTwin(load_scenario("paper_fault_free").plant, cpp)
    assert no_rods.rod_fields(0.0, None) == NO_RODS


def test_a_truth_of_the_older_layout_decodes_with_the_rods_nan():
    """plant_truth_v1_t (no rod fields): read by decode_current as today's
    type, the shared fields as sent, the rods' floats NaN and ints 0; also
    from a log, beside a message of today's layout."""
    from sc_rt.wire.legacy import decode_current

    old = sc_rt_lcm.plant_truth_v1_t()
    old.seq, old.t, old.cmd_seq_applied, old.fault_stuck = 7, 0.7, 6, [0, 1, 0, 0]
    new = sc_rt_lcm.plant_truth_t()
    new.seq, new.t, new.n_rods, new.rod_dipole = 8, 0.8, 3, [1.0, -2.0, 3.0, 0.0, 0.0, 0.0]
    new.rod_fault = [2, 0, -1, 0, 0, 0]
    assert old.encode()[:8] != new.encode()[:8]  # another fingerprint: another layout
    rec, idx = decode_current(sc_rt_lcm.plant_truth_t, [old.encode(), new.encode()])
    assert list(idx) == [0, 1] and list(rec["seq"]) == [7, 8] and rec["fault_stuck"][0].tolist() == [0, 1, 0, 0]
    assert rec["cmd_seq_applied"][0] == 6 and rec["t"][0] == 0.7
    for k in ("rod_dipole_cmd", "rod_dipole", "dipole_B"):
        assert np.all(np.isnan(rec[k][0])), k
    assert rec["n_rods"][0] == 0 and not np.any(rec["rod_fault"][0])
    assert rec["n_rods"][1] == 3 and rec["rod_fault"][1].tolist() == [2, 0, -1, 0, 0, 0]
    assert rec["rod_dipole"][1].tolist() == [1.0, -2.0, 3.0, 0.0, 0.0, 0.0]


def test_a_log_of_the_older_layout_rebuilds_the_rods_from_rod_cmd_t(tmp_path):
    """A magnetic run's log written before the change (plant_truth_v1_t):
    the report's rod_dipole_cmd comes from the rod_cmd_t matched by the
    applied wheel command's seq, as before; with today's truth from the
    truth, where it differs from that match (the plant held another)."""
    from sc_rt.logs.logread import read_log
    from sc_rt.logs.faults import fault_summary
    from sc_rt.logs.rebuild import rebuild

    def log(path, truth_cls):
        ev = lcm.EventLog(str(path), "w", overwrite=True)
        ts = 1_000_000
        for k in range(3):
            s = sc_rt_lcm.plant_state_t()
            s.seq, s.t = k, 0.1 * k
            ev.write_event(ts, "SCRT_STATE", s.encode())
            r = sc_rt_lcm.rod_cmd_t()
            r.seq, r.state_seq, r.t, r.n_rods = k, k, s.t, 3
            r.dipole = [float(k + 1), 2.0, -1.0, 0.0, 0.0, 0.0]
            ev.write_event(ts + 100, "SCRT_ROD_CMD", r.encode())
            c = sc_rt_lcm.wheel_cmd_t()
            c.seq, c.state_seq, c.t = k, k, s.t
            ev.write_event(ts + 200, "SCRT_CMD", c.encode())
            tr = truth_cls()
            tr.seq, tr.t, tr.cmd_seq_applied = k, s.t, k
            if truth_cls is sc_rt_lcm.plant_truth_t:  # the plant held rod command 0 all along (late ones)
                tr.n_rods, tr.rod_dipole_cmd = 3, [1.0, 2.0, -1.0, 0.0, 0.0, 0.0]
                tr.rod_fault = [0, 0, 1 if k >= 1 else -1, 0, 0, 0]
            ev.write_event(ts + 300, "SCRT_TRUTH", tr.encode())
            ts += 100_000
        ev.close()

    log(tmp_path / "old.lcmlog", sc_rt_lcm.plant_truth_v1_t)
    d = read_log(tmp_path / "old.lcmlog")
    assert d.channels["SCRT_TRUTH"]["undecodable"] == 0
    r = rebuild(d, "lockstep")
    assert r.has_truth.all() and r.rods is None
    assert r.arrays["rod_dipole_cmd"][:, 0].tolist() == [1.0, 2.0, 3.0]  # matched by seq
    assert fault_summary(d, r)["rod_state_changes"] == []

    log(tmp_path / "new.lcmlog", sc_rt_lcm.plant_truth_t)
    d = read_log(tmp_path / "new.lcmlog")
    r = rebuild(d, "lockstep")
    assert r.arrays["rod_dipole_cmd"][:, 0].tolist() == [1.0, 1.0, 1.0]  # what the plant held
    assert r.rods["rod_fault"][:, 2].tolist() == [-1, 1, 1]
    assert fault_summary(d, r)["rod_state_changes"] == [
        {"t": 0.0, "rod": 3, "fault": "dead", "active": False}, {"t": 0.1, "rod": 3, "fault": "dead", "active": True}]


def _truth(t, fault, dipole=(0.0, 0.0, 0.0), n_rods=3):
    m = sc_rt_lcm.plant_truth_t()
    m.t, m.n_rods = t, n_rods
    m.rod_fault = [*fault, *(0,) * (6 - len(fault))]
    m.rod_dipole = [*dipole, *(0.0,) * (6 - len(dipole))]
    return sc_rt_lcm.plant_truth_t.decode(m.encode())


def test_the_echo_is_the_commands_fault_state_at_the_truths_time():
    """What ``sc-rt fault --rod`` takes for its echo (python/sc_rt/tools/faultcmd.py):
    the command's kind on its rod, active inside its window and minus it
    outside, a stuck rod's dipole once active; a pending fault of the same
    kind (day_hold schedules rod 2 stuck from 1e9 s) is no echo of one
    injected now."""
    from sc_rt.tools.faultcmd import _echoed, rod_clear_msg, rod_inject_msg

    now = rod_inject_msg(2, "stuck", dipole=3.5)
    assert not _echoed(now, _truth(4.0, [0, -2, 0]))  # the scheduled stuck rod, pending: not this one
    assert not _echoed(now, _truth(4.0, [0, 2, 0], (0.0, 1.0, 0.0)))  # stuck at another dipole
    assert _echoed(now, _truth(4.1, [0, 2, 0], (0.0, 3.5, 0.0)))
    later = rod_inject_msg(3, "dead", at=100.0, until=200.0)
    assert _echoed(later, _truth(4.0, [0, 0, -1])) and not _echoed(later, _truth(4.0, [0, 0, 1]))
    assert _echoed(later, _truth(150.0, [0, 0, 1])) and not _echoed(later, _truth(150.0, [0, 0, -1]))
    assert _echoed(later, _truth(200.0, [0, 0, -1]))  # its end passed
    assert not _echoed(later, _truth(4.0, [0, 0, -3]))  # another kind
    assert not _echoed(rod_inject_msg(4, "dead"), _truth(4.0, [0, 0, 0]))  # a rod the plant lacks
    assert _echoed(rod_clear_msg(2), _truth(4.0, [0, 0, 1])) and not _echoed(rod_clear_msg(2), _truth(4.0, [0, 3]))


def test_the_answer_is_the_commands_seq_not_a_state_the_rod_already_had():
    """``faultcmd.answer``: applied when the truth's ``fault_seq_applied`` is the
    command's seq, refused when ``fault_seq_refused`` is; a truth already
    showing the state asked for (day_hold's rod 2 stuck, pending, for an
    inject with a later onset; the same fault sent again) is no answer while
    the emulator has not applied this command. A later command applied over
    it still counts when the state shows this one."""
    from sc_rt.tools.faultcmd import answer, inject_msg, rod_inject_msg

    cmd = rod_inject_msg(2, "stuck", dipole=500.0, at=100.0)  # beyond day_hold's 100 A m^2
    cmd.seq = 1000
    pending = _truth(5.0, [0, -2, 0])  # what the rod showed before: day_hold's armed fault
    assert answer(cmd, pending) is None
    pending.fault_seq_applied, pending.fault_seq_refused = 999, 1000
    assert answer(cmd, pending) == "refused"
    ok = _truth(5.0, [0, -2, 0])
    ok.fault_seq_applied, ok.fault_seq_refused = 1000, -1
    assert answer(cmd, ok) == "applied"
    later = _truth(5.0, [0, -2, 0])
    later.fault_seq_applied, later.fault_seq_refused = 1001, -1  # another command after it; the state is it
    assert answer(cmd, later) == "applied" and answer(rod_inject_msg(2, "dead"), later) is None
    wheel = inject_msg(3, effectiveness=0.5)
    wheel.seq = 7
    healthy = _truth(1.0, [])
    healthy.fault_seq_applied = 6
    assert answer(wheel, healthy) is None
    healthy.fault_seq_applied = 7
    assert answer(wheel, healthy) == "applied"


def test_a_logs_fault_commands_are_marked_by_the_seqs_the_truth_echoes():
    """sc-rt report (logs/faults.py): a command whose seq a truth names as
    applied is applied; one it names as refused, refused; one no truth names,
    nor any later one (another emulator's, one ignoring fault commands), not
    applied; one a later command's echo covers, and every command of a log
    of the older layout, unknown (None). The report's pages draw the applied
    and the unknown ones only (rod_faults.live_fault_records)."""
    from sc_rt.logs.faults import _mark_answers
    from sc_rt.results.present.rod_faults import live_fault_records
    from sc_rt.wire.codec import decode_array
    from sc_rt.wire.legacy import decode_current

    truths = []
    for applied, refused in ((-1, -1), (1000, -1), (1000, 1001)):
        m = sc_rt_lcm.plant_truth_t()
        m.fault_seq_applied, m.fault_seq_refused = applied, refused
        truths.append(m.encode())
    T, _ = decode_array(sc_rt_lcm.plant_truth_t, truths)
    cmds = [{"seq": 999, "rod": 4}, {"seq": 1000, "rod": 1}, {"seq": 1001, "rod": 2}, {"seq": 1002, "rod": 3}]
    _mark_answers(cmds, T)
    assert cmds == [{"seq": 999, "rod": 4, "applied": None},  # 1000 applied in the same row: cannot tell
                    {"seq": 1000, "rod": 1, "applied": True},
                    {"seq": 1001, "rod": 2, "applied": False, "refused": True},
                    {"seq": 1002, "rod": 3, "applied": False, "refused": False}]
    assert [c["rod"] for c in live_fault_records({"faults": {"commands": cmds}}, None)] == [4, 1]
    old, _ = decode_current(sc_rt_lcm.plant_truth_t, [sc_rt_lcm.plant_truth_v1_t().encode()])
    cmds = [{"seq": 1000, "rod": 1}]
    _mark_answers(cmds, old)
    assert cmds == [{"seq": 1000, "rod": 1, "applied": None}]
    assert live_fault_records({"faults": {"commands": cmds}}, None) == cmds


def test_a_rod_fault_no_emulator_echoes_exits_1_naming_why():
    """No emulator on the bus (in-process memq): exit 1, the channel, the URL
    and the reasons named (the old main published and exited 0)."""
    r = lcmnet.cli_memq("fault", "inject", "--rod", "2", "--kind", "reversed", "--timeout", "0.3", "--prefix", "B1_")
    assert r.returncode == 1, r.stdout + r.stderr
    why = [ln for ln in r.stderr.splitlines() if ln.startswith("sc-rt fault: not applied")]
    assert len(why) == 1 and "no emulator echoed it on B1_SCRT_TRUTH within 0.3 s" in why[0], r.stderr
    assert "memq://" in why[0] and "--accept-fault-commands" in why[0]


@pytest.mark.lcm
def test_a_rod_fault_is_echoed_by_an_emulator_that_applies_it(tmp_path):
    """Against real emulator processes (day_hold's three rods, real time):
    applied and echoed (exit 0) for an inject now, one with a later onset
    and a clear; refused by the plant (exit 1 at once, named) for a rod it
    lacks and for rod 2 stuck beyond its 100 A m^2 limit with a later onset
    (day_hold arms rod 2 stuck, pending: a rule reading the rod's state alone
    took that pending fault for the command's echo and said "applied");
    not echoed (exit 1, the reason named) by an emulator without
    --accept-fault-commands (on the old main: exit 0)."""
    lcmnet.require()
    url = "udpm://239.255.76.67:7753?ttl=0"
    url2 = "udpm://239.255.76.67:7754?ttl=0"
    fault = f"{PY} -m sc_rt.cli fault"
    emu = f"{PY} -m sc_rt.cli emulator day_hold --mode realtime --rate 20 --duration 120"
    script = lcmnet.two_emulators(emu, url, url2, tmp_path) + f"""
{fault} inject --rod 1 --kind dead --timeout 20 --lcm-url '{url}'; echo "rc_dead=$?"
{fault} inject --rod 3 --kind stuck --dipole 3.5 --at 100 --timeout 20 --lcm-url '{url}'; echo "rc_later=$?"
{fault} clear --rod 1 --timeout 20 --lcm-url '{url}'; echo "rc_clear=$?"
{fault} inject --rod 5 --kind dead --timeout 20 --lcm-url '{url}'; echo "rc_no_rod=$?"
{fault} inject --rod 2 --kind stuck --dipole 500 --at 100 --timeout 20 --lcm-url '{url}'; echo "rc_beyond=$?"
{fault} inject --rod 1 --kind reversed --timeout 1 --lcm-url '{url2}'; echo "rc_ignored=$?"
kill -INT $E1 $E2; wait
"""
    r = lcmnet.run_script(script, timeout=240)
    so, se = r.stdout, r.stderr
    for name in ("dead", "later", "clear"):
        assert f"rc_{name}=0" in so, so + se
    assert so.count("applied: echoed on SCRT_TRUTH at t = ") == 3, so + se
    assert "rc_no_rod=1" in so and "rc_beyond=1" in so and "rc_ignored=1" in so, so + se
    lines = [ln for ln in se.splitlines() if ln.startswith("sc-rt fault: not applied")]
    assert len(lines) == 3, se
    assert all("the emulator refused it (said on SCRT_TRUTH at t = " in ln for ln in lines[:2]), se
    assert "no emulator echoed it on SCRT_TRUTH within 1 s" in lines[2], se
    assert url2 in lines[2] and "--accept-fault-commands" in lines[2], se


def test_spy_shows_the_rods_truth():
    """``sc-rt spy``'s summary and line of a plant_truth_t with rods: the
    rods' dipoles and fault states, only those of the plant's rods."""
    from sc_rt.tools.spy import Spy, summarize

    m = _truth(2.0, [2, 0, -1], (4.0, -1.5, 0.0))
    m.dipole_B = [4.0, -1.5, 0.0]
    s = summarize(m)
    assert (s["n_rods"], s["rod_dipole"], s["rod_fault"], s["dipole_B"]) == (
        3, [4.0, -1.5, 0.0], [2, 0, -1], [4.0, -1.5, 0.0])
    spy = Spy("memq://")
    spy.lc.publish("SCRT_TRUTH", m.encode())
    spy.listen(0.2)
    assert "rods [+4.00 -1.50 +0.00] A m^2  rod fault [2, 0, -1]" in spy.render()
    assert summarize(sc_rt_lcm.plant_truth_t())["rod_dipole"] == []  # a plant without rods
