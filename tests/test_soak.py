"""A 2-minute soak (bench/soak.py; 30 minutes there): real time at 100 Hz,
both processes' memory flat after the warm-up (<= 1 MB; the controller keeps
fixed-size histograms, the emulator preallocates its run), no message lost
between the processes and the log."""

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
    # memory after the warm-up, until the run ends: the controller flat
    # (<= 1 MB: its statistics are fixed-size histograms); the emulator, which
    # allocates and touches what it keeps per row at start, flat (<= 1 MB)
    m = r["memory"]
    # (an empty dict: fewer than 3 RSS samples of both processes after the
    # warm-up; the samples say which process was missing)
    assert set(m) == {"emulator", "controller"}, [s for s in r["samples"] if s[1] and s[2]][-5:]
    assert m["controller"]["flat"] and m["controller"]["unexplained_kb"] <= 1024, m["controller"]
    assert m["emulator"]["flat"] and m["emulator"]["growth_kb"] <= 1024, m["emulator"]
    assert m["emulator"]["span_s"] > 60, m["emulator"]  # the samples cover most of the run
    # zero lost log events: every state, guidance and truth the emulator sent
    # (one per row) and every command and status the controller sent (one
    # per step) is in the log
    assert r["lost_log_events"] == 0, r["log"]
    assert r["log"]["SCRT_CMD"]["sent"] == r["controller_steps"] > 0.9 * r["rows"]
