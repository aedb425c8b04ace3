"""sc-rt fault: argument checks, the emulator's handling (only with
--accept-fault-commands), and a fault injected live into a real-time HIL run:
in the log, in plant_truth_t and in the report, at the right time."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

import numpy as np
import pytest
import sc_rt_lcm

from collections import Counter

from sc_rt.emulator.receiver import Receiver
from sc_rt.emulator.state import Shared
from sc_rt.tools.faultcmd import clear_msg, inject_msg
from sc_rt.logs.report import read_log, write_report
from sc_rt.scenario.reader import load_scenario

import figcheck
import lcmnet

ROOT = Path(__file__).resolve().parent.parent
HERE = Path(__file__).resolve().parent
PY = shlex.quote(sys.executable)


cli = lcmnet.cli_memq


@pytest.mark.parametrize("args, message", [
    (["inject", "--wheel", "0"], "--wheel must be 1..4, got 0"),
    (["inject", "--wheel", "5"], "--wheel must be 1..4, got 5"),
    (["inject", "--wheel", "1", "--effectiveness", "1.2"], "--effectiveness must be in [0, 1], got 1.2"),
    (["inject", "--wheel", "1", "--effectiveness", "-0.1"], "--effectiveness must be in [0, 1]"),
    (["inject", "--wheel", "1", "--rate", "0"], "--rate must be > 0, got 0.0"),
    (["inject", "--wheel", "1", "--rate", "nan"], "--rate must be finite"),
    (["inject", "--wheel", "1", "--at", "5", "--until", "5"], "--until must be after --at"),
    (["inject", "--wheel", "1", "--at", "-1"], "--at must be a simulation time >= 0 s"),
    (["inject", "--wheel", "1", "--bias", "inf"], "--bias must be finite"),
    (["clear", "--wheel", "7"], "--wheel must be 1..4, got 7"),
    (["inject", "--wheel", "1", "--at", "1", "--now"], "not allowed with argument --at"),
    (["inject"], "one of the arguments --wheel --rod is required"),
    (["inject", "--wheel", "1"], "changes nothing"),
    (["inject", "--wheel", "1", "--effectiveness", "1", "--bias", "0", "--at", "3"], "changes nothing"),
    (["inject", "--wheel", "x"], "invalid int value: 'x'"),
    (["inject", "--wheel", "1", "--friction", "-1"], "--friction must be >= 0, got -1.0"),
    (["inject", "--wheel", "1", "--friction", "2", "--stuck"], "ignores --friction"),
    (["inject", "--wheel", "1", "--bias", "0.1", "--timeout", "0"], "argument --timeout: 0: must be"),
    (["clear", "--wheel", "1", "--timeout", "nan"], "argument --timeout: nan: must be"),
])
def test_bad_arguments_exit_2_with_a_message(args, message):
    r = cli("fault", *args)
    assert r.returncode == 2, r.stdout
    assert message in r.stderr


def test_good_arguments_publish():
    r = cli("fault", "inject", "--wheel", "2", "--effectiveness", "0.4", "--at", "3", "--until", "9",
            "--no-wait")
    assert r.returncode == 0, r.stderr
    assert "inject wheel 2" in r.stdout and "SCRT_FAULT" in r.stdout and "not waiting" in r.stdout
    r = cli("fault", "clear", "--wheel", "2", "--prefix", "B1_", "--no-wait")
    assert r.returncode == 0 and "B1_SCRT_FAULT" in r.stdout


def test_a_fault_no_emulator_echoes_exits_1_naming_url_and_channel():
    r = cli("fault", "inject", "--wheel", "2", "--effectiveness", "0.4", "--timeout", "0.3",
            "--prefix", "B1_")
    assert r.returncode == 1, r.stdout + r.stderr
    assert "not applied: no emulator echoed it on B1_SCRT_TRUTH within 0.3 s" in r.stderr
    assert "memq://" in r.stderr and "B1_SCRT_FAULT" in r.stderr


@pytest.mark.slow
def test_fault_echo_applied_refused_and_unheard(tmp_path):
    """Against a real emulator process: applied (exit 0, echoed in
    plant_truth_t), an onset the emulator has passed (exit 2), and an
    emulator that does not accept fault commands (exit 1)."""
    lcmnet.require()
    url = "udpm://239.255.76.67:7743?ttl=0"
    url2 = "udpm://239.255.76.67:7744?ttl=0"
    wait = f"{PY} {shlex.quote(str(HERE / 'buswait.py'))}"
    fault = f"{PY} -m sc_rt.cli fault"
    emu = f"{PY} -m sc_rt.cli emulator scenarios/paper_fault_free.toml --mode realtime --rate 20 --duration 60"
    # the emulator is at t >= 1 s once buswait has seen the state of t = 1 (20 states)
    script = lcmnet.two_emulators(emu, url, url2, tmp_path) + f"""
while [ "$({wait} '{url}' state 60 | cut -d. -f1)" -lt 1 ]; do :; done
{fault} inject --wheel 2 --effectiveness 0.3 --timeout 20 --lcm-url '{url}'; echo "rc_applied=$?"
{fault} inject --wheel 3 --bias 0.1 --at 0.5 --timeout 20 --lcm-url '{url}'; echo "rc_past=$?"
{fault} inject --wheel 3 --bias 0.1 --timeout 1 --lcm-url '{url2}'; echo "rc_ignored=$?"
{fault} clear --wheel 2 --timeout 20 --lcm-url '{url}'; echo "rc_clear=$?"
kill -INT $E1 $E2; wait
"""
    r = lcmnet.run_script(script, timeout=180)
    so, se = r.stdout, r.stderr
    assert "rc_applied=0" in so and "applied: echoed on SCRT_TRUTH at t = " in so, so + se
    assert "rc_past=2" in so and "--at 0.5: the onset is in the past" in se, so + se
    assert "rc_ignored=1" in so and "no emulator echoed it on SCRT_TRUTH within 1 s" in se, so + se
    assert url2 in se
    assert "rc_clear=0" in so, so + se


def test_messages():
    m = inject_msg(3, effectiveness=0.25, bias=-0.1, at=4.0, until=6.5, rate=2.0, stuck=False)
    d = sc_rt_lcm.fault_cmd_t.decode(m.encode())
    assert (d.wheel, d.action, d.now, d.t_onset, d.t_end, d.effectiveness, d.bias, d.rate, d.stuck) == (
        3, d.ACTION_INJECT, False, 4.0, 6.5, 0.25, -0.1, 2.0, False)
    n = inject_msg(1, stuck=True)
    assert n.now and n.t_end == -1.0 and n.stuck
    c = clear_msg(4)
    assert c.action == c.ACTION_CLEAR and c.wheel == 4


def _receiver(accept: bool, scenario: str = "paper_fault_free") -> Receiver:
    """The emulator's receiver built alone (no emulator, no loop) on an
    in-process bus, with the shared values it writes."""
    import lcm

    scn = load_scenario(ROOT / "scenarios" / f"{scenario}.toml")
    return Receiver(lcm.LCM("memq://"), "", 1, 10, Shared(Counter(), scn.actuators), accept_faults=accept)


def test_emulator_applies_faults_only_when_it_accepts_them():
    rx = _receiver(False)
    emu = rx.shared
    rx.lc.publish("SCRT_FAULT", inject_msg(2, effectiveness=0.5).encode())
    rx.lc.handle_timeout(200)
    assert emu.counters["fault_ignored"] == 1 and emu.act.faults == () and emu.faults_applied == []

    rx = _receiver(True)
    emu = rx.shared
    emu.t_now = 12.5
    rx.lc.publish("SCRT_FAULT", inject_msg(2, effectiveness=0.5, bias=0.1, at=20.0, until=30.0).encode())
    rx.lc.handle_timeout(200)
    (f,) = emu.act.faults
    assert (f.wheel, f.effectiveness, f.bias, f.onset, f.end, f.rate) == (1, 0.5, 0.1, 20.0, 30.0, 1.0)
    rx.on_fault("SCRT_FAULT", inject_msg(2, stuck=True).encode())  # replaces wheel 2's fault, now
    (f,) = emu.act.faults
    assert f.stuck and f.onset == 12.5 and f.end is None
    rx.on_fault("SCRT_FAULT", inject_msg(4, bias=0.2).encode())
    assert sorted(x.wheel for x in emu.act.faults) == [1, 3]
    rx.on_fault("SCRT_FAULT", clear_msg(2).encode())
    assert [x.wheel for x in emu.act.faults] == [3]
    # hostile: undecodable, a wheel out of range, an effectiveness out of range
    rx.on_fault("SCRT_FAULT", b"nonsense")
    bad = inject_msg(1, bias=0.1)
    bad.wheel = 9
    rx.on_fault("SCRT_FAULT", bad.encode())
    bad = inject_msg(1, bias=0.1)
    bad.effectiveness = 3.0
    rx.on_fault("SCRT_FAULT", bad.encode())
    assert emu.counters["malformed"] == 1 and emu.counters["fault_rejected"] == 2
    assert emu.counters["fault_applied"] == 4 and [x.wheel for x in emu.act.faults] == [3]
    actions = [r.get("action", "rejected") for r in emu.faults_applied]
    assert actions == ["inject", "inject", "inject", "clear", "rejected", "rejected"]
    assert emu.faults_applied[0]["t"] == 12.5 and emu.faults_applied[0]["onset"] == 20.0


def test_a_live_friction_rise_needs_flight_wheels():
    # the paper's wheels have no friction: refused, named
    rx = _receiver(True)
    rx.on_fault("SCRT_FAULT", inject_msg(3, friction=4.0).encode())
    assert rx.shared.counters["fault_rejected"] == 1 and rx.shared.act.faults == ()
    assert "friction" in rx.shared.faults_applied[0]["rejected"]
    # on flight_wheels' torque-commanded wheels it applies
    rx = _receiver(True, "flight_wheels")
    rx.shared.t_now = 7.0
    rx.on_fault("SCRT_FAULT", inject_msg(3, friction=4.0, rate=0.5).encode())
    (f,) = rx.shared.act.faults
    assert (f.wheel, f.friction, f.onset, f.rate, f.effectiveness) == (2, 4.0, 7.0, 0.5, 1.0)
    assert rx.shared.faults_applied[0]["friction"] == 4.0


@pytest.mark.slow  # ~10-16 s: an 8 s real-time run and its report with figures
def test_fault_injected_live_shows_in_log_truth_and_report(tmp_path, monkeypatch):
    lcmnet.require()
    rate = 50.0
    url = "udpm://239.255.76.67:7741?ttl=0"
    out = tmp_path / "hil"
    wait = f"{PY} {shlex.quote(str(HERE / 'buswait.py'))} '{url}'"
    # as soon as the run's states are on the bus (an event, not a sleep):
    # wheel 2 from t = 6 s to 7 s (in the future), wheel 3 stuck now, then
    # cleared once the plant has reported it stuck for 25 ticks (0.5 s)
    script = f"""
set -e
{PY} -m sc_rt.cli hil scenarios/paper_fault_free.toml --mode realtime --control-rate {rate} \\
    --duration 8 --accept-fault-commands --out {out} --no-plots --lcm-url '{url}' > {tmp_path}/hil.log 2>&1 &
HIL=$!
export SCRT_WAIT_PID=$HIL
{wait} state 60 > /dev/null
{PY} -m sc_rt.cli fault inject --wheel 2 --effectiveness 0.3 --bias 0.05 --rate 5 --at 6 --until 7 \\
    --lcm-url '{url}'
{PY} -m sc_rt.cli fault inject --wheel 3 --stuck --now --lcm-url '{url}'
{wait} stuck 3 25 60 > /dev/null
{PY} -m sc_rt.cli fault clear --wheel 3 --lcm-url '{url}'
wait $HIL
"""
    r = lcmnet.run_script(script, timeout=120)
    so, se = r.stdout, r.stderr
    assert r.returncode == 0, se + (tmp_path / "hil.log").read_text()
    assert so.count("sc-rt fault:") == 3

    # 1. the emulator applied all three (timing.json: faults_applied)
    timing = json.loads((out / "timing.json").read_text())
    applied = timing["faults_applied"]
    assert [(a["wheel"], a["action"]) for a in applied] == [(2, "inject"), (3, "inject"), (3, "clear")]
    assert applied[0]["onset"] == 6.0 and applied[0]["end"] == 7.0 and applied[0]["t"] < 6.0
    t_stuck, t_clear = applied[1]["t"], applied[2]["t"]
    assert applied[1]["onset"] == t_stuck and t_stuck < t_clear
    # (the premise of the checks below: all three arrived before wheel 2's window)
    assert t_clear < 6.0, f"the fault commands arrived too late in the run: {applied}"

    # 2. the log holds the commands and plant_truth_t echoes the fault state
    d = read_log(out / "run.lcmlog")
    F = d.records["SCRT_FAULT"]
    assert list(F["wheel"]) == [2, 3, 3] and list(F["action"]) == [1, 1, 2]
    assert d.undecodable == 0
    T = d.records["SCRT_TRUTH"]
    t = T["t"].astype(float)
    L2, Y2, B2 = (T[k][:, 1].astype(float) for k in ("fault_effectiveness", "fault_Y", "fault_bias"))
    inj = t >= applied[0]["t"] - 1e-9
    assert np.all(L2[inj] == 0.3) and np.all(L2[~inj] == 1.0) and np.all(B2[inj] == 0.05)
    on = (t > 6.0 + 1e-9) & (t < 7.0 - 1e-9)
    assert np.all(Y2[on] > 0) and np.all(Y2[~on] == 0)  # Y = 0 at the onset and from the end on
    acc = T["wheel_accel"][:, 1].astype(float)
    # (15) on wheel 2 while active: what the plant did is not what was commanded
    u = T["u_cmd"][:, 1].astype(float)
    assert np.count_nonzero(acc[on] != u[on]) >= 0.9 * np.count_nonzero(on)
    S3 = T["fault_stuck"][:, 2]
    stuck = (t >= t_stuck - 1e-9) & (t < t_clear - 1e-9)
    assert np.all(S3[stuck] == 1) and np.all(S3[~stuck] == 0) and np.count_nonzero(stuck) >= 10
    assert np.all(T["wheel_accel"][:, 2].astype(float)[stuck] == 0.0)

    # 3. the report has them at the right time, and the fault figure
    figs = figcheck.record_figures(monkeypatch)
    rep = write_report(out / "run.lcmlog", tmp_path / "report")
    f = rep["faults"]
    assert f["first_active_s"][1] == pytest.approx(6.0 + 1 / rate)
    assert f["first_active_s"][0] is None and f["first_active_s"][3] is None
    ch = [(c["wheel"], c["t"], c["stuck"], c["effectiveness"]) for c in f["state_changes"]]
    assert (2, applied[0]["t"], False, 0.3) in ch
    assert (3, t_stuck, True, 1.0) in ch and (3, t_clear, False, 1.0) in ch
    assert [c["action"] for c in f["commands"]] == ["inject", "inject", "clear"]
    assert f["commands"][0]["t_onset"] == 6.0 and f["commands"][0]["t_end"] == 7.0
    # received on the bus within a few periods of when the emulator applied it,
    # or within the emulator's worst tick lateness on a loaded machine
    tol = max(0.2, timing["emulator_tick_lateness_us"]["max"] / 1e6 + 2 / rate)
    for c, a in zip(f["commands"], applied):
        assert abs(c["t_sim_at_receipt"] - a["t"]) <= tol, (c, a, tol)
    # the fault figure shows what happened: one panel per wheel; wheel 2's
    # effectiveness L drops to 0.3 and its Y(t) rises inside (6 s, 7 s) with a
    # red onset line at 6 s; wheel 3 has a stuck span from t_stuck to t_clear
    png = tmp_path / "report" / "faults.png"
    figcheck.assert_png_is_a_plot(png)
    fig = figs[png.name]
    panels = [ax for ax in fig.axes if ax.get_title(loc="left").startswith("wheel ")]
    assert [ax.get_title(loc="left").split()[1] for ax in panels] == ["1", "2", "3", "4"]
    twins = {id(ax): [a for a in fig.axes if a is not ax and a.bbox.bounds == ax.bbox.bounds][0]
             for ax in panels}

    def line(ax, label):
        (ln,) = [ln for ln in ax.get_lines() if ln.get_label() == label]
        return np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float)

    x, L = line(twins[id(panels[1])], "L")
    assert np.all(L[x >= applied[0]["t"] + 1e-9] == 0.3) and np.all(L[x < applied[0]["t"] - 1e-9] == 1.0)
    x, Y = line(twins[id(panels[1])], "Y(t)")
    assert np.all(Y[(x > 6.0 + 1e-9) & (x < 7.0 - 1e-9)] > 0) and np.all(Y[x <= 6.0] == 0)
    vlines = [(ln.get_xdata()[0], ln.get_color(), ln.get_linestyle()) for ln in panels[1].get_lines()
              if len(ln.get_xdata()) == 2 and ln.get_xdata()[0] == ln.get_xdata()[1]]
    assert (6.0, "r", "--") in vlines, vlines
    # the actual acceleration: wheel 3 still while stuck, wheel 2 not what was commanded in its window
    x, act = line(panels[2], "actual")
    held = (x >= t_stuck + 1e-9) & (x < t_clear - 1e-9)
    assert held.sum() >= 10 and np.all(act[held] == 0.0)
    x, act = line(panels[1], "actual")
    _, cmd = line(panels[1], "command (saturated)")
    win = (x > 6.0 + 1e-9) & (x < 7.0 - 1e-9)
    assert np.count_nonzero(act[win] != cmd[win]) >= 0.9 * np.count_nonzero(win)
    stuck_spans = [c for c in panels[2].collections if c.get_label() == "stuck"]
    assert len(stuck_spans) == 1
    xs = np.concatenate([p.vertices[:, 0] for p in stuck_spans[0].get_paths()])
    assert xs.min() == pytest.approx(t_stuck, abs=1 / rate) and xs.max() <= t_clear + 1e-9
    assert not [c for c in panels[0].collections + panels[1].collections if c.get_label() == "stuck"]
    assert rep["timing"]["faults_applied"] == f["commands"]


def test_authenticated_fault_commands_cannot_be_replayed_or_misaddressed():
    """Before: under --auth-key the emulator applied any fault_cmd_t whose
    tag verified; seq was never checked and the message named no session,
    so a command captured from an earlier run was accepted again (issue #25,
    case 8). The receiver is built alone (authenticated: a keyed bus)."""
    import lcm

    scn = load_scenario(ROOT / "scenarios" / "paper_fault_free.toml")
    rx = Receiver(lcm.LCM("memq://"), "", 77, 10, Shared(Counter(), scn.actuators), accept_faults=True,
                  authenticated=True)

    def cmd(seq: int, session: int, wheel: int = 2):
        m = inject_msg(wheel, effectiveness=0.5)
        m.seq, m.session = seq, session
        return m.encode()

    rx.on_fault("SCRT_FAULT", cmd(10, 77))
    assert rx.counters["fault_applied"] == 1
    rx.on_fault("SCRT_FAULT", cmd(10, 77))  # the same bytes again: a replay
    rx.on_fault("SCRT_FAULT", cmd(9, 77, wheel=3))  # an older one
    assert rx.counters["fault_replayed"] == 2 and rx.counters["fault_applied"] == 1
    rx.on_fault("SCRT_FAULT", cmd(11, 78, wheel=3))  # another run's emulator
    rx.on_fault("SCRT_FAULT", cmd(12, 0, wheel=3))  # addressed to none
    assert rx.counters["fault_foreign_session"] == 2 and [f.wheel for f in rx.shared.act.faults] == [1]
    rx.on_fault("SCRT_FAULT", cmd(13, 77, wheel=3))
    assert rx.counters["fault_applied"] == 2

    # without a key: any emulator (session 0) and no seq rule, as before; another session still refused
    rx = Receiver(lcm.LCM("memq://"), "", 77, 10, Shared(Counter(), scn.actuators), accept_faults=True)
    rx.on_fault("SCRT_FAULT", cmd(5, 0))
    rx.on_fault("SCRT_FAULT", cmd(5, 0, wheel=3))
    rx.on_fault("SCRT_FAULT", cmd(6, 78, wheel=4))
    assert rx.counters["fault_applied"] == 2 and rx.counters["fault_foreign_session"] == 1
