"""A Python law in real time does what it is told (issue 41 item 7):
``sc-rt hil --law file.py:Class --mode realtime --trigger event
--realtime-priority`` runs ``sc-rt controller`` event-triggered (a step on
each state's arrival: it never waits for a deadline, so every step's wake
lateness is exactly 0) at the priority it asked for (SCHED_FIFO, or
SCHED_OTHER with the refusal said), and timing.json says the trigger that
ran, the same in ``trigger`` and in ``timing_setup.trigger``. Before, it
ran on its timer at SCHED_OTHER and timing.json said "event" and "timer".

The real-time runs are judged with every real-time limit at 1 (a loaded
machine keeps them valid): what is checked is what the controller did, not
how fast the machine is."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sc_rt.hil.bench_end import run_trigger
from sc_rt.hil.external import python_controller_command
from sc_rt.hil.floor import TimingSetup
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
PD_SPEC = str(ROOT / "examples" / "python_laws" / "pd.py") + ":PythonPD"
LOOSE = "misses=1,skipped=1,dropped=1,stale=1"


def test_the_trigger_timing_json_states_is_the_one_that_ran():
    event, timer = TimingSetup(trigger="event"), TimingSetup(trigger="timer")
    assert run_trigger({"trigger": "event"}, event, told=True) == ("event", None)
    assert run_trigger({}, timer, told=True) == ("timer", None)  # told, and says nothing: what it was told
    assert run_trigger({}, event, told=False) == (None, None)  # --external: not told, says nothing: unknown
    assert run_trigger({"trigger": "timer"}, event, told=False) == ("timer", None)  # its own, said
    assert run_trigger({"trigger": "timer"}, event, told=True) == ("timer", "event")  # told, ran another
    # the Python law's controller is told what sc-rt-controller is
    cmd = python_controller_command(PD_SPEC, True, "event", 1)
    assert " --trigger event" in cmd and " --realtime-priority" in cmd and " --cpu 1" in cmd
    assert " --trigger timer" in python_controller_command(PD_SPEC, False, "timer")


@pytest.mark.lcm
@pytest.mark.slow  # two 3 s real-time runs
@pytest.mark.parametrize("trigger", ["event", "timer"])
def test_a_python_law_in_real_time_runs_the_trigger_and_priority_it_is_given(tmp_path, trigger):
    import lcmnet

    lcmnet.require()
    out = tmp_path / trigger
    r = lcmnet.run_cli(["hil", "paper_faults", "--mode", "realtime", "--control-rate", "20", "--duration", "3",
                        "--law", PD_SPEC, "--trigger", trigger, "--realtime-priority", "--floor", "off",
                        "--rt-limits", LOOSE, "--out", str(out), "--no-plots"], timeout=120)
    assert r.returncode == 0, r.stderr + r.stdout
    s = json.loads((out / "controller_summary.json").read_text())
    t = json.loads((out / "timing.json").read_text())
    # the trigger: the one asked for, the same everywhere timing.json says it
    assert s["trigger"] == t["trigger"] == t["timing_setup"]["trigger"] == trigger and "trigger_asked" not in t
    # the priority: asked for (FIFO, or FIFO refused and said), and timing.json reports what it got
    assert s["scheduler"].startswith(("SCHED_FIFO 80", "SCHED_OTHER (SCHED_FIFO denied)")), s["scheduler"]
    assert t["scheduler"] == s["scheduler"]
    assert s["steps"] > 0 and s["law"] == "python-pd"
    late = load_traj(out)["wake_lateness_us"]
    late = late[np.isfinite(late)]
    assert late.size > 0
    if trigger == "event":  # each step at its state's arrival: no deadline to be late for
        assert s["wake_lateness_us"]["max"] == 0.0 and np.all(late == 0.0)
    else:  # its own clock: it wakes after each deadline
        assert s["wake_lateness_us"]["max"] > 0.0
