"""Bench isolation: two benches started on one LCM URL refuse to mix
(emulator/collision.py); the policy itself, without a bus."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

import pytest

from sc_rt.emulator.collision import COLLISION_MESSAGES, CollisionGuard
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate

import lcmnet
from trajcmp import compared_fields, load_traj

ROOT = Path(__file__).resolve().parent.parent
HERE = Path(__file__).resolve().parent
PY = shlex.quote(sys.executable)


def test_guard_tells_a_second_bench_from_strays_and_a_restarted_peer():
    g = CollisionGuard("udpm://x", "", plant_session=1, alive_s=0.5)
    s = 10**9
    # a fuzzer: a new session per message, never a run
    for i in range(1000):
        assert g.controller_msg(1000 + i, i, ours=7, ours_last_ns=0, now_ns=1) is None
        assert g.plant_state(5000 + i, i, 7) is None
    # our own states come back: never a collision
    for i in range(100):
        assert g.plant_state(1, i, 7) is None
    # replays and out-of-order messages of one session restart its run
    for i in range(5 * COLLISION_MESSAGES):
        assert g.controller_msg(42, i % 3, ours=7, ours_last_ns=0, now_ns=1) is None
    # a controller that answers while ours has been silent longer than alive_s:
    # a restarted controller (adopted by the emulator), not a collision
    for i in range(5 * COLLISION_MESSAGES):
        assert g.controller_msg(43, i, ours=7, ours_last_ns=0, now_ns=s) is None
    # a second controller while ours is alive: a collision at the threshold
    for i in range(COLLISION_MESSAGES - 1):
        assert g.controller_msg(44, i, ours=7, ours_last_ns=s, now_ns=s + 1) is None
    why = g.controller_msg(44, COLLISION_MESSAGES, ours=7, ours_last_ns=s, now_ns=s + 1)
    assert why and "0x2c" in why and "0x7" in why and "0x1" in why and "udpm://x" in why
    assert g.foreign == {"controller": 44}
    # another plant: a collision once it keeps publishing in order
    g2 = CollisionGuard("udpm://y", "P_", plant_session=1, alive_s=0.5)
    reasons = [g2.plant_state(99, i, None) for i in range(COLLISION_MESSAGES)]
    assert reasons[:-1] == [None] * (COLLISION_MESSAGES - 1)
    assert "another plant (session 0x63)" in reasons[-1] and "P_SCRT_STATE" in reasons[-1]


@pytest.mark.lcm
@pytest.mark.slow  # ~10-20 s: two benches, one of them stopped early
def test_two_benches_on_one_url_refuse_to_mix(tmp_path):
    lcmnet.require()
    url = "udpm://239.255.76.67:7721?ttl=0&recv_buf_size=4194304"
    a, b = tmp_path / "a", tmp_path / "b"
    wait = f"{PY} {shlex.quote(str(HERE / 'buswait.py'))} '{url}'"
    # B starts once A's loop runs (an event, not a sleep); A's run is long
    # enough to be running still when B's controller and emulator come up
    script = f"""
{PY} -m sc_rt.cli hil scenarios/paper_faults.toml --duration 3000 --no-plots --out {a} \\
    --lcm-url '{url}' > {tmp_path}/a.out 2> {tmp_path}/a.err &
A=$!
SCRT_WAIT_PID=$A {wait} cmd 120 > /dev/null || exit 3
{PY} -m sc_rt.cli hil scenarios/paper_fault_free.toml --duration 300 --no-plots --out {b} \\
    --lcm-url '{url}' > {tmp_path}/b.out 2> {tmp_path}/b.err
echo $? > {tmp_path}/b.rc
wait $A
echo $? > {tmp_path}/a.rc
"""
    r = lcmnet.run_script(script, timeout=400)
    assert r.returncode == 0, r.stderr
    rc = {k: int((tmp_path / f"{k}.rc").read_text()) for k in "ab"}
    err = {k: (tmp_path / f"{k}.err").read_text() for k in "ab"}
    # the first bench hears the second bench's controller (or plant) and refuses:
    # exit 1, one line naming both sessions and the URL, metrics marked invalid
    assert rc["a"] == 1, (rc, err["a"][-2000:])
    ma = json.loads((a / "metrics.json").read_text())
    assert ma["valid"] is False and ma["partial"] is True, ma
    assert "bench collision on udpm://239.255.76.67:7721" in ma["invalid_reason"]
    assert f"{ma['plant_session']:#x}" in err["a"] and f"{ma['controller_session']:#x}" in err["a"]
    assert "another controller (session 0x" in err["a"] or "another plant (session 0x" in err["a"]
    assert "STOPPED" in err["a"] and "bench collision" in err["a"]
    timing = json.loads((a / "timing.json").read_text())
    assert timing["emulator_counters"]["bench_collision"] == 1
    # the second bench either refuses too, or (when the first had already
    # stopped before it listened) ran alone: then its run is complete, valid,
    # and bit-identical to the offline run: never a mixed run marked valid
    mb = json.loads((b / "metrics.json").read_text())
    if rc["b"] != 0:
        assert rc["b"] == 1 and mb["valid"] is False and "bench collision" in err["b"], err["b"][-2000:]
    else:
        assert mb["valid"] is True and "partial" not in mb, mb
        sim = simulate(load_scenario(ROOT / "scenarios/paper_fault_free.toml"), engine="python", duration=300)
        compared_fields(load_traj(b), sim)
    assert mb["plant_session"] != ma["plant_session"]
