"""Live magnetorquer-rod faults (issue 43 item 3: rod_fault_cmd_t on
SCRT_ROD_FAULT, ``sc-rt fault inject|clear --rod N``): the arguments, the
emulator's receiver (only with --accept-fault-commands, the same session,
seq and --auth-key rules as the wheels' fault commands, a rod the plant has
not refused), and a lockstep run of day_hold with three rod faults sent
live, which equals bit for bit ``sc-rt sim --engine cpp`` of the same file
with those faults scheduled in ``[[magnetorquers.faults]]`` (the scenario
reader's, not the bus's), its log read by ``sc-rt report`` and exported to
MCAP.

Every test here fails on the main before this change: ``sc-rt fault`` had
no --rod (exit 2), rod_fault_cmd_t and the receiver's on_rod_fault did not
exist."""

from __future__ import annotations

import json
import re
import shlex
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import sc_rt_lcm

from sc_rt.emulator.receiver import Receiver
from sc_rt.emulator.state import Shared
from sc_rt.scenario.reader import load_scenario
from sc_rt.scenario.shipped import resolve
from sc_rt.tools.faultcmd import rod_clear_msg, rod_inject_msg

import lcmnet
from trajcmp import compared_fields, load_traj

ROOT = Path(__file__).resolve().parent.parent
HERE = Path(__file__).resolve().parent
PY = shlex.quote(sys.executable)


cli = lcmnet.cli_memq


@pytest.mark.parametrize("args, message", [
    (["inject", "--rod", "0", "--kind", "dead"], "--rod must be 1..6, got 0"),
    (["inject", "--rod", "7", "--kind", "dead"], "--rod must be 1..6, got 7"),
    (["clear", "--rod", "9"], "--rod must be 1..6, got 9"),
    (["inject", "--rod", "1"], "a rod fault needs --kind dead|stuck|reversed"),
    (["inject", "--rod", "1", "--kind", "stuck"], "a stuck rod needs its dipole: give --dipole X"),
    (["inject", "--rod", "1", "--kind", "dead", "--dipole", "3"], "--dipole is a stuck rod's value"),
    (["inject", "--rod", "1", "--kind", "stuck", "--dipole", "nan"], "--dipole must be finite, got nan"),
    (["inject", "--rod", "1", "--kind", "dead", "--bias", "0.1"], "--bias is a wheel fault's"),
    (["inject", "--rod", "1", "--kind", "dead", "--stuck"], "--stuck is a wheel fault's"),
    (["inject", "--rod", "1", "--kind", "reversed", "--at", "5", "--until", "4"], "--until must be after --at"),
    (["inject", "--wheel", "1", "--kind", "dead"], "--kind is a rod fault's: give --rod N"),
])
def test_bad_rod_arguments_exit_2_in_one_line(args, message):
    r = cli("fault", *args)
    assert r.returncode == 2, r.stdout
    assert r.stderr.startswith(f"sc-rt fault {args[0]}: error: ") and message in r.stderr, r.stderr
    assert r.stderr.count("\n") == 1, r.stderr  # one line


@pytest.mark.parametrize("args, message", [
    (["inject", "--rod", "1", "--kind", "bent"], "argument --kind: invalid choice: 'bent'"),
    (["inject", "--rod", "1", "--wheel", "1", "--kind", "dead"], "not allowed with argument"),
    (["inject", "--kind", "dead"], "one of the arguments --wheel --rod is required"),
])
def test_rod_usage_errors_exit_2(args, message):
    r = cli("fault", *args)
    assert r.returncode == 2 and message in r.stderr, r.stderr


def test_rod_messages_carry_what_was_asked():
    m = sc_rt_lcm.rod_fault_cmd_t.decode(rod_inject_msg(2, "stuck", dipole=-4.5, at=12.0, until=30.0).encode())
    assert (m.rod, m.action, m.kind, m.now, m.t_onset, m.t_end, m.dipole) == (
        2, m.ACTION_INJECT, m.KIND_STUCK, False, 12.0, 30.0, -4.5)
    n = rod_inject_msg(3, "reversed")
    assert n.now and n.t_end == -1.0 and n.kind == n.KIND_REVERSED and n.dipole == 0.0
    assert rod_inject_msg(1, "dead").kind == 1  # the core's RodFault::Dead (magnetorquer.hpp)
    c = rod_clear_msg(4)
    assert c.action == c.ACTION_CLEAR and c.rod == 4 and c.now
    r = cli("fault", "inject", "--rod", "2", "--kind", "reversed", "--at", "3", "--prefix", "B1_", "--no-wait")
    assert r.returncode == 0, r.stderr
    assert "inject rod 2 (reversed, at t = 3 s) -> B1_SCRT_ROD_FAULT" in r.stdout
    assert "not waiting for the echo" in r.stdout


def _receiver(accept: bool = True, key: bytes | None = None, session: int = 1):
    """The emulator's receiver built alone on an in-process bus (with ``key``:
    keyed, AuthLCM), day_hold's three rods in its shared values."""
    import lcm

    from sc_rt.wire.auth import AuthLCM

    scn = load_scenario("day_hold")
    shared = Shared(Counter(), scn.actuators, rods=scn.plant.magnetorquers)
    lc = lcm.LCM("memq://")
    if key is not None:
        lc = AuthLCM(lc, key, shared.counters)
    return Receiver(lc, "", session, 10, shared, accept_faults=accept, authenticated=key is not None)


def test_the_emulator_applies_rod_faults_only_when_it_accepts_them_and_refuses_a_rod_it_has_not():
    rx = _receiver(accept=False)
    before = rx.shared.rods
    rx.lc.publish("SCRT_ROD_FAULT", rod_inject_msg(1, "dead").encode())
    rx.lc.handle_timeout(200)
    assert rx.counters["fault_ignored"] == 1 and rx.shared.rods is before

    rx = _receiver()
    scheduled = rx.shared.rods.faults  # day_hold arms rod 2 (stuck at 0 from 1e9 s)
    assert [(f.rod, f.kind) for f in scheduled] == [(1, "stuck")]
    rx.shared.t_now = 12.5
    rx.lc.publish("SCRT_ROD_FAULT", rod_inject_msg(1, "reversed", at=20.0, until=30.0).encode())
    rx.lc.handle_timeout(200)
    rx.on_rod_fault("SCRT_ROD_FAULT", rod_inject_msg(3, "stuck", dipole=7.0).encode())  # now: 12.5
    rx.on_rod_fault("SCRT_ROD_FAULT", rod_inject_msg(2, "dead").encode())  # replaces the scheduled one
    got = {f.rod: (f.kind, f.dipole, f.onset, f.end) for f in rx.shared.rods.faults}
    assert got == {0: ("reversed", 0.0, 20.0, 30.0), 2: ("stuck", 7.0, 12.5, float("inf")),
                   1: ("dead", 0.0, 12.5, float("inf"))}
    rx.on_rod_fault("SCRT_ROD_FAULT", rod_clear_msg(3).encode())
    assert sorted(f.rod for f in rx.shared.rods.faults) == [0, 1]
    # the plant has 3 rods: a 4th (valid on the wire, 1..6) is refused, named; nonsense counted
    rx.on_rod_fault("SCRT_ROD_FAULT", rod_inject_msg(4, "dead").encode())
    rx.on_rod_fault("SCRT_ROD_FAULT", b"nonsense")
    bad = rod_inject_msg(1, "dead")
    bad.kind = 9
    rx.on_rod_fault("SCRT_ROD_FAULT", bad.encode())
    assert rx.counters["fault_applied"] == 4 and rx.counters["fault_rejected"] == 2
    assert rx.counters["malformed"] == 1
    rejected = [r["rejected"] for r in rx.shared.faults_applied if "rejected" in r]
    assert rejected == ["rod must be 1..3 (the plant's rods), got 4", "unknown rod fault kind 9"]
    # what it applied, in order (timing.json's faults_applied): rods 1-based, no end as None
    assert [(r["rod"], r["action"]) for r in rx.shared.faults_applied if "rejected" not in r] == [
        (1, "inject"), (3, "inject"), (2, "inject"), (3, "clear")]
    assert rx.shared.faults_applied[1] == {"t": 12.5, "rod": 3, "action": "inject", "kind": "stuck", "dipole": 7.0,
                                           "onset": 12.5, "end": None}
    # a plant without rods refuses them, named
    scn = load_scenario("paper_fault_free")
    import lcm

    rx = Receiver(lcm.LCM("memq://"), "", 1, 10, Shared(Counter(), scn.actuators), accept_faults=True)
    rx.on_rod_fault("SCRT_ROD_FAULT", rod_inject_msg(1, "dead").encode())
    assert rx.shared.faults_applied == [{"rejected": "the plant has no magnetorquer rods ([magnetorquers])",
                                         "rod": 1}]


def test_a_live_rod_stuck_beyond_its_limit_is_refused_named():
    # day_hold's rods hold 100 A m^2 at most: a command to stick one at more (a valid
    # message: the CLI does not know the plant's rods) leaves the rods as they were
    rx = _receiver()
    before = rx.shared.rods
    for dipole in (100.5, -1e300):
        rx.on_rod_fault("SCRT_ROD_FAULT", rod_inject_msg(1, "stuck", dipole=dipole).encode())
    assert rx.shared.rods is before and rx.counters["fault_rejected"] == 2 and not rx.counters["fault_applied"]
    assert [r["rejected"].split(": ")[-1] for r in rx.shared.faults_applied] == [
        "rod 1 stuck at 100.5 A m^2, beyond its limit 100.0 A m^2",
        "rod 1 stuck at -1e+300 A m^2, beyond its limit 100.0 A m^2"]
    rx.on_rod_fault("SCRT_ROD_FAULT", rod_inject_msg(1, "stuck", dipole=-100.0).encode())  # at the limit: held
    assert [(f.rod, f.kind, f.dipole) for f in rx.shared.rods.faults if f.rod == 0] == [(0, "stuck", -100.0)]


def test_a_flood_of_refused_rod_faults_is_counted_and_only_the_first_reasons_kept():
    # memory bounded by the emulator, not by its input: 250 refusals, 100 reasons kept (MAX_REFUSALS_KEPT)
    rx = _receiver()
    for i in range(250):
        msg = rod_inject_msg(1, "stuck", dipole=200.0 + i)
        msg.seq = 10_000 + i
        rx.on_rod_fault("SCRT_ROD_FAULT", msg.encode())
    assert rx.counters["fault_rejected"] == 250 and len(rx.shared.faults_applied) == 100
    assert rx.shared.faults_applied[-1]["rejected"].endswith("rod 1 stuck at 299.0 A m^2, beyond its limit 100.0 A m^2")
    assert rx.shared.fault_seq_refused == 10_249 and rx.shared.fault_seq_applied == -1  # what the truth echoes


def test_under_auth_key_an_unauthenticated_misaddressed_or_replayed_rod_fault_is_refused():
    from sc_rt.wire.auth import unauthenticated

    key = b"a key for this test"
    rx = _receiver(key=key, session=77)
    before = rx.shared.rods

    def cmd(seq: int, session: int, rod: int = 1) -> bytes:
        m = rod_inject_msg(rod, "dead")
        m.seq, m.session = seq, session
        return m.encode()

    # no tag (an unauthenticated publisher), and a tag of another key: dropped before decoding
    unauthenticated(rx.lc).publish("SCRT_ROD_FAULT", cmd(10, 77))
    rx.lc.handle_timeout(200)
    from sc_rt.wire.auth import message_tag

    data = cmd(11, 77)
    unauthenticated(rx.lc).publish("SCRT_ROD_FAULT", data + message_tag(b"another key", "SCRT_ROD_FAULT", data))
    rx.lc.handle_timeout(200)
    assert rx.counters["auth_failed"] == 2 and rx.shared.rods is before and rx.counters["fault_applied"] == 0
    # tagged, but addressed to no emulator (session 0) or another one: refused
    rx.lc.publish("SCRT_ROD_FAULT", cmd(12, 0))
    rx.lc.handle_timeout(200)
    rx.lc.publish("SCRT_ROD_FAULT", cmd(13, 78))
    rx.lc.handle_timeout(200)
    assert rx.counters["fault_foreign_session"] == 2 and rx.shared.rods is before
    rx.lc.publish("SCRT_ROD_FAULT", cmd(14, 77))
    rx.lc.handle_timeout(200)
    assert rx.counters["fault_applied"] == 1 and [f.kind for f in rx.shared.rods.faults if f.rod == 0] == ["dead"]
    # the same command again, or an older one (a wheel's seq counts: one line): a replay
    rx.lc.publish("SCRT_ROD_FAULT", cmd(14, 77, rod=3))
    rx.lc.handle_timeout(200)
    from sc_rt.tools.faultcmd import inject_msg

    w = inject_msg(2, effectiveness=0.5)
    w.seq, w.session = 20, 77
    rx.lc.publish("SCRT_FAULT", w.encode())
    rx.lc.handle_timeout(200)
    rx.lc.publish("SCRT_ROD_FAULT", cmd(19, 77, rod=3))
    rx.lc.handle_timeout(200)
    assert rx.counters["fault_replayed"] == 2 and rx.counters["fault_applied"] == 2
    assert not [f for f in rx.shared.rods.faults if f.rod == 2]


# --- over real LCM: a lockstep run of day_hold with rod faults sent live ---------------

DURATION = 60.0  # [s] 601 rows at 10 Hz
#: the live commands (sc-rt fault arguments) and the [[magnetorquers.faults]] they amount to: rod 1
#: stuck from the emulator's time when it arrives (before the controller answers state 0: t = 0), rod 3
#: dead on [5, 30) s, rod 2 reversed from 20.3 s (replacing the fault day_hold arms on rod 2)
LIVE = (["--rod", "1", "--kind", "stuck", "--dipole", "4", "--now"],
        ["--rod", "3", "--kind", "dead", "--at", "5", "--until", "30"],
        ["--rod", "2", "--kind", "reversed", "--at", "20.3"])
SCHEDULED = """
[[magnetorquers.faults]]
rod = 1
kind = "stuck"
dipole = 4.0
onset = 0.0

[[magnetorquers.faults]]
rod = 3
kind = "dead"
onset = 5.0
end = 30.0

[[magnetorquers.faults]]
rod = 2
kind = "reversed"
onset = 20.3
"""


@pytest.fixture(scope="module")
def live_run(tmp_path_factory):
    """day_hold for 60 s in lockstep, its controller (sc-rt-controller, as
    sc-rt hil starts it) held back until the three rod faults are sent (an
    event: a file the script makes), so that where they land is known."""
    from sc_rt.hil.procs import controller_binary

    lcmnet.require()
    tmp = tmp_path_factory.mktemp("rod_fault")
    out, go, url = tmp / "hil", tmp / "go", "udpm://239.255.76.67:7983?ttl=0&recv_buf_size=4194304"
    ctl = (f"until [ -e {shlex.quote(str(go))} ]; do sleep 0.05; done; exec {shlex.quote(controller_binary())} "
           '--config "$SCRT_CONFIG" --mode lockstep --lcm-url "$SCRT_LCM_URL" --summary "$SCRT_SUMMARY"')
    wait = f"{PY} {shlex.quote(str(HERE / 'buswait.py'))} '{url}'"
    # --no-wait: a lockstep emulator publishes no truth (no echo) before its controller answers
    faults = "\n".join(f"{PY} -m sc_rt.cli fault inject {' '.join(a)} --no-wait --lcm-url '{url}' || exit 3"
                       for a in LIVE)
    script = f"""
{PY} -m sc_rt.cli hil day_hold --mode lockstep --duration {DURATION:g} --accept-fault-commands --no-plots \\
    --out {out} --lcm-url '{url}' --external {shlex.quote('sh -c ' + shlex.quote(ctl))} --start-timeout 300 \\
    > {tmp}/hil.log 2>&1 &
HIL=$!
export SCRT_WAIT_PID=$HIL
{wait} state 120 > /dev/null || exit 4
{faults}
touch {shlex.quote(str(go))}
wait $HIL
"""
    r = lcmnet.run_script(script, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr + (tmp / "hil.log").read_text()
    assert r.stdout.count("sc-rt fault: inject rod") == 3, r.stdout
    return out, tmp


def _scheduled_file(tmp: Path) -> Path:
    """day_hold with the live faults written as [[magnetorquers.faults]] in place of its own."""
    text = Path(resolve("day_hold")).read_text()
    text, n = re.subn(r"\[\[magnetorquers\.faults\]\].*?\nonset = 1\.0e9[^\n]*\n", SCHEDULED.lstrip(), text,
                      flags=re.S)
    assert n == 1
    path = tmp / "day_hold_scheduled.toml"
    path.write_text(text)
    return path


@pytest.mark.lcm
def test_rod_faults_sent_live_in_lockstep_equal_the_cpp_engine_with_them_scheduled(live_run):
    from sc_rt.scenario.overrides import with_overrides
    from sc_rt.sim.engines import simulate

    out, tmp = live_run
    applied = json.loads((out / "timing.json").read_text())["faults_applied"]
    assert applied == [
        {"t": 0.0, "rod": 1, "action": "inject", "kind": "stuck", "dipole": 4.0, "onset": 0.0, "end": None},
        {"t": 0.0, "rod": 3, "action": "inject", "kind": "dead", "dipole": 0.0, "onset": 5.0, "end": 30.0},
        {"t": 0.0, "rod": 2, "action": "inject", "kind": "reversed", "dipole": 0.0, "onset": 20.3, "end": None}]
    scheduled = load_scenario(_scheduled_file(tmp))
    assert {(f.rod, f.kind, f.onset) for f in scheduled.plant.magnetorquers.faults} == {
        (0, "stuck", 0.0), (2, "dead", 5.0), (1, "reversed", 20.3)}
    hil = load_traj(out)
    every = scheduled.record.every
    run = simulate(with_overrides(scheduled, duration=DURATION), engine="cpp")
    sim = {k: np.asarray(run[k])[::every] for k in hil.files if k != "meta_json" and k in run}
    assert len(run["t"]) == round(DURATION * 10) + 1 and len(hil["t"]) == len(sim["t"])
    done = compared_fields(hil, sim)
    assert {"rod_dipole_cmd", "B_B", "h_wheels_B", "sigma_BN", "omega_BN_B"} <= set(done), done
    # and the faults changed the run: without them (day_hold as shipped) the body rates differ
    plain = simulate(with_overrides(load_scenario("day_hold"), duration=DURATION), engine="cpp")
    w_plain = np.asarray(plain["omega_BN_B"])[::every]
    assert w_plain.shape == hil["omega_BN_B"].shape and not np.array_equal(w_plain, hil["omega_BN_B"])


@pytest.mark.lcm
def test_the_log_holds_the_rod_fault_commands_for_the_report_and_the_mcap(live_run, tmp_path):
    from mcap.reader import make_reader

    from sc_rt.logs.report import read_log, write_report

    out, _ = live_run
    d = read_log(out / "run.lcmlog")
    F = d.records["SCRT_ROD_FAULT"]
    assert list(F["rod"]) == [1, 3, 2] and list(F["kind"]) == [2, 1, 3] and d.undecodable == 0
    rep = write_report(out / "run.lcmlog", tmp_path / "report")
    cmds = [(c["rod"], c["action"], c["kind"], c["now"], c["t_onset"], c["t_end"], c["dipole"])
            for c in rep["faults"]["commands"]]
    assert cmds == [(1, "inject", "stuck", True, 0.0, -1.0, 4.0), (3, "inject", "dead", False, 5.0, 30.0, 0.0),
                    (2, "inject", "reversed", False, 20.3, -1.0, 0.0)]
    # the three reached the plant before its first row: the truth echoes the newest one's seq,
    # which covers the two before it (the log cannot tell those apart: None, drawn as sent)
    assert [c["applied"] for c in rep["faults"]["commands"]] == [None, None, True]
    assert [c["seq"] for c in rep["faults"]["commands"]] == [int(v) for v in F["seq"]]
    mcap = tmp_path / "run.mcap"
    r = lcmnet.run_cli(["export", str(out / "run.lcmlog"), "--mcap", str(mcap)], netns=False)
    assert r.returncode == 0, r.stderr
    rows, schema = [], None
    with open(mcap, "rb") as f:
        for sch, _ch, msg in make_reader(f).iter_messages(topics=["SCRT_ROD_FAULT"]):
            rows.append(json.loads(msg.data))
            schema = json.loads(sch.data)
    assert [(m["rod"], m["kind"], m["dipole"]) for m in rows] == [(1, 2, 4.0), (3, 1, 0.0), (2, 3, 0.0)]
    assert schema["properties"]["dipole"]["description"].startswith("[A m^2]")


@pytest.mark.parametrize("cpp", [True, False])
def test_a_row_with_the_rods_a_command_left_is_the_row_of_a_plant_with_them_scheduled(cpp):
    """The emulator's arithmetic of a row (emulator/twin.py) given the rods
    as a live command left them equals the twin of a plant built with the
    same faults in its scenario (C++ twin and Python model alike)."""
    import dataclasses

    from sc_rt.emulator.twin import PlantTwin
    from sc_rt.model.rods import RodFault
    from sc_rt.scenario.overrides import initial_state

    scn = load_scenario("day_hold")
    faults = (RodFault(rod=0, kind="stuck", dipole=4.0, onset=0.0), RodFault(rod=1, kind="reversed", onset=0.05),
              RodFault(rod=2, kind="dead", onset=0.0, end=0.08))
    rods = dataclasses.replace(scn.plant.magnetorquers, faults=faults)
    live = PlantTwin(scn.plant, cpp)
    sched = PlantTwin(dataclasses.replace(scn.plant, magnetorquers=rods), cpp)
    x0, d_cmd = initial_state(scn), (30.0, -20.0, 10.0)
    a = live.integrate(scn.actuators, 0.0, x0, np.zeros(4), 10, 0.01, d_cmd=d_cmd, rods=rods)
    ra = live.row(scn.actuators, 0.0, x0, np.zeros(4), live.motor_at_start, d_cmd, rods)
    b = sched.integrate(scn.actuators, 0.0, x0, np.zeros(4), 10, 0.01, d_cmd=d_cmd)
    rb = sched.row(scn.actuators, 0.0, x0, np.zeros(4), sched.motor_at_start, d_cmd)
    # a fresh twin (the wheels' motor state goes on from row to row) without the faults
    healthy = PlantTwin(scn.plant, cpp).integrate(scn.actuators, 0.0, x0, np.zeros(4), 10, 0.01, d_cmd=d_cmd)
    assert np.array_equal(a, b) and not np.array_equal(a, healthy)
    assert all(np.array_equal(u, v) for u, v in zip(ra, rb))
    assert [float(v) for v in live.dipole_B(0.06, d_cmd, rods)] == [4.0, 20.0, 0.0]  # stuck, reversed, dead


#: the rod faults the live run's commands left (LIVE; day_hold's armed rod 2 replaced before its onset)
SHOWN = ["rod 1 stuck at 4 A m^2 (live, received at 0 s) from 0 s",
         "rod 2 reversed (live, received at 0 s) from 20.3 s",
         "rod 3 dead (live, received at 0 s) from 5 s to 30 s"]


@pytest.mark.lcm
def test_the_reports_of_the_live_run_and_of_its_log_show_its_rod_faults(live_run, tmp_path, monkeypatch):
    """report.html of the run (timing.json's faults_applied) and of its log
    (sc-rt report: the log's rod_fault_cmd_t) list the three live rod faults
    in the verdict and on the rods' lanes of the timeline, and the log's
    magnetic_control.png marks each rod's (tests/test_rod_view.py: the
    scheduled ones)."""
    from sc_rt.logs.report import write_report
    from sc_rt.results.present import magnetic_figure as magfig
    from sc_rt.results.present.html_report import write_html_report

    out, _ = live_run
    figs = []
    real = magfig.save_figure
    monkeypatch.setattr(magfig, "save_figure", lambda fig, path, *a, **kw: (figs.append(fig), real(fig, path))[1])
    write_report(out / "run.lcmlog", tmp_path / "report")
    for page in (write_html_report(out, tmp_path / "hil.html").read_text(),
                 write_html_report(tmp_path / "report").read_text()):
        assert f'<li id="verdict-rod-faults">Rod faults: {"; ".join(SHOWN)}</li>' in page
        timeline = page[page.index('<section id="timeline">'):page.index("<h2>Figures</h2>")]
        for rod, text in zip((1, 2, 3), SHOWN):
            lane = timeline.split(f">rod {rod} fault</text>")[1].split("</g>")[0]
            assert 'class="rod-fault live"' in lane and text in lane, rod
            assert "scheduled" not in lane  # day_hold's armed rod 2 fault never began
    (fig,) = figs
    gids = {a.get_gid() for ax in fig.axes for a in ax.get_children()}
    assert {"rod-fault-1", "rod-fault-2", "rod-fault-3"} <= gids


@pytest.mark.lcm
def test_the_logged_truth_of_the_rods_is_the_scheduled_faults_applied_by_hand(live_run):
    """plant_truth_t of the live run, row by row: ``rod_dipole_cmd`` the
    logged rod_cmd_t answering the row's state (lockstep), ``rod_dipole``
    that command clipped and through the three faults applied by hand in
    numpy, ``dipole_B`` G_B of it, ``rod_fault`` the kinds at each row's
    time; and the report's rod_dipole_cmd, taken from the truth, equals the
    emulator's own record (fails on the old main: no such fields)."""
    from sc_rt.logs.report import read_log
    from sc_rt.logs.rebuild import rebuild

    out, _ = live_run
    d = read_log(out / "run.lcmlog")
    T, R = d.records["SCRT_TRUTH"], d.records["SCRT_ROD_CMD"]
    rods = load_scenario("day_hold").plant.magnetorquers
    G, lim = np.asarray(rods.axes), np.asarray(rods.max_dipole)
    first = {}
    for i, s in enumerate(R["state_seq"]):
        first.setdefault(int(s), i)
    t = np.asarray(T["t"], float)
    rows = [j for j in range(len(T)) if int(T["seq"][j]) in first]
    assert len(T) >= 600 and len(rows) >= len(T) - 1
    cmd = np.array([np.asarray(R["dipole"][first[int(T["seq"][j])]], float) for j in rows])
    tr = t[rows]
    assert np.array_equal(np.asarray(T["rod_dipole_cmd"][rows], float), cmd)
    assert np.all(T["n_rods"] == 3)
    want = np.clip(cmd[:, :3], -lim, lim)
    want[:, 0] = 4.0  # stuck at 4 A m^2 from t = 0
    dead = (tr >= 5.0) & (tr < 30.0)
    want[dead, 2] = 0.0
    rev = tr >= 20.3
    want[rev, 1] = -want[rev, 1]
    got = np.asarray(T["rod_dipole"][rows], float)
    assert np.array_equal(got[:, :3], want) and not np.any(got[:, 3:])
    np.testing.assert_allclose(np.asarray(T["dipole_B"][rows], float), want @ G.T, rtol=1e-13, atol=1e-12)
    fault = np.asarray(T["rod_fault"][rows], int)
    assert np.array_equal(fault[:, 0], np.full(len(rows), 2))
    assert np.array_equal(fault[:, 1], np.where(rev, 3, -3))
    assert np.array_equal(fault[:, 2], np.where(dead, 1, -1)) and not np.any(fault[:, 3:])
    assert dead.any() and rev.any() and (~rev).any()  # every window seen
    # the report's rows: the truth's commands, equal to the emulator's own record
    r = rebuild(d)
    hil = load_traj(out)
    every = load_scenario("day_hold").record.every
    assert np.array_equal(r.arrays["rod_dipole_cmd"][::every], hil["rod_dipole_cmd"])
