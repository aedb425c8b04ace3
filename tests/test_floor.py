"""The bench floor (sc-rt floor, sc-rt hil --self-test), the controller's
trigger modes and the null law: structure and sanity, never speed."""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest

from sc_rt.hil.floor import FLOOR_SERIES, TimingSetup, compare_to_floor

import lcmnet
from trajcmp import load_traj


def _cli(args, cache, timeout=300):
    env = {**os.environ, "SCRT_FLOOR_CACHE": str(cache)}
    return lcmnet.run([sys.executable, "-m", "sc_rt.cli", *args], timeout=timeout, env=env)


def _sane(p):
    assert set(p) >= {"p50", "p99", "max"}
    assert 0 <= p["p50"] <= p["p99"] <= p["max"]


def test_timing_setup_and_the_floor_comparison():
    with pytest.raises(ValueError, match="trigger"):
        TimingSetup(trigger="sometimes")
    s = TimingSetup(trigger="event", controller_cpu=1, null_law=True)
    assert s.controller_args() == ["--trigger", "event", "--cpu", "1", "--null-law"]
    # the trigger is always named: the controller binary's own default never decides
    assert TimingSetup().controller_args() == ["--trigger", "event"]
    assert TimingSetup(trigger="timer").controller_args() == ["--trigger", "timer"]
    assert s.key() != TimingSetup().key()
    timing = {"state_to_cmd_latency_us": {"p50": 120.0, "p99": 300.0, "max": 900.0}}
    floor = {"latency_us": {"p50": 80.0, "p99": 200.0, "max": 500.0}, "source": "cached"}
    c = compare_to_floor(timing, floor)
    assert c["added_us"]["latency_us"] == {"p50": 40.0, "p99": 100.0}
    assert c["added_us"]["tick_lateness_us"] == {"p50": None, "p99": None}
    assert c["line"].startswith("bench floor p99 200 us; this controller added 100 us")
    assert "not like for like" not in c["line"]
    # a floor that ran under another scheduler than the run says so
    mixed = compare_to_floor({**timing, "scheduler": "SCHED_FIFO 80 + mlockall"},
                             {**floor, "scheduler": "SCHED_OTHER (SCHED_FIFO denied)"})
    assert mixed["line"].endswith("(the floor ran SCHED_OTHER (SCHED_FIFO denied), this run SCHED_FIFO 80 + "
                                  "mlockall: not like for like)")
    same = compare_to_floor({**timing, "scheduler": "SCHED_FIFO 80 + mlockall"},
                            {**floor, "scheduler": "SCHED_FIFO 80 + mlockall, CPU 1"})
    assert "not like for like" not in same["line"]


@pytest.mark.lcm
def test_floor_of_an_event_triggered_null_controller(tmp_path):
    lcmnet.require()
    r = _cli(["floor", "--json", "--control-rate", "200", "--duration", "1", "--trigger", "event",
              "--rtt-count", "200"], tmp_path)
    assert r.returncode == 0, r.stderr + r.stdout
    f = json.loads(r.stdout)
    assert f["source"] == "measured before the run" and f["mode"] == "realtime" and f["control_rate_hz"] == 200
    for s in FLOOR_SERIES:
        _sane(f[s])
    _sane(f["lcm_rtt_us"])
    assert f["lcm_rtt_us"]["p50"] > 0 and f["lcm_rtt_n"] == 200
    assert f["latency_us"]["p50"] > 0
    assert f["rows"] == 201  # 1 s at 200 Hz: states 0..200
    # event-triggered: one step per state that arrived, each on a new state
    assert 0 < f["steps"] <= f["rows"] and f["stale_states"] == 0
    assert f["wake_lateness_us"]["max"] == 0.0  # it steps on the arrival: no timer to be late for
    assert 0.0 <= f["fresh_fraction"] <= 1.0
    assert f["setup"]["trigger"] == "event" and f["setup"]["null_law"] is False  # the run's setup, cached
    cached = list(tmp_path.glob("floor-*-realtime-200hz-fifo-event-*.json"))  # real-time priority: the default
    assert len(cached) == 1 and json.loads(cached[0].read_text())["steps"] == f["steps"]


@pytest.mark.lcm
def test_self_test_prints_the_floor_table(tmp_path):
    lcmnet.require()
    r = _cli(["hil", "paper_faults", "--self-test", "--control-rate", "100", "--duration", "1"], tmp_path)
    assert r.returncode == 0, r.stderr + r.stdout
    assert "bench floor:" in r.stdout and "realtime 100 Hz, event trigger" in r.stdout  # the default
    for name in ("LCM round trip", "state-to-command latency", "emulator tick lateness"):
        assert name in r.stdout
    assert list(tmp_path.glob("floor-*-realtime-100hz-fifo-event-*.json"))


@pytest.mark.lcm
@pytest.mark.slow
def test_a_realtime_run_carries_its_cached_floor_and_the_null_law_answers_zero(tmp_path):
    lcmnet.require()
    cache = tmp_path / "cache"
    r = _cli(["floor", "--control-rate", "100", "--duration", "1", "--rtt-count", "100"], cache)
    assert r.returncode == 0, r.stderr + r.stdout
    out = tmp_path / "run"
    r = _cli(["hil", "paper_faults", "--mode", "realtime", "--control-rate", "100", "--duration", "1",
              "--floor", "cached", "--out", str(out)], cache)
    assert r.returncode == 0, r.stderr + r.stdout
    t = json.loads((out / "timing.json").read_text())
    assert t["floor"]["source"] == "cached" and t["floor"]["control_rate_hz"] == 100
    assert t["over_floor"]["line"].startswith("bench floor p99 ")
    assert "this controller added" in r.stdout
    # the defaults (issue #31): the event trigger, and real-time priority asked
    # for (granted, or the refusal named: the output says which)
    assert t["trigger"] == "event" and t["null_law"] is False
    assert t["scheduler"].startswith("SCHED_FIFO 80") or "SCHED_FIFO denied" in t["scheduler"], t["scheduler"]
    assert f"scheduler {t['scheduler']}" in r.stdout
    assert (out / "timing.png").stat().st_size > 0
    # the floor's own controller: zero commands, the same messages
    null = tmp_path / "null"
    code = (f"from pathlib import Path; from sc_rt.hil.runner import run_hil; "
            f"from sc_rt.plan import Outputs, Timing, TimingSetup, plan_run; "
            f"run_hil(plan_run('paper_faults', engine='bench', duration=2.0, outputs=Outputs(out=Path({str(null)!r}), "
            f"plots=False), timing=Timing(mode='lockstep', setup=TimingSetup(null_law=True))))")
    r = lcmnet.run([sys.executable, "-c", code], timeout=300)
    assert r.returncode == 0, r.stderr + r.stdout
    z = load_traj(null)
    assert len(z["u_cmd"]) == 21 and not np.any(z["u_cmd"]) and not np.any(z["cmd_stale"])
    s = json.loads((null / "controller_summary.json").read_text())
    assert s["null_law"] is True and s["steps"] == 21


def test_the_emulators_thread_setup_is_given_back():
    import gc

    from sc_rt.emulator.rtproc import RealtimeThread

    cpus = os.sched_getaffinity(0)
    was = gc.isenabled()
    with RealtimeThread(freeze_gc=True, cpu=min(cpus)) as rt:
        assert not gc.isenabled() and gc.get_freeze_count() > 0
        assert os.sched_getaffinity(0) == {min(cpus)}
        assert "gc frozen" in rt.description and f"CPU {min(cpus)}" in rt.description
    assert gc.isenabled() == was and gc.get_freeze_count() == 0
    assert os.sched_getaffinity(0) == cpus
    assert os.sched_getscheduler(0) == os.SCHED_OTHER
