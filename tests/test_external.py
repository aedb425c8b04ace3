"""Your own controller on the bench (issue #14 B): a Python law as an LCM
process (`sc-rt controller`), any process that speaks the protocol
(`sc-rt hil --external`, `--external-wait`), the guidance on the bus and
the optional status. Each run is compared with an independent computation:
the offline run of the same law, the core's guidance, the controller's
own status messages."""

from __future__ import annotations

import json
import sys
import threading
from pathlib import Path

import lcm
import numpy as np
import pytest
import sc_rt_lcm

from sc_rt import _core
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate

import lcmnet
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "external_controller" / "qfb_controller.py"
QFB_OFFLINE = str(ROOT / "examples" / "python_laws" / "pd.py") + ":QuaternionFeedback"
PD_SPEC = str(ROOT / "examples" / "python_laws" / "pd.py") + ":PythonPD"
pytestmark = pytest.mark.lcm

lcmnet.require()


def _events(log: Path) -> dict[str, list[bytes]]:
    out: dict[str, list[bytes]] = {}
    for ev in lcm.EventLog(str(log), "r"):
        out.setdefault(ev.channel, []).append(ev.data)
    return out


def test_example_is_plain_python_under_80_lines():
    text = EXAMPLE.read_text()
    assert len(text.splitlines()) < 80
    assert "import sc_rt\n" not in text and "from sc_rt " not in text and "from sc_rt." not in text


@pytest.mark.slow
def test_external_controller_in_lockstep_equals_the_offline_law(tmp_path):
    """The example (own MRP arithmetic, sc_rt_lcm only, no status) against
    the same law offline through the core's tracking errors."""
    out = tmp_path / "hil"
    d = 60.0
    r = lcmnet.run_cli(["hil", "paper_faults", "--duration", str(d), "--out", str(out),
                        "--external", f"{{python}} {EXAMPLE}"])
    assert r.returncode == 0, r.stderr + r.stdout
    m = json.loads((out / "metrics.json").read_text())
    timing = json.loads((out / "timing.json").read_text())
    hil = load_traj(out)
    off = simulate(load_scenario("paper_faults"), duration=d, law=QFB_OFFLINE)
    rows = int(d * 10) + 1
    assert m["controller"] == "quaternion-feedback" and m["finite"] and m["steps"] == rows
    # tracking errors from the plant side: no NaN although no status was sent
    assert np.all(np.isfinite(hil["sigma_BD"])) and np.all(np.isfinite(hil["omega_BD_B"]))
    for k in ("sigma_BN", "omega_BN_B", "wheel_speed", "u_cmd", "sigma_BD", "omega_BD_B"):
        assert np.allclose(hil[k], off[k], rtol=0, atol=1e-12), (k, np.max(np.abs(hil[k] - off[k])))
    for k in ("first_bound_violation_s", "first_bound_violation_axis", "saturated_fraction", "safe_steps"):
        assert m[k] == off.metrics[k], k
    for k, v in off.metrics["sigma_e_norm"].items():
        assert m["sigma_e_norm"][k] == pytest.approx(v, rel=1e-9), k
    # none missing, none waited for: no status, no timeout, no re-sent state in the run
    emu = timing["emulator_counters"]
    assert timing["dropped"] == 0 and emu.get("cmd_timeout", 0) == 0
    assert emu.get("state_resent", 0) == 0 and emu["ctrl_info"] >= 1
    assert timing["rows"] == rows and timing["steps"] == rows
    for f in ("attitude_error.png", "pointing_error.png", "wheel_commands.png", "timing.png"):
        assert (out / f).stat().st_size > 0, f
    # the log carries the guidance and the announcement; sc-rt report labels and measures the same
    ev = _events(out / "run.lcmlog")
    assert len(ev["SCRT_GUIDANCE"]) >= rows and "SCRT_CTRL_STATUS" not in ev
    rep = tmp_path / "report"
    r = lcmnet.run_cli(["report", str(out / "run.lcmlog"), "--out", str(rep), "--no-plots"], netns=False)
    assert r.returncode == 0, r.stderr
    rm = json.loads((rep / "metrics.json").read_text())
    assert rm["controller"] == "quaternion-feedback"
    for k in ("first_bound_violation_s", "sigma_e_norm", "max_abs_u_cmd", "saturated_fraction"):
        assert rm[k] == m[k], k
    ch = json.loads((rep / "report.json").read_text())["channels"]
    assert ch["SCRT_GUIDANCE"]["type"] == "guidance_t" and ch["SCRT_GUIDANCE"]["count"] >= rows
    assert ch["SCRT_CTRL_INFO"]["count"] >= 1
    assert all(c["undecodable"] == 0 for c in ch.values()), ch
    # the MCAP export decodes the new types like any other (one JSON channel each)
    from mcap.reader import make_reader

    r = lcmnet.run_cli(["export", str(out / "run.lcmlog"), "--mcap", str(tmp_path / "run.mcap")], netns=False)
    assert r.returncode == 0 and " 0 undecodable" in r.stdout, r.stdout + r.stderr
    with open(tmp_path / "run.mcap", "rb") as f:
        topics = {c.topic for c in make_reader(f).get_summary().channels.values()}
    assert {"SCRT_GUIDANCE", "SCRT_CTRL_INFO", "SCRT_STATE", "SCRT_CMD"} <= topics, topics


def test_guidance_on_the_bus_is_the_controllers(tmp_path):
    """guidance_t k equals, bit for bit, the sigma_DN sc-rt-controller
    reports for state k, and omega_DN_D / its derivative equal the core's."""
    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", "paper_faults", "--duration", "10", "--out", str(out), "--no-plots"])
    assert r.returncode == 0, r.stderr
    ev = _events(out / "run.lcmlog")
    g = {m.seq: m for m in map(sc_rt_lcm.guidance_t.decode, ev["SCRT_GUIDANCE"])}
    st = {m.state_seq: m for m in map(sc_rt_lcm.controller_status_t.decode, ev["SCRT_CTRL_STATUS"])}
    states = {m.seq: m for m in map(sc_rt_lcm.plant_state_t.decode, ev["SCRT_STATE"])}
    assert set(g) == set(st) == set(states) == set(range(101))
    params = load_scenario("paper_faults").core_config().guidance
    for k in g:
        assert g[k].sigma_DN == st[k].sigma_DN, k
        assert g[k].t == states[k].t and g[k].session == states[k].session
        assert np.array_equal(g[k].omega_DN_D, _core.omega_d(params, g[k].t))
        assert np.array_equal(g[k].omega_dot_DN_D, _core.omega_d_dot(params, g[k].t))
    # the statuses are still waited for from a controller that sends them: one per row
    assert json.loads((out / "metrics.json").read_text())["controller"] == "dsc-ppc"


def test_python_law_through_lcm_equals_offline_bitwise(tmp_path):
    """`sc-rt hil --law module:Class` (sc-rt controller, lockstep) is the
    offline run of the same Python law to the last bit, and the process's
    summary has the C++ process's keys."""
    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", "paper_faults", "--duration", "20", "--law", PD_SPEC, "--out", str(out),
                        "--no-plots"])
    assert r.returncode == 0, r.stderr + r.stdout
    hil = load_traj(out)
    off = simulate(load_scenario("paper_faults"), duration=20, law=PD_SPEC)
    for k in ("sigma_BN", "omega_BN_B", "wheel_speed", "u_cmd", "u_sat", "sigma_BD", "omega_BD_B", "e1",
              "e2", "chi", "lam", "flags", "ctrl_mode"):
        assert np.array_equal(hil[k], off[k], equal_nan=True), k
    s = json.loads((out / "controller_summary.json").read_text())
    # the same keys as sc-rt-controller's summary (from a run of the C++ process)
    r = lcmnet.run_cli(["hil", "paper_faults", "--duration", "1", "--law", "pd", "--out", str(tmp_path / "cpp"),
                        "--no-plots"])
    assert r.returncode == 0, r.stderr
    cpp = json.loads((tmp_path / "cpp" / "controller_summary.json").read_text())
    assert set(s) == set(cpp) and set(s["rejected"]) == set(cpp["rejected"])
    assert s["law"] == "python-pd" and s["mode"] == "lockstep"
    assert s["steps"] == 201 + s["rejected"]["duplicate"] or s["steps"] == 201
    assert json.loads((out / "metrics.json").read_text())["controller"] == "python-pd"


def _statusless_controller(url: str, stop: threading.Event, answered: list) -> None:
    """A controller that sends commands only: no info, no status."""
    lc = lcm.LCM(url)
    session = 12345

    def on_state(_ch, data):
        s = sc_rt_lcm.plant_state_t.decode(data)
        c = sc_rt_lcm.wheel_cmd_t()
        c.seq, c.session, c.state_seq, c.t = len(answered), session, s.seq, s.t
        answered.append(s.seq)
        lc.publish("SCRT_CMD", c.encode())

    lc.subscribe("SCRT_STATE", on_state)
    while not stop.is_set():
        lc.handle_timeout(20)


def test_statusless_controller_is_not_waited_for():
    """Run inside the network namespace: an emulator with a 60 s command
    timeout finishes 31 states against a controller that never sends a
    status (waiting for one per state would take 31 minutes)."""
    code = f"""
import sys, threading
sys.path.insert(0, {str(ROOT / 'tests')!r})
from test_external import _statusless_controller
from sc_rt.emulator.process import Emulator, Options
from sc_rt.wire.lcmio import free_port_url
from sc_rt.scenario.reader import load_scenario
url = free_port_url()
stop, answered = threading.Event(), []
th = threading.Thread(target=_statusless_controller, args=(url, stop, answered), daemon=True)
th.start()
emu = Emulator(load_scenario("paper_faults"), Options(url=url, duration=3.0, cmd_timeout=60.0, start_timeout=30.0))
run = emu.run()
stop.set()
import numpy as np
assert len(run) == 31 and not np.any(run["cmd_stale"]), run.counters
assert run.counters.get("cmd_timeout", 0) == 0
print("OK", run.meta.law)
"""
    r = lcmnet.run([sys.executable, "-c", code], timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["OK", "external"]  # commands only, no name announced


@pytest.mark.slow
def test_external_wait_takes_a_controller_started_by_hand(tmp_path):
    out = tmp_path / "hil"
    script = (f"{sys.executable} -m sc_rt.cli hil paper_faults --duration 5 --no-plots --out {out} "
              f"--external-wait --start-timeout 60 --lcm-url udpm://239.255.76.67:7771?ttl=0 "
              f"--prefix T1_ 2>{tmp_path}/hil.err & H=$!; "
              # the controller is started when sc-rt hil says it waits (an event, not a sleep)
              f"until grep -q 'waiting up to' {tmp_path}/hil.err; do sleep 0.05; done; "
              f"SCRT_LCM_URL=udpm://239.255.76.67:7771?ttl=0 SCRT_PREFIX=T1_ SCRT_CONFIG={out}/controller_config.bin "
              f"{sys.executable} {EXAMPLE} 2>/dev/null & C=$!; wait $H; R=$?; kill $C; exit $R")
    r = lcmnet.run_script(script, timeout=120)
    assert r.returncode == 0, (tmp_path / "hil.err").read_text()
    m = json.loads((out / "metrics.json").read_text())
    assert m["controller"] == "quaternion-feedback" and m["steps"] == 51 and m["finite"]
    t = json.loads((out / "timing.json").read_text())
    assert t["dropped"] == 0


@pytest.mark.parametrize("argv,word", [
    (["--external", "/nonexistent/controller"], "cannot start"),
    (["--external", "sh -c 'exit 3'"], "died (exit code 3)"),
    (["--external", "'unbalanced"], "--external"),
    (["--external-wait", "--law", PD_SPEC], "cannot be combined"),
    (["--start-timeout", "5"], "--start-timeout"),
])
def test_bad_external_options_are_one_line(argv, word, tmp_path):
    r = lcmnet.run_cli(["hil", "paper_faults", "--duration", "1", "--no-plots", "--out", str(tmp_path / "o"),
                        *argv], timeout=120)
    assert r.returncode == 2, r.stderr
    lines = [x for x in r.stderr.splitlines() if not x.startswith("sc-rt hil: LCM URL")]
    assert len(lines) == 1 and word in lines[0], r.stderr


def test_emulator_with_a_hand_started_controller_records_errors_and_label(tmp_path):
    """`sc-rt emulator --start-timeout` waits for a controller started after
    it; its run has the tracking errors (from the plant side: the example
    sends no status), metrics and the announced law's name."""
    out = tmp_path / "emu"
    cfg = tmp_path / "cfg.bin"
    url = "udpm://239.255.76.67:7772?ttl=0"
    script = (f"{sys.executable} -m sc_rt.cli config paper_faults --out {cfg} >/dev/null || exit 3\n"
              f"{sys.executable} -m sc_rt.cli emulator paper_faults --duration 5 --out {out} --lcm-url '{url}' "
              f"--start-timeout 60 >{tmp_path}/emu.out 2>{tmp_path}/emu.err & E=$!; "
              f"SCRT_LCM_URL='{url}' {sys.executable} {EXAMPLE} {cfg} 2>/dev/null & C=$!; "
              f"wait $E; R=$?; kill $C; exit $R")
    r = lcmnet.run_script(script, timeout=120)
    assert r.returncode == 0, (tmp_path / "emu.err").read_text()
    tr = load_traj(out)
    assert len(tr["t"]) == 51 and not np.any(tr["cmd_stale"])
    assert np.all(np.isfinite(tr["sigma_BD"])) and np.all(np.isfinite(tr["omega_BD_B"]))
    m = json.loads((out / "metrics.json").read_text())
    assert m["controller"] == "quaternion-feedback" and m["finite"]
    off = simulate(load_scenario("paper_faults"), duration=5, law=QFB_OFFLINE)
    assert np.allclose(tr["sigma_BD"], off["sigma_BD"], rtol=0, atol=1e-12)


@pytest.mark.slow  # a 3 s real-time run
def test_python_law_in_real_time(tmp_path):
    """sc-rt controller in real time: its own deadlines (PhaseLock), the C++
    process's summary, the timing report from its status messages."""
    out = tmp_path / "rt"
    r = lcmnet.run_cli(["hil", "paper_faults", "--mode", "realtime", "--control-rate", "20", "--duration", "3",
                        "--law", PD_SPEC, "--out", str(out), "--no-plots"], timeout=120)
    assert r.returncode == 0, r.stderr + r.stdout
    s = json.loads((out / "controller_summary.json").read_text())
    t = json.loads((out / "timing.json").read_text())
    m = json.loads((out / "metrics.json").read_text())
    assert s["mode"] == "realtime" and s["control_rate_hz"] == 20.0 and s["law"] == "python-pd"
    assert s["steps"] >= 40 and s["received"] >= 40  # it ran on its own clock through the run (61 ticks)
    assert t["rows"] == 61 and t["mode"] == "realtime" and m["controller"] == "python-pd" and m["finite"]
    assert t["compute_us"]["p50"] > 0 and t["wake_lateness_us"]["p50"] is not None
    hil = load_traj(out)
    used = ~np.isnan(hil["compute_us"])  # rows whose state the controller used (its status)
    assert used.sum() >= 30 and np.all(np.isfinite(hil["sigma_BD"]))  # most ticks, even on a loaded machine


@pytest.mark.slow  # a 3 s real-time run
def test_external_controller_in_real_time(tmp_path):
    """The example answers each state on arrival, which is all real time
    needs: every tick has a fresh command once it runs, and the run is
    labelled and measured like any other."""
    out = tmp_path / "rt"
    r = lcmnet.run_cli(["hil", "paper_faults", "--mode", "realtime", "--control-rate", "20", "--duration", "3",
                        "--external", f"{{python}} {EXAMPLE}", "--out", str(out), "--no-plots"], timeout=120)
    assert r.returncode == 0, r.stderr + r.stdout
    m = json.loads((out / "metrics.json").read_text())
    t = json.loads((out / "timing.json").read_text())
    assert m["controller"] == "quaternion-feedback" and m["finite"] and t["rows"] == 61
    tr = load_traj(out)
    assert np.all(np.isfinite(tr["sigma_BD"]))
    assert np.count_nonzero(tr["cmd_stale"] == 0) >= 30  # commands applied on most of the 61 ticks
