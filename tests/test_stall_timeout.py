"""A law that never returns, in a contained run (sim, compare, montecarlo:
a plugin's or a Python law's run in a child, sc_rt.isolate), is killed once
no step has returned for the stall timeout, and the run fails naming the
law and the last time it reached (issue 40 item 7): before, ``sc-rt sim``
with such a law hung for ever. The laws loop for ever, so the outcome does
not depend on the machine's speed; a run that makes progress is never
stopped, whatever its length."""

from __future__ import annotations

import mmap
import time

import numpy as np
import psutil
import pytest

from sc_rt import isolate
from sc_rt.isolate import ChildDied, ChildStalled, beat, beat_done, call_in_child

from bounded import sc_rt

HUNG = '''
import numpy as np


class HangsFromHalfASecond:
    def __init__(self, setup):
        self.B_pinv = setup.model.B_pinv

    def reset(self, inp):
        pass

    def step(self, inp):
        while inp.t >= 0.5:
            pass
        return -self.B_pinv @ (0.05 * inp.e.sigma_BD + 0.24 * inp.e.omega_BD_B)
'''


def _beats_then_hangs(n: int) -> None:
    for k in range(n):
        beat(k * 0.1)
    while True:
        time.sleep(1.0)


def _beats_many(n: int) -> int:
    for k in range(n):
        beat(float(k))
    return n


def _done_then_works(seconds: float) -> str:
    beat(0.0)
    beat_done()  # the steps are over: the rest (the metrics, a hand-over) is not watched
    time.sleep(seconds)
    return "answered"


def test_a_child_that_stops_beating_is_killed_naming_its_last_time():
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    with pytest.raises(ChildStalled, match=r"no step returned for 0.3 s \(after t = 0.4 s; SCRT_STALL_TIMEOUT") as e:
        call_in_child(_beats_then_hangs, 5, stall=0.3)
    assert isinstance(e.value, ChildDied) and e.value.t == pytest.approx(0.4)
    with pytest.raises(ChildStalled, match=r"before its first step"):
        call_in_child(_beats_then_hangs, 0, stall=0.3)
    assert {p.pid for p in psutil.Process().children(recursive=True)} == before


def test_progress_and_the_work_after_the_steps_are_never_stopped():
    assert call_in_child(_beats_many, 2_000_000, stall=5.0) == 2_000_000
    assert call_in_child(_done_then_works, 1.0, stall=0.2) == "answered"
    assert not isolate.beating()  # this process is watched by nobody: beat is a no-op
    beat(1.0)


def test_the_cpp_loop_in_parts_equals_the_loop_in_one_call(monkeypatch):
    """A contained run on the C++ engine runs its loop BEAT_ROWS rows a
    call (so that a plugin's steps beat): the same numbers, to the bit, as
    the loop in one call (two paths of the bindings)."""
    from sc_rt.scenario.reader import load_scenario
    from sc_rt.sim import engines

    scn = load_scenario("paper_faults")
    one = engines.simulate(scn, engine="cpp", duration=60.0)
    shared = mmap.mmap(-1, 16)
    monkeypatch.setitem(isolate._BEAT, "map", shared)
    monkeypatch.setattr(engines, "BEAT_ROWS", 97)  # parts that do not divide the run
    parts = engines.simulate(scn, engine="cpp", duration=60.0)
    assert isolate._BEAT_LAYOUT.unpack_from(shared, 0)[0] == -1  # beat_done after the steps
    assert len(one) == len(parts) == 601
    for name in one.trajectory:
        np.testing.assert_array_equal(one[name], parts[name], err_msg=name)


@pytest.mark.parametrize("engine", ["python", "cpp"])
def test_sim_of_a_python_law_that_never_returns_fails_naming_it(tmp_path, engine):
    (tmp_path / "hung.py").write_text(HUNG)
    rc, lines, _ = sc_rt(["sim", "paper_fault_free", "--law", "hung.py:HangsFromHalfASecond", "--engine", engine,
                          "--duration", "5", "--out", "out", "--no-plots"], tmp_path,
                         env={"SCRT_STALL_TIMEOUT": "0.5"})
    assert rc == 1, lines
    assert lines[-1].startswith("sc-rt sim: FAILED: the law python:") and "hung.py:HangsFromHalfASecond hung: " \
        "no step returned for 0.5 s (after t = 0.4 s" in lines[-1], lines


def test_a_plugin_that_never_returns_fails_its_run_on_the_cpp_engine(tmp_path, plugins):
    rc, lines, _ = sc_rt(["sim", "paper_fault_free", "--law", f"plugin:{plugins['hangs']}", "--engine", "cpp",
                          "--duration", "5", "--out", "out", "--no-plots"], tmp_path,
                         env={"SCRT_STALL_TIMEOUT": "1"})
    assert rc == 1 and f"the law plugin:{plugins['hangs']} hung: no step returned for 1 s" in lines[-1], lines


@pytest.mark.parametrize("bad", ["0", "-2", "nan", "soon"])
def test_a_bad_stall_timeout_is_refused_before_anything_starts(tmp_path, bad):
    rc, lines, _ = sc_rt(["sim", "paper_fault_free", "--out", "out"], tmp_path, env={"SCRT_STALL_TIMEOUT": bad})
    assert rc == 2 and lines == [f"sc-rt sim: SCRT_STALL_TIMEOUT={bad}: must be a number of seconds > 0"], lines
    assert not (tmp_path / "out").exists()
