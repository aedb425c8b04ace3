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
  command with 130 / 143 within the interrupt grace (before: ignored)."""

from __future__ import annotations

import json
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
