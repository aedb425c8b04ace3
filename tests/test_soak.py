"""A 2-minute soak (bench/soak.py; 30 minutes there): real time at 100 Hz,
both processes' memory flat after the warm-up (beyond what each records per
step by design), no message lost between the processes and the log."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

import lcmnet

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))

import soak  # noqa: E402

pytestmark = pytest.mark.lcm


@pytest.mark.slow  # ~2.5 min of real time
def test_two_minute_soak_memory_flat_and_no_lost_log_events(tmp_path):
    lcmnet.require()
    r = soak.soak(2.0, 100.0, tmp_path / "soak", sample_s=2.0, port=7762)
    assert r["rows"] == 12001
    # memory after the warm-up: the controller flat (<= 1 MB beyond its 24 B
    # of samples per step); the emulator, which keeps the run in memory until
    # it writes it, grows linearly within its per-row budget (bench/soak.py)
    m = r["memory"]
    assert set(m) == {"emulator", "controller"}, m
    assert m["controller"]["flat"], m["controller"]
    assert m["emulator"]["within_budget"] and m["emulator"]["linear"], m["emulator"]
    # zero lost log events: every state, guidance and truth the emulator sent
    # (one per row) and every command and status the controller sent (one
    # per step) is in the log
    assert r["lost_log_events"] == 0, r["log"]
    assert r["log"]["SCRT_CMD"]["sent"] == r["controller_steps"] > 0.9 * r["rows"]
