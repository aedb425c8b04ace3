"""A law that never returns in its probe (constructed and stepped once at
rest, in a child process: sc_rt.plan.law.probe_law, where a run is planned)
is killed after the probe timeout and refused, named (issue 40, item 7;
docs/LAWS.md): ``sc-rt check`` and the planning of a run no longer hang. The timeout
is set small by SCRT_PROBE_TIMEOUT; the laws loop for ever, so the outcome
does not depend on the machine's speed. Bounded runs: tests/bounded.py."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import psutil
import pytest

from sc_rt.isolate import ChildDied, call_in_child
from sc_rt.plan.run import plan_run
from sc_rt.scenario.schema import ScenarioError

from bounded import forked, sc_rt

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper_fault_free.toml"
PROBE_TIMEOUT_ENV = "SCRT_PROBE_TIMEOUT"  # docs/LAWS.md (sc_rt.isolate)

HUNG = '''
import numpy as np


class HangsInInit:
    def __init__(self, setup):
        while True:
            pass

    def reset(self, inp):
        pass

    def step(self, inp):
        return np.zeros(4)


class HangsInStep:
    def __init__(self, setup):
        pass

    def reset(self, inp):
        pass

    def step(self, inp):
        while True:
            pass
'''


def _no_child_left(before: set[int]) -> None:
    left = [p for p in psutil.Process().children(recursive=True) if p.pid not in before]
    assert left == [], left


def test_call_in_child_kills_a_child_that_does_not_answer_in_time():
    from sc_rt.isolate import ChildTimedOut

    before = {p.pid for p in psutil.Process().children(recursive=True)}
    with pytest.raises(ChildTimedOut, match=r"no answer within 0.2 s: killed") as e:
        call_in_child(signal.pause, timeout=0.2)  # never returns (no signal comes)
    assert isinstance(e.value, ChildDied) and e.value.timeout == 0.2
    _no_child_left(before)
    assert call_in_child(sum, [1, 2, 3], timeout=60) == 6  # an answer in time is the answer
    with pytest.raises(ChildDied, match="signal SIGKILL"):  # and a death is still a death
        call_in_child(lambda: os.kill(os.getpid(), signal.SIGKILL), timeout=60)
    _no_child_left(before)


def test_the_probe_timeout_is_documented_and_set_by_the_environment(monkeypatch):
    from sc_rt import isolate
    from sc_rt.isolate import probe_timeout

    assert isolate.PROBE_TIMEOUT_ENV == PROBE_TIMEOUT_ENV
    monkeypatch.delenv(PROBE_TIMEOUT_ENV, raising=False)
    assert probe_timeout() == 30.0
    assert "30 s" in (ROOT / "docs" / "LAWS.md").read_text() and PROBE_TIMEOUT_ENV in (
        ROOT / "docs" / "LAWS.md").read_text()
    monkeypatch.setenv(PROBE_TIMEOUT_ENV, "0.25")
    assert probe_timeout() == 0.25
    for bad in ("0", "-1", "nan", "inf", "abc"):
        monkeypatch.setenv(PROBE_TIMEOUT_ENV, bad)
        with pytest.raises(ValueError, match=f"^{PROBE_TIMEOUT_ENV}={bad}: must be a number of seconds > 0$"):
            probe_timeout()


@pytest.mark.parametrize("cls", ["HangsInInit", "HangsInStep"])
def test_planning_a_run_whose_law_never_returns_is_an_error_naming_the_law(tmp_path, monkeypatch, cls):
    (tmp_path / "hung.py").write_text(HUNG)
    scn = tmp_path / "s.toml"
    scn.write_text(PAPER.read_text().replace('controller = "dsc-ppc"', f'controller = "python:hung.py:{cls}"', 1))
    monkeypatch.setenv(PROBE_TIMEOUT_ENV, "0.2")

    def load():  # in a child of its own (see _forked): the issues, and whether the probe left a process
        try:
            plan_run(scn)
        except ScenarioError as e:
            return [(i.key, i.message) for i in e.errors], psutil.Process().children(recursive=True) == []
        return "loaded", None

    [(key, message)], none_left = forked(load, timeout=60)
    assert key == "run.controller" and f"hung.py:{cls}" in message, message
    assert "did not return within 0.2 s when constructed and probed at rest" in message, message
    assert PROBE_TIMEOUT_ENV in message and none_left


@pytest.mark.parametrize("cmd", ["check", "sim", "montecarlo"])
def test_a_command_whose_law_never_returns_in_its_probe_ends_with_exit_2(tmp_path, cmd):
    (tmp_path / "hung.py").write_text(HUNG)
    args = {"check": ["check", "s.toml"], "sim": ["sim", "paper_fault_free", "--law", "hung.py:HangsInStep"],
            "montecarlo": ["montecarlo", "paper_fault_free", "--law", "hung.py:HangsInInit", "--runs", "2",
                           "--workers", "2"]}[cmd]
    (tmp_path / "s.toml").write_text(PAPER.read_text().replace('controller = "dsc-ppc"',
                                                               'controller = "python:hung.py:HangsInInit"', 1))
    rc, lines, out = sc_rt([*args, "--out", "out"] if cmd != "check" else args, tmp_path,
                           env={PROBE_TIMEOUT_ENV: "0.2"})
    text = "\n".join(lines) + out
    assert rc == 2 and "did not return within 0.2 s when constructed and probed at rest" in text, text
    assert "hung.py:Hangs" in text, text
    if cmd != "check":
        assert len(lines) == 1, lines
