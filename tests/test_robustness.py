"""Robustness over real LCM: hostile input during a lockstep run, a killed
and restarted controller, stale states in real time. Each is a real run."""

from __future__ import annotations

import json
import os
import shlex
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt.analysis import TRAJECTORY_KEYS
from sc_rt.scenario import load_scenario
from sc_rt.sim import simulate

import lcmnet

ROOT = Path(__file__).resolve().parent.parent
HERE = Path(__file__).resolve().parent
pytestmark = pytest.mark.lcm
PY = shlex.quote(sys.executable)


def run_in_netns(script: str, timeout: float = 300) -> subprocess.CompletedProcess:
    """A shell script in one network namespace (or on the host loopback)."""
    p = subprocess.Popen(lcmnet.wrap(["sh", "-c", script]), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, cwd=ROOT, start_new_session=True)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        out, err = p.communicate()
        pytest.fail(f"did not finish in {timeout} s:\n{err[-3000:]}")
    return subprocess.CompletedProcess(script, p.returncode, out, err)


def test_fuzz_during_lockstep_run_changes_nothing(tmp_path):
    # 4 MB socket buffers (the host's rmem_max): a burst must not overflow them
    url = "udpm://239.255.76.67:7711?ttl=0&recv_buf_size=4194304"
    n = 100_000
    out = tmp_path / "hil"
    sent = tmp_path / "sent.json"
    script = f"""
set -e
{PY} -m sc_rt.cli hil scenarios/paper_faults.toml --controller dsc --duration 2000 --no-plots \\
    --out {out} --lcm-url '{url}' > {tmp_path}/hil.log 2>&1 &
HIL=$!
sleep 1.0
{PY} {HERE / 'fuzz_lcm.py'} '{url}' {n} {sent}
wait $HIL
"""
    r = run_in_netns(script, timeout=600)
    assert r.returncode == 0, r.stderr + (tmp_path / "hil.log").read_text()
    s = json.loads(sent.read_text())
    assert s["n"] == n
    timing = json.loads((out / "timing.json").read_text())
    summary = json.loads((out / "controller_summary.json").read_text())
    # the fuzzing overlapped the run: the run was still going when it ended
    assert timing["wall_s"] > s["seconds"]
    # both processes stayed up and answered every state
    assert summary["steps"] == timing["rows"] == 20001
    assert timing["dropped"] == 0
    # every hostile message was counted by its receiver, never applied
    by_channel = {ch: sum(v for k, v in s["sent"].items() if k.startswith(ch + ":"))
                  for ch in ("SCRT_STATE", "SCRT_CMD", "SCRT_CTRL_STATUS", "SCRT_FAULT")}
    emu = timing["emulator_counters"]
    # (a state the emulator re-sent after a slow answer is a duplicate too)
    ctl_rejected = sum(summary["rejected"].values()) - emu.get("state_resent", 0)
    assert ctl_rejected == by_channel["SCRT_STATE"], (summary["rejected"], by_channel)
    emu_rejected = sum(emu.get(k, 0) for k in ("malformed", "trailing_bytes", "invalid_command",
                                                "foreign_session", "duplicate", "out_of_order",
                                                "status_out_of_order", "fault_ignored"))
    assert emu_rejected == by_channel["SCRT_CMD"] + by_channel["SCRT_CTRL_STATUS"] + by_channel["SCRT_FAULT"], emu
    assert timing["faults_applied"] == []
    # and the trajectory is bit-identical to a clean offline run
    hil = np.load(out / "trajectory.npz")
    sim = simulate(load_scenario(ROOT / "scenarios/paper_faults.toml"), law="dsc", engine="python",
                   duration=2000)
    for k in TRAJECTORY_KEYS:
        assert np.array_equal(hil[k], sim.trajectory[k]), k
