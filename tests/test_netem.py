"""A lossy link between the controller's and the plant's namespaces
(bench/netem_lab.py; every case, 30 s each: bench/bench_netem.py): both
processes stay up, what each side lost and got twice agrees with the
impairment's configuration within binomial bounds and with the log of its
own side, the log keeps everything, the run keeps its bound."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))

import netem_lab  # noqa: E402

pytestmark = pytest.mark.lcm


def _backend() -> str | None:
    if netem_lab.netem_available() is None:
        return "netem"
    if netem_lab.nft_available() is None:
        return "nft"
    return None


def test_binomial_bound_and_netem_spec():
    assert netem_lab.parse_netem("delay 2ms 1ms loss 5% duplicate 1%") == {
        "loss": 0.05, "duplicate": 0.01, "corrupt": 0.0, "reorder": 0.0, "delay_ms": 2.0, "jitter_ms": 1.0}
    e, tol = netem_lab.binomial_bound(3000, 0.05)
    assert e == 150 and 5 * 11.9 + 2 < tol < 5 * 12 + 2.1
    assert netem_lab.binomial_bound(100, 0.0) == (0.0, 2.0)


@pytest.mark.slow  # ~15-20 s: a 12 s real-time run at 100 Hz across two namespaces
@pytest.mark.skipif(_backend() is None, reason="no tc netem and no nftables egress hook, or no namespaces")
def test_lossy_duplicating_link_is_counted_on_both_sides(tmp_path):
    r = netem_lab.run_case(tmp_path, "loss 5% duplicate 2%", duration=12.0, rate=100.0, port=7735,
                           backend=_backend())
    assert r["controller_alive"]
    c = r["checks"]
    for side in ("to_controller", "to_emulator"):
        assert c[side]["lost_ok"] and c[side]["dup_ok"], (side, c[side], r[side])
    # each process counted what its side's logger received (the same
    # datagrams): the duplicates exactly, up to the window's edges
    for name, pairs in (("controller", c["controller_counters_match_log"]),
                        ("emulator", c["emulator_counters_match_log"])):
        for k, (counted, logged) in pairs.items():
            assert abs(counted - logged) <= max(3, 0.01 * logged), (name, k, counted, logged)
    # the log keeps everything its logger received
    assert all(r["log"].values()), r["log"]
    # a lost state is a step without a fresh one (held command), never a crash;
    # the run keeps its prescribed bound and ends under control
    assert r["stale"]["controller_stale_steps"] >= 0.5 * r["to_controller"]["lost"]
    assert r["result"]["finite"] and r["result"]["first_bound_violation_s"] is None, r["result"]
    assert r["stale"]["ends_normal"]
