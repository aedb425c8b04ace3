"""A lockstep controller with the sensors' estimator answers a re-sent state
again and stays alive (found by tests/test_sanitizers.py: the slower ASan
build made the emulator re-send states, and the controller deadlocked on its
own mutex; issue #24, item 6)."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

import pytest

import lcmnet

ROOT = Path(__file__).resolve().parent.parent
pytestmark = pytest.mark.lcm

# The emulator's resend: the same plant_state_t (same session and seq) twice.
# Each must get its command; then SIGTERM must end the controller at once.
DRIVER = r"""
import json, subprocess, sys, time
import lcm, sc_rt_lcm
ctl_bin, cfg, url, out = sys.argv[1:5]
p = subprocess.Popen([ctl_bin, "--config", cfg, "--lcm-url", url], stdout=subprocess.DEVNULL,
                     stderr=subprocess.PIPE, text=True)
assert "mode on" in p.stderr.readline()
lc = lcm.LCM(url)
cmds = []
lc.subscribe("SCRT_CMD", lambda c, d: cmds.append(sc_rt_lcm.wheel_cmd_t.decode(d).state_seq))
m = sc_rt_lcm.plant_state_t()
m.seq, m.session, m.t = 0, 42, 0.0
m.sigma_BN, m.omega_BN_B, m.wheel_speed = [0.3, -0.2, -0.4], [-0.01, 0.02, -0.03], [0.0] * 4
for i in range(2):
    lc.publish("SCRT_STATE", m.encode())
    end = time.monotonic() + 10
    while len(cmds) <= i and time.monotonic() < end:
        lc.handle_timeout(50)
p.terminate()
try:
    rc = p.wait(10)
except subprocess.TimeoutExpired:
    p.kill()
    rc = "hung"
json.dump({"cmds": cmds, "rc": rc}, open(out, "w"))
"""


def test_a_resent_state_is_answered_again_with_the_estimator_on(tmp_path):
    lcmnet.require()
    cfg = tmp_path / "cfg.bin"
    r = lcmnet.run([sys.executable, "-m", "sc_rt.cli", "config", "paper_faults_sensors", "--out", str(cfg)],
                   netns=False, timeout=120)
    assert r.returncode == 0, r.stderr
    drv = tmp_path / "driver.py"
    drv.write_text(DRIVER)
    out = tmp_path / "out.json"
    ctl = Path(sys.executable).parent / "sc-rt-controller"
    url = "udpm://239.255.76.67:7761?ttl=0"
    r = lcmnet.run_script(f"{shlex.quote(sys.executable)} {drv} {ctl} {cfg} '{url}' {out}", timeout=120)
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    # both copies answered (the second one: the same command again), and the
    # controller ended on SIGTERM instead of hanging on its mutex
    assert d["cmds"] == [0, 0] and d["rc"] == 0, d
