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
    lcmnet.require()
    script = tmp_path / "hangs.py"
    script.write_text(HANGS)
    out = tmp_path / "rt"
    r = lcmnet.run_cli(["hil", "paper_fault_free", "--mode", "realtime", "--control-rate", "20", "--duration", "2",
                        "--external", f"{sys.executable} {script}", "--out", str(out), "--no-plots",
                        "--floor", "off"], timeout=120)
    assert r.returncode == 1, r.stderr + r.stdout
    assert "did not keep real time" in r.stderr and "dropped ticks" in r.stderr
    m = json.loads((out / "metrics.json").read_text())
    t = json.loads((out / "timing.json").read_text())
    assert m["valid"] is False and m["invalid_reason"].startswith("did not keep real time")
    assert t["kept_real_time"] is False and t["realtime_limits"]["dropped"] == 0.01
