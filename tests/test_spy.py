"""sc-rt spy during a real-time HIL run; sc-rt lcm-spy (LCM's GUI) with our
types under Xvfb, fed by sc-rt replay; the spy never dies of a bad message."""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import lcm
import pytest
import sc_rt_lcm

from sc_rt.wire import codec as wire
from sc_rt.tools.spy import Spy

import lcmnet

ROOT = Path(__file__).resolve().parent.parent
HERE = Path(__file__).resolve().parent
PY = shlex.quote(sys.executable)
PERIODIC = ("SCRT_STATE", "SCRT_CMD", "SCRT_CTRL_STATUS", "SCRT_TRUTH")


@pytest.mark.slow  # ~8-10 s: a 9 s real-time run
def test_spy_sees_every_channel_at_the_configured_rate(tmp_path):
    lcmnet.require()
    rate = 100.0
    listen = 3.0
    url = "udpm://239.255.76.67:7731?ttl=0"
    out = tmp_path / "hil"
    # the spy starts once the run's states are on the bus (an event, waited
    # for up to 60 s), then listens 3 s of a 9 s run
    script = f"""
set -e
{PY} -m sc_rt.cli hil scenarios/paper_fault_free.toml --mode realtime --control-rate {rate} \\
    --duration 9 --out {out} --no-plots --lcm-url '{url}' > {tmp_path}/hil.log 2>&1 &
HIL=$!
SCRT_WAIT_PID=$HIL {PY} {shlex.quote(str(HERE / 'buswait.py'))} '{url}' state 60 > /dev/null
{PY} -m sc_rt.cli spy --lcm-url '{url}' --once --json --duration {listen} > {tmp_path}/spy.json
wait $HIL
"""
    r = lcmnet.run_script(script, timeout=180)
    assert r.returncode == 0, r.stderr + (tmp_path / "hil.log").read_text()
    snap = json.loads((tmp_path / "spy.json").read_text())
    timing = json.loads((out / "timing.json").read_text())
    # the run itself kept the configured rate: every tick (a command late for
    # a tick on a loaded machine is the controller's miss, not the spy's)
    assert timing["rows"] == int(9 * rate) + 1, timing
    # how late the publishers were at worst, by their own measurements: the
    # emulator's ticks (states, truth) and the controller's wake-ups (commands, status)
    late_s = (timing["emulator_tick_lateness_us"]["max"] + timing["wake_lateness_us"]["max"]) / 1e6
    ch = snap["channels"]
    types = {"SCRT_STATE": "plant_state_t", "SCRT_CMD": "wheel_cmd_t",
             "SCRT_CTRL_STATUS": "controller_status_t", "SCRT_TRUTH": "plant_truth_t"}
    rates = {}
    for name in PERIODIC:
        assert name in ch, (name, sorted(ch))
        c = ch[name]
        assert c["type"] == types[name] and c["undecodable"] == 0, c
        rates[name] = c["rate_hz"]
        # the span the spy observed (first to last arrival): at least a second
        # of the run, at most its listening time
        span = (c["count"] - 1) / c["rate_hz"]
        assert 1.0 <= span <= listen + 0.5, (name, span, c)
        # over that span the rate is the configured one, up to the lateness of
        # the first and last message (the publisher's worst lateness, the
        # spy's own largest gap) and one message; 5 % on a quiet machine
        tol = max(0.05 * rate, rate * (late_s + c["max_gap_ms"] / 1e3) / span + 1 / span)
        assert tol <= 0.5 * rate, (name, tol, late_s, c)  # still a measurement of the rate
        assert abs(c["rate_hz"] - rate) <= tol, (name, c["rate_hz"], tol, c["count"])
        assert c["jitter_ms"] is not None and c["jitter_ms"] >= 0
    print("spy rates [Hz]:", rates)
    # it counted no state twice: no more than were published up to the last it saw
    st = ch["SCRT_STATE"]
    assert st["count"] <= st["latest"]["seq"] + 1 and st["latest"]["seq"] < timing["rows"], st
    s = ch["SCRT_CTRL_STATUS"]["summary"]
    assert s["law"] == "dsc-ppc" and len(s["sigma_BD"]) == 3 and s["compute_us"] > 0
    assert len(ch["SCRT_STATE"]["summary"]["wheel_speed"]) == 4
    assert ch["SCRT_CMD"]["latest"]["seq"] > 0
    assert ch["SCRT_TRUTH"]["summary"]["fault_effectiveness"] == [1.0] * 4


def test_spy_counts_bad_messages_and_renders(tmp_path):
    # memq: LCM's in-process provider; the spy publishes to itself
    spy = Spy("memq://", window=10.0)
    good = sc_rt_lcm.plant_state_t()
    good.seq, good.t = 7, 0.7
    cmd = sc_rt_lcm.wheel_cmd_t()
    cmd.flags = cmd.FLAG_BOUND_Y | cmd.FLAG_SAT_3
    cmd.mode = cmd.MODE_NORMAL
    cfg = sc_rt_lcm.controller_config_t()
    cfg.scenario = "x"
    for data in (good.encode(), b"garbage", good.encode()[:-1], good.encode() + b"\0", b""):
        spy.lc.publish("SCRT_STATE", data)
    spy.lc.publish("SCRT_CMD", cmd.encode())
    spy.lc.publish("SCRT_CONFIG", cfg.encode())
    spy.lc.publish("SCRT_CONFIG", cfg.encode() + b"zz")
    spy.lc.publish("SCRT_CTRL_STATUS", sc_rt_lcm.controller_status_t().encode())
    spy.lc.publish("SCRT_TRUTH", sc_rt_lcm.plant_truth_t().encode())
    spy.lc.publish("SCRT_FAULT", sc_rt_lcm.fault_cmd_t().encode())
    spy.listen(0.3)
    snap = json.loads(json.dumps(spy.snapshot()))
    st = snap["channels"]["SCRT_STATE"]
    assert st["count"] == 5 and st["undecodable"] == 4 and st["type"] == "plant_state_t"
    assert st["undecodable_kinds"] == {"unknown_type": 2, "malformed": 1, "trailing_bytes": 1}
    assert st["latest"]["seq"] == 7 and st["summary"]["t"] == 0.7
    c = snap["channels"]["SCRT_CMD"]["summary"]
    assert c["flags"] == ["BOUND_Y", "SAT_3"] and c["mode"] == "NORMAL"
    assert snap["channels"]["SCRT_CONFIG"]["undecodable_kinds"] == {"trailing_bytes": 1}
    text = spy.render()
    for name in ("SCRT_STATE", "SCRT_CMD", "SCRT_CTRL_STATUS", "SCRT_TRUTH", "SCRT_FAULT", "SCRT_CONFIG"):
        assert name in text
    assert "BOUND_Y" in text and "scenario x" in text


def _synthetic_log(path: Path, seconds: float, rate: float) -> None:
    log = lcm.EventLog(str(path), "w", overwrite=True)
    n = int(seconds * rate)
    for k in range(n):
        ts = 1_000_000 + int(k * 1e6 / rate)
        s = sc_rt_lcm.plant_state_t()
        s.seq, s.t = k, k / rate
        s.wheel_speed = [10.0, -5.0, 3.0, 0.5]
        c = sc_rt_lcm.controller_status_t()
        c.state_seq, c.t, c.steps = k, k / rate, k + 1
        c.sigma_BD = [1e-3, -2e-3, 5e-4]
        log.write_event(ts, "SCRT_STATE", s.encode())
        log.write_event(ts + 200, "SCRT_CTRL_STATUS", c.encode())
        log.write_event(ts + 300, "SCRT_TRUTH", sc_rt_lcm.plant_truth_t().encode())
        log.write_event(ts + 400, "NOT_OURS", b"\x01\x02\x03")
    log.close()


@pytest.mark.slow  # ~11-12 s: Xvfb, a JDK build of the types jar, lcm-spy, an 8 s replay
def test_lcm_spy_finds_our_types_under_xvfb(tmp_path):
    """The real lcm-spy, started by sc-rt lcm-spy, while sc-rt replay plays a
    log: it loads our types jar (built here from the .lcm files into a fresh
    cache) and decodes without an exception; sc-rt spy sees the replay."""
    lcmnet.require()
    missing = [t for t in ("Xvfb", "java", "javac", "jar") if shutil.which(t) is None]
    if missing:
        pytest.fail(f"{', '.join(missing)} not found: the lcm-spy test needs Xvfb and a JDK "
                    "(Debian: apt-get install xvfb default-jdk-headless; .ci/run installs them)",
                    pytrace=False)
    log = tmp_path / "play.lcmlog"
    _synthetic_log(log, 8.0, 50.0)
    url = "udpm://239.255.76.67:7732?ttl=0"
    shot = tmp_path / "lcm-spy.png"
    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path / "cache"))
    env.pop("DISPLAY", None)
    GRAB = ("import sys; from PIL import ImageGrab; im = ImageGrab.grab(xdisplay=sys.argv[1]); "
            "im.save(sys.argv[2]); sys.exit(len(im.convert('L').getcolors(1 << 16) or []) <= 5)")
    script = f"""
set -e
cd {tmp_path}
Xvfb -displayfd 3 -screen 0 1024x768x24 -nolisten tcp 3>display.txt 2>xvfb.log &
XVFB=$!
trap 'kill $XVFB $PLAY $SPY 2>/dev/null || true' EXIT
for i in $(seq 600); do [ -s display.txt ] && break; sleep 0.1; done
export DISPLAY=:$(cat display.txt)
{PY} -m sc_rt.cli lcm-spy --build-only > jar.txt
{PY} -m sc_rt.cli lcm-spy --lcm-url '{url}' > lcm-spy.out 2>&1 &
SPY=$!
# the replay starts once lcm-spy has loaded the types (what it prints at start)
for i in $(seq 600); do grep -q 'LCM types' lcm-spy.out && break; sleep 0.1; done
{PY} -m sc_rt.cli replay {log} --lcm-url '{url}' &
PLAY=$!
{PY} -m sc_rt.cli spy --lcm-url '{url}' --once --json --duration 2 > spy.json
# the screenshot once the window is drawn (not one flat colour), up to 60 s
for i in $(seq 60); do
  {PY} -c "{GRAB}" "$DISPLAY" '{shot}' && break
  sleep 1
done
kill $SPY; wait $SPY || true
wait $PLAY
"""
    r = lcmnet.run_script(script, timeout=120, env=env)
    spy_out = (tmp_path / "lcm-spy.out").read_text() if (tmp_path / "lcm-spy.out").exists() else ""
    assert r.returncode == 0, r.stderr + spy_out
    jar = Path((tmp_path / "jar.txt").read_text().strip())
    assert jar.parent == tmp_path / "cache" / "sc-rt" and jar.exists()
    # what lcm-spy prints at start: the number of LCM classes found on its CLASSPATH
    m = re.search(r"Found (\d+) LCM types", spy_out)
    assert m and int(m.group(1)) >= len(wire.TYPES), spy_out
    assert "CLASSPATH=" + str(jar) in spy_out
    assert "messageReceived ex" not in spy_out and "Exception in thread" not in spy_out, spy_out
    snap = json.loads((tmp_path / "spy.json").read_text())["channels"]
    assert snap["SCRT_STATE"]["type"] == "plant_state_t"
    # the log's 50 Hz over the span the spy observed, up to the lateness of its
    # first and last message (bounded by the largest gap it saw) and one
    # message; 5 % on a quiet machine
    c = snap["SCRT_STATE"]
    span = (c["count"] - 1) / c["rate_hz"]
    assert 1.0 <= span <= 2.5, c
    tol = max(2.5, 50.0 * 2 * c["max_gap_ms"] / 1e3 / span + 1 / span)
    assert tol <= 25.0 and abs(c["rate_hz"] - 50.0) <= tol, (tol, c)
    assert snap["NOT_OURS"]["type"] is None and snap["NOT_OURS"]["undecodable"] > 0
    # the window is there: the screenshot is not one flat colour
    from PIL import Image

    img = Image.open(shot).convert("L")
    assert len(img.getcolors(1 << 16) or []) > 5


@pytest.mark.slow  # ~1-6 s: javac builds the types jar and a checker
def test_types_jar_decodes_messages_encoded_by_python(tmp_path, monkeypatch):
    """Java and Python agree on the wire: each class of the jar decodes a
    Python-encoded message of its type (the fingerprints match)."""
    if shutil.which("javac") is None:
        pytest.fail("javac not found (Debian: apt-get install default-jdk-headless)", pytrace=False)
    from sc_rt.tools.lcmspy import lcm_jar, types_jar

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    jar = types_jar()
    args = []
    for name, cls in sorted(wire.TYPES.items()):
        m = cls()
        if name == "plant_state_t":
            m.seq, m.t = 42, 4.2
        f = tmp_path / f"{name}.bin"
        f.write_bytes(m.encode())
        args.append(f"{name}={f}")
    (tmp_path / "Check.java").write_text("""
import java.nio.file.*;
public class Check {
    public static void main(String[] args) throws Exception {
        String ps = null;
        for (String a : args) {
            String[] kv = a.split("=", 2);
            if (kv[0].equals("plant_state_t")) ps = kv[1];
            byte[] data = Files.readAllBytes(Paths.get(kv[1]));
            Object o = Class.forName("sc_rt_lcm." + kv[0]).getConstructor(byte[].class).newInstance((Object) data);
            System.out.println("OK " + o.getClass().getName());
        }
        System.out.println(new sc_rt_lcm.plant_state_t(Files.readAllBytes(Paths.get(ps))).seq);
    }
}
""")
    cp = f"{lcm_jar()}{os.pathsep}{jar}"
    r = subprocess.run(["javac", "-cp", cp, "-d", str(tmp_path), str(tmp_path / "Check.java")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert sum(a.startswith("plant_state_t=") for a in args) == 1
    r = subprocess.run(["java", "-cp", f"{cp}{os.pathsep}{tmp_path}", "Check", *args],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == sum((["OK", f"sc_rt_lcm.{n}"] for n in sorted(wire.TYPES)), []) + ["42"]


def test_lcm_spy_without_java_says_what_to_install(tmp_path):
    env = dict(os.environ, PATH=str(tmp_path), XDG_CACHE_HOME=str(tmp_path / "cache"))
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "lcm-spy", "--build-only"], capture_output=True,
                       text=True, env=env, cwd=ROOT)
    assert r.returncode == 2
    assert "default-jdk-headless" in r.stderr and "javac" in r.stderr


@pytest.mark.parametrize("mode", [["--once"], ["--once", "--json"], []])
def test_spy_says_when_nothing_is_heard(mode):
    """Nothing on the bus: the spy names the URL and exits 1 (--once, or
    live with --duration), so a script can tell an empty bus from a quiet one."""
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "spy", "--lcm-url", "memq://", "--duration", "0.3",
                        *mode], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "sc-rt spy: nothing heard on memq://" in r.stderr
