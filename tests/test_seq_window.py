"""Sequence numbers one message cannot poison (issue 40 item 2,
docs/PROTOCOL.md "Sequence numbers"), without --auth-key, in lockstep over
real LCM with a forger on the bus (tests/seqjump_lcm.py):

- one plant state with the live session and seq + 10^6: the controller drops
  it (counted seq_jump) and follows the genuine states; the run is valid and
  bitwise the offline one. Before: every genuine state after it was "out of
  order", 423 of 601 rows zeroed, valid.
- one command with the controller's session and seq + 10^6: the plant drops
  it (cmd_seq_jump); the run is valid, bitwise the offline one, no row
  applies the forged [9, -7, 9, -7].
- commands racing the controller's own (its session, the next seq): counted
  as conflicts and the run fails, named. Before: the forged commands were
  applied and the run failed only by chance.

And the gate's rule itself, on the bound InputGate: a jump is taken only
when its successor confirms it (a plant that really moved on)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core, load_scenario, simulate

import lcmnet
from trajcmp import load_traj

HERE = Path(__file__).resolve().parent
PY = sys.executable
W = 1000  # the window of cpp/shell/input_gate.hpp kSeqWindow and emulator/inbox.py SEQ_WINDOW


def test_the_gate_takes_a_jump_only_when_its_successor_confirms_it():
    g = _core.InputGate(2_000_000_000)
    V = _core.GateVerdict
    assert g.offer(0, 7, 0, True) == V.Accept
    assert g.offer(1, 7, 1, True) == V.Accept
    assert g.offer(2, 7, 1 + W + 1, True) == V.SeqJump  # one forged message: dropped
    assert g.offer(3, 7, 2, True) == V.Accept  # the genuine ones go on
    assert g.seq == 2
    assert g.offer(4, 7, 2 + W, True) == V.Accept  # within the window: a plant that lost W - 1 states
    assert g.offer(5, 7, 2 + 3 * W, True) == V.SeqJump
    assert g.offer(6, 7, 2 + 3 * W + 1, True) == V.Accept  # confirmed by its successor
    assert g.seq == 2 + 3 * W + 1 and g.counts().seq_jump == 2


def _bench(tmp_path: Path, mode: str, port: int) -> tuple:
    out = tmp_path / "hil"
    script = f"""
{PY} -m sc_rt.cli hil paper_faults --mode lockstep --no-plots --out {out} \
    --lcm-url 'udpm://239.255.76.67:{port}?ttl=0&recv_buf_size=4194304' > {tmp_path}/hil.log 2>&1 &
HIL=$!
SCRT_WAIT_PID=$HIL {PY} {HERE / 'seqjump_lcm.py'} 'udpm://239.255.76.67:{port}?ttl=0' {mode} {tmp_path}/forged.json
wait $HIL
echo "rc=$?"
"""
    r = lcmnet.run_script(script, timeout=300)
    log = (tmp_path / "hil.log").read_text()
    forged = json.loads((tmp_path / "forged.json").read_text())
    return r, log, forged, out


def _same_as_offline(out: Path) -> None:
    hil = load_traj(out)
    sim = simulate(load_scenario("paper_faults"), engine="python")
    for k in ("sigma_BN", "omega_BN_B", "u_cmd", "wheel_speed"):
        assert np.array_equal(hil[k], sim[k]), k
    assert not np.any(np.all(hil["u_cmd"] == [9.0, -7.0, 9.0, -7.0], axis=1))


@pytest.mark.lcm
def test_one_forged_state_far_ahead_does_not_cut_the_controller_off(tmp_path):
    lcmnet.require()
    r, log, forged, out = _bench(tmp_path, "state", 7971)
    assert "rc=0" in r.stdout and forged["sent"]["SCRT_STATE"] == 1, r.stdout + log + str(forged)
    summary = json.loads((out / "controller_summary.json").read_text())
    assert summary["rejected"]["seq_jump"] == 1, summary["rejected"]
    m = json.loads((out / "metrics.json").read_text())
    assert m["valid"] is True
    _same_as_offline(out)


@pytest.mark.lcm
def test_one_forged_command_far_ahead_does_not_cut_the_plant_off(tmp_path):
    lcmnet.require()
    r, log, forged, out = _bench(tmp_path, "cmd", 7972)
    assert "rc=0" in r.stdout and forged["sent"]["SCRT_CMD"] == 1, r.stdout + log + str(forged)
    emu = json.loads((out / "timing.json").read_text())["emulator_counters"]
    assert emu.get("cmd_seq_jump") == 1 and emu.get("cmd_timeout", 0) == 0, emu
    assert json.loads((out / "metrics.json").read_text())["valid"] is True
    _same_as_offline(out)


@pytest.mark.lcm
def test_one_forged_state_inside_the_window_fails_the_run_named(tmp_path):
    """Inside the window (seq + 999 < W) a forged state is indistinguishable
    from a plant that lost 998 states: the controller takes it and drops the
    genuine states after it as out of order. Lockstep does not answer-fill
    them: the bench waits for the answer to the next state, then stops the
    run, invalid, naming it (never a valid run with zeroed rows).
    docs/PROTOCOL.md: --auth-key refuses the forged state itself."""
    lcmnet.require()
    r, log, forged, out = _bench(tmp_path, "state_in_window", 7974)
    assert forged["sent"]["SCRT_STATE"] == 1, forged
    assert "rc=1" in r.stdout, r.stdout + log
    m = json.loads((out / "metrics.json").read_text())
    assert m["valid"] is False and "did not answer state" in m["invalid_reason"], m["invalid_reason"]
    tr = load_traj(out)
    assert np.all(~tr["cmd_stale"]) and len(tr) < 601  # every row its own answer, up to the stop


@pytest.mark.lcm
def test_commands_racing_the_controller_fail_the_run_named(tmp_path):
    lcmnet.require()
    r, log, forged, out = _bench(tmp_path, "race", 7973)
    assert forged["sent"]["SCRT_CMD"] > 0, forged
    assert "rc=1" in r.stdout, r.stdout + log
    m = json.loads((out / "metrics.json").read_text())
    emu = json.loads((out / "timing.json").read_text())["emulator_counters"]
    assert emu.get("cmd_conflict", 0) > 0, emu
    assert m["valid"] is False and "forged or racing sender" in m["invalid_reason"], m["invalid_reason"]
    # the log alone gives the same verdict (issue 40 item 4: its report said valid before)
    rep = lcmnet.run_cli(["report", str(out / "run.lcmlog"), "--no-plots", "--out", str(tmp_path / "rep")],
                         netns=False)
    assert rep.returncode == 0, rep.stderr
    mr = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert mr["valid"] is False and "forged or racing sender" in mr["invalid_reason"], mr.get("invalid_reason")
    assert json.loads((tmp_path / "rep" / "report.json").read_text())["command_conflicts"] > 0
