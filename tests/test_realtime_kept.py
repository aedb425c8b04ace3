"""A real-time run that did not keep real time says so and is invalid
(issue #25, case 5): RealtimeLimits judged against constructed timing
records, and, deterministically on the bench, a controller that answers the
first states and then hangs (alive, silent): the watchdog's dropped ticks
make the run invalid with the reason, exit 1. One number of SAFE steps:
metrics.json's is the controller's (timing.json controller_safe_steps)."""

from __future__ import annotations

import json
import sys
import textwrap

import numpy as np
import pytest

from sc_rt.logs.timing import RealtimeLimits, realtime_shortfall

import lcmnet


def _timing(**kw):
    t = {"mode": "realtime", "control_rate_hz": 1000.0, "steps": 30000, "rows": 30001, "deadline_misses": 0,
         "stale_states": 0, "dropped": 0, "steps_per_s": 1000.0}
    return {**t, **kw}


def test_limits_against_constructed_records():
    lim = RealtimeLimits()
    assert realtime_shortfall(_timing(), lim) is None
    assert realtime_shortfall(_timing(mode="lockstep", deadline_misses=10**6), lim) is None
    # the run: 886 steps/s at 1 kHz (30 s), 13,194 stale steps, 85 misses, 52 dropped ticks
    why = realtime_shortfall(_timing(steps=26580, rows=30001, stale_states=13194, deadline_misses=85,
                                     dropped=52, steps_per_s=886.0), lim)
    assert why is not None and why.startswith("did not keep real time")
    assert "periods without a step 3421 of 30001" in why  # 11 % of the periods had no step
    assert "deadline misses" not in why and "stale" not in why  # 0.32 % <= 1 %; 49.6 % <= 50 %
    assert realtime_shortfall(_timing(steps=100, rows=101, dropped=2), lim) is None  # the allowance
    assert "dropped ticks 3 of 101" in realtime_shortfall(_timing(steps=100, rows=101, dropped=3), lim)
    assert realtime_shortfall(_timing(deadline_misses=301), lim) is not None  # 1.003 % > 1 %
    assert realtime_shortfall(_timing(deadline_misses=300), lim) is None
    assert "stale states 15001" in realtime_shortfall(_timing(stale_states=15001), lim)


def test_latency_and_stall_limits_against_the_period():
    """Issue 41 item 7, issue 40: "kept real time" judged against the control
    period. The issue's Python law answered 1 % of its states a whole period
    late (p99 10.25 ms at 100 Hz); a plant that stalled 1.5 s was called real
    time. Constructed records, and the counts from a constructed record."""
    lim = RealtimeLimits()
    late = {"answers": 2000, "answers_judged": 1800, "answers_over_period": 0, "ticks_over_period": 0,
            "worst_tick_lateness_periods": 0.3}
    assert realtime_shortfall(_timing(**late), lim) is None
    why = realtime_shortfall(_timing(**{**late, "answers_over_period": 19}), lim)  # 1.06 % > 1 %
    assert why is not None and "answers later than a period 19 of 1800" in why
    assert realtime_shortfall(_timing(**{**late, "answers_over_period": 18}), lim) is None  # 1 %: not beyond
    why = realtime_shortfall(_timing(**{**late, "worst_tick_lateness_periods": 145.0}), lim)  # 1.45 s at 100 Hz
    assert why is not None and "worst tick 145 periods late" in why
    assert realtime_shortfall(_timing(**{**late, "worst_tick_lateness_periods": 25.0}), lim) is None
    assert "ticks later than a period 301 of 30001" in realtime_shortfall(_timing(**{**late,
                                                                                   "ticks_over_period": 301}), lim)


def test_lateness_counts_from_a_record():
    """lateness_counts against numpy on the record's own columns: answers
    before ACQUIRE_S are not judged under the timer (the phase lock's
    acquisition), all are under the event trigger."""
    from sc_rt.logs.timing import ACQUIRE_S, lateness_counts
    from sc_rt.results.record.meta import RunMeta
    from sc_rt.results.record.run import Run
    from sc_rt import load_scenario

    n = 1001
    run = Run.allocate(n, RunMeta.of_scenario(load_scenario("paper_faults"), "hil-realtime", mode="realtime"))
    rate = run.meta.control_rate_hz
    period_us = 1e6 / rate
    t = np.arange(n) / rate
    lat = np.full(n, 0.03 * period_us)
    lat[::7] = np.nan  # held commands: not answers
    late_at = np.array([0.05, 0.5, 1.5, 2.5, 2.6, 9.0]) * 100 / rate
    lat[np.rint(late_at * rate).astype(int)] = 1.05 * period_us  # later than a period
    tick = np.full(n, 0.005 * period_us)
    tick[[400, 401]] = [2.5 * period_us, 1.5 * period_us]
    run["t"][:], run["latency_us"][:], run["tick_lateness_us"][:] = t, lat, tick
    for trigger, since in (("timer", ACQUIRE_S), ("event", 0.0), (None, ACQUIRE_S)):
        c = lateness_counts(run, trigger)
        ok = np.isfinite(lat) & (t >= since)
        assert c["answers_judged"] == ok.sum() and c["answers"] == np.isfinite(lat).sum()
        assert c["answers_over_period"] == (lat[ok] > period_us).sum() == (late_at >= since).sum()
        assert c["ticks_over_period"] == 2 and c["worst_tick_lateness_periods"] == 2.5


HANGS = textwrap.dedent("""
    import os, secrets, time, lcm
    from sc_rt_lcm import plant_state_t, wheel_cmd_t
    P, session, st = os.environ.get("SCRT_PREFIX", ""), secrets.randbits(62), {"n": 0}
    lc = lcm.LCM(os.environ["SCRT_LCM_URL"])
    def on_state(_ch, data):
        s = plant_state_t.decode(data)
        if st["n"] >= 5:
            return  # hung: alive, silent
        c = wheel_cmd_t()
        c.utime, c.seq, c.session, c.state_seq, c.t = int(time.time() * 1e6), st["n"], session, s.seq, s.t
        c.u_cmd, c.u_sat, c.mode = [0.0] * 4, [0.0] * 4, wheel_cmd_t.MODE_NORMAL
        st["n"] += 1
        lc.publish(P + "SCRT_CMD", c.encode())
    lc.subscribe(P + "SCRT_STATE", on_state)
    while True:
        lc.handle()
""")


@pytest.mark.lcm
def test_a_realtime_run_whose_controller_hangs_is_invalid(tmp_path):
    r, out = _realtime_external(tmp_path, HANGS, "20", "2")
    assert "did not keep real time" in r.stderr and "dropped ticks" in r.stderr
    m = json.loads((out / "metrics.json").read_text())
    t = json.loads((out / "timing.json").read_text())
    assert m["valid"] is False and m["invalid_reason"].startswith("did not keep real time")
    assert t["kept_real_time"] is False and t["realtime_limits"]["dropped"] == 0.01
    # the log alone gives the same verdict (issue 40 item 4)
    rm, rt = _report(out, tmp_path / "rep")
    assert rm["valid"] is False and "dropped ticks" in rm["invalid_reason"], rm.get("invalid_reason")
    assert rt["kept_real_time"] is False and rt["realtime_limits_source"] == "the run's start record"


def _realtime_external(tmp_path, script_text, rate, duration, *extra):
    """A real-time hil run of paper_fault_free with the --external controller
    ``script_text``, which must fail (exit 1): (the process, its --out)."""
    lcmnet.require()
    script = tmp_path / "controller.py"
    script.write_text(script_text)
    out = tmp_path / "rt"
    r = lcmnet.run_cli(["hil", "paper_fault_free", "--mode", "realtime", "--control-rate", rate, "--duration",
                        duration, "--external", f"{sys.executable} {script}", "--out", str(out), "--no-plots",
                        "--floor", "off", *extra], timeout=120)
    assert r.returncode == 1, r.stderr + r.stdout
    return r, out


def _report(out, rep):
    """sc-rt report of a run's log: (metrics.json, timing.json)."""
    r = lcmnet.run_cli(["report", str(out / "run.lcmlog"), "--out", str(rep), "--no-plots"], timeout=120)
    assert r.returncode == 0, r.stderr + r.stdout
    return json.loads((rep / "metrics.json").read_text()), json.loads((rep / "timing.json").read_text())


STALLS = textwrap.dedent("""
    import os, secrets, signal, time, lcm
    from sc_rt_lcm import plant_state_t, wheel_cmd_t
    P, session, st = os.environ.get("SCRT_PREFIX", ""), secrets.randbits(62), {"n": 0, "stalled": False}
    lc = lcm.LCM(os.environ["SCRT_LCM_URL"])
    def on_state(_ch, data):
        s = plant_state_t.decode(data)
        c = wheel_cmd_t()
        c.utime, c.seq, c.session, c.state_seq, c.t = int(time.time() * 1e6), st["n"], session, s.seq, s.t
        c.u_cmd, c.u_sat, c.mode = [0.0] * 4, [0.0] * 4, wheel_cmd_t.MODE_NORMAL
        st["n"] += 1
        lc.publish(P + "SCRT_CMD", c.encode())
        if s.t >= 1.0 and not st["stalled"]:  # the fault: the plant's process stops for 1.5 s
            st["stalled"] = True
            os.kill(os.getppid(), signal.SIGSTOP)
            time.sleep(1.5)
            os.kill(os.getppid(), signal.SIGCONT)
    lc.subscribe(P + "SCRT_STATE", on_state)
    while True:
        lc.handle()
""")


@pytest.mark.lcm
def test_a_realtime_run_whose_plant_stalls_is_invalid(tmp_path):
    """Issue 40: a real-time run whose plant process stalled 1.5 s (tick
    lateness up to 1.45 s) was judged to have kept real time. The external
    controller stops the bench's process (the plant emulator) once for at
    least 1.5 s: 150 periods at 100 Hz, the limit 25. The rows the plant
    catches up on the watchdog's zero are dropped ticks (38 % of this short
    run, 0.5 % of the issue's 300 s one): the dropped limit is set aside
    here, so the stall alone has to fail the run."""
    _r, out = _realtime_external(tmp_path, STALLS, "100", "4", "--rt-limits", "dropped=1")
    t = json.loads((out / "timing.json").read_text())
    m = json.loads((out / "metrics.json").read_text())
    assert t["worst_tick_lateness_periods"] >= 140, t  # the stop, measured by the plant's own clock
    assert "worst tick" in m["invalid_reason"] and t["kept_real_time"] is False
    # the log alone: the states' receipt times show the stall, judged by the run's own limits
    rm, rt = _report(out, tmp_path / "rep")
    assert rt["realtime_limits"]["dropped"] == 1.0 and rt["realtime_limits_source"] == "the run's start record"
    assert rt["worst_tick_lateness_periods"] >= 140, rt
    assert rm["valid"] is False and "worst tick" in rm["invalid_reason"], rm.get("invalid_reason")
