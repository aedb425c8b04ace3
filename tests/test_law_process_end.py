"""A Python law that ends its process, crashes it or never returns cannot
take the command with it (issue 40 item 7): like a plugin, it runs in a
child of its own (sc_rt.sim.isolated), so that

- ``os._exit(0)`` or a segfault in its step gives ``sc-rt sim`` one line
  naming how, and exit 1 (before: exit 0 and no output, or exit -11 and no
  message);
- a campaign whose law segfaults in a run records that run as crashed and
  ends with its summary (before: "process pool is not usable anymore",
  exit 2, no montecarlo.json);
- SIGINT or SIGTERM to ``sc-rt sim`` while the law never returns ends the
  command with 130 / 143 within the interrupt grace (before: ignored);
- a law that hangs mid-step in every run of a campaign: each run is killed
  after the stall timeout and recorded as ``hung`` (before: "crashed its
  run's process"), the campaign and its ``--resume`` go on; ``compare``
  runs the other laws and says which one hung."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from sc_rt.isolate import INTERRUPT_GRACE_S

import lcmnet
from test_interrupt import SAYS

PY = sys.executable

LAW = '''
import ctypes
import os

import numpy as np


class Ends:
    name = "ends"

    def __init__(self, setup):
        pass

    def reset(self, inp):
        pass

    def step(self, inp):
        if inp.t >= 1.0:
            {action}
        return np.zeros(4)
'''

ACTIONS = {"exit": "os._exit(0)", "segfault": "ctypes.string_at(0)", "hang": "while True: pass"}


def _law(tmp_path, kind: str) -> str:
    f = tmp_path / f"{kind}.py"
    f.write_text(LAW.replace("{action}", ACTIONS[kind]))
    return f"{f}:Ends"


@pytest.mark.parametrize("kind, how", [("exit", "exit code 0"), ("segfault", "signal SIGSEGV")])
def test_a_python_law_ending_its_process_fails_sim_in_one_line(tmp_path, kind, how):
    r = subprocess.run([PY, "-m", "sc_rt.cli", "sim", "paper_fault_free", "--engine", "cpp", "--duration", "5",
                        "--law", _law(tmp_path, kind), "--out", str(tmp_path / "o"), "--no-plots"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 1, (r.returncode, r.stderr)
    lines = [x for x in r.stderr.strip().splitlines() if "FAILED" in x]
    assert len(lines) == 1 and how in lines[0], r.stderr


def test_a_campaign_survives_a_python_law_that_segfaults(tmp_path):
    out = tmp_path / "mc"
    r = subprocess.run([PY, "-m", "sc_rt.cli", "montecarlo", "paper_fault_free", "--runs", "3", "--workers", "2",
                        "--law", _law(tmp_path, "segfault"), "--out", str(out)],
                       capture_output=True, text=True, timeout=600)
    assert (out / "montecarlo.json").exists(), r.stderr
    s = json.loads((out / "montecarlo.json").read_text())
    assert s["status"].get("crashed") == 3, s["status"]
    assert "crashed its run's process in 3 of 3 runs" in r.stderr, r.stderr


@pytest.mark.parametrize("sig, code", [("INT", 130), ("TERM", 143)])
def test_an_interrupt_ends_sim_while_its_python_law_never_returns(tmp_path, sig, code):
    law = _law(tmp_path, "hang")
    started = SAYS.format(f=tmp_path / "e.txt", t="rows ...")
    script = f"""
{PY} -m sc_rt.cli sim paper_fault_free --engine cpp --duration 5 --law {law} --out {tmp_path}/o --no-plots \
    > {tmp_path}/o.txt 2> {tmp_path}/e.txt &
P=$!
{started}
kill -{sig} $P
wait $P
echo "rc=$?"
"""
    r = lcmnet.run_script(script, timeout=120 + 2 * INTERRUPT_GRACE_S)
    err = (tmp_path / "e.txt").read_text()
    assert f"rc={code}" in r.stdout, r.stdout + err
    assert "STOPPED" in err and "did not stop within" in err, err


def test_a_campaign_goes_on_past_a_law_that_hangs_mid_step_and_resumes(tmp_path):
    """Every run's law loops for ever from t = 1 s: each run is killed after
    the stall timeout and recorded as hung (not crashed), the campaign ends
    with its summary, and --resume runs the new ids the same way."""
    out = tmp_path / "mc"
    env = {**os.environ, "SCRT_STALL_TIMEOUT": "1"}
    args = [PY, "-m", "sc_rt.cli", "montecarlo", "paper_fault_free", "--workers", "2",
            "--law", _law(tmp_path, "hang"), "--out", str(out)]
    r = subprocess.run(args + ["--runs", "2"], capture_output=True, text=True, timeout=600, env=env)
    s = json.loads((out / "montecarlo.json").read_text())
    assert s["status"].get("hung") == 2 and not s["status"].get("crashed"), (s["status"], r.stderr)
    assert "the law hung (no step within SCRT_STALL_TIMEOUT; killed) in 2 of 2 runs" in r.stderr, r.stderr
    r = subprocess.run(args + ["--runs", "3", "--resume"], capture_output=True, text=True, timeout=600, env=env)
    s = json.loads((out / "montecarlo.json").read_text())
    assert s["runs"] == 3 and s["status"].get("hung") == 3, (s, r.stderr)
    assert "the law hung (no step within SCRT_STALL_TIMEOUT; killed) in 3 of 3 runs" in r.stderr, r.stderr


def test_compare_goes_on_past_a_law_that_hangs_mid_step(tmp_path):
    out = tmp_path / "cmp"
    r = subprocess.run([PY, "-m", "sc_rt.cli", "compare", "paper_fault_free", "--duration", "3", "--law",
                        _law(tmp_path, "hang"), "--law", "pd", "--out", str(out)], capture_output=True, text=True,
                       timeout=600, env={**os.environ, "SCRT_STALL_TIMEOUT": "1"})
    assert r.returncode == 1 and "pd done" in r.stderr, r.stderr  # a failed run fails the command; the rest ran
    rows = {row["law"]: row for row in json.loads((out / "compare.json").read_text())["rows"]}
    hung = [row for law, row in rows.items() if law != "pd"]
    assert len(hung) == 1 and hung[0]["valid"] is False, rows
    assert "hung: no step returned for 1 s (after t = 0.9" in hung[0]["invalid_reason"], hung[0]
    assert rows["pd"]["valid"] is True
