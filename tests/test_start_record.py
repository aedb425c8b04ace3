"""The run's own mode, written down (issue #25, case 6): sc-rt hil writes a
start record into the log (SCRT_HIL_START: scenario, mode, trigger, rate,
the law's identity, run id) and sc-rt report reads it instead of guessing
from the wake lateness. Before, an event-triggered real-time run was
reported as lockstep (its lateness is all 0) and a lockstep run of a
status-less external controller as real time."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from sc_rt.wire.startrec import start_record

import lcmnet

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "external_controller" / "qfb_controller.py"
pytestmark = pytest.mark.lcm


def test_start_record_parsing():
    rec = {"sc_rt_start": 1, "mode": "realtime", "trigger": "event"}
    assert start_record([(0, 0, "SCRT_HIL_START", b"paper_faults"),
                         (1, 0, "SCRT_HIL_START", json.dumps(rec).encode())]) == rec
    assert start_record([(0, 0, "SCRT_HIL_START", b"paper_faults")]) is None  # an older log
    assert start_record([(0, 0, "SCRT_HIL_START", b'{"mode": "x"}')]) is None  # not ours


def _hil_then_report(tmp_path: Path, *args: str) -> tuple[dict, dict, dict]:
    lcmnet.require()
    out = tmp_path / "run"
    r = lcmnet.run_cli(["hil", "paper_fault_free", "--duration", "2", "--control-rate", "20", "--out", str(out),
                        "--no-plots", "--floor", "off", *args], timeout=180)
    assert r.returncode == 0, r.stderr + r.stdout
    rep = tmp_path / "rep"
    r = lcmnet.run_cli(["report", str(out / "run.lcmlog"), "--out", str(rep), "--no-plots"], netns=False)
    assert r.returncode == 0, r.stderr + r.stdout
    return (json.loads((rep / "report.json").read_text()), json.loads((rep / "timing.json").read_text()),
            json.loads((rep / "metrics.json").read_text()))


@pytest.mark.slow
@pytest.mark.parametrize("trigger", ["event", "timer"])
def test_report_labels_real_time_runs_by_their_trigger(tmp_path, trigger):
    rep, timing, _m = _hil_then_report(tmp_path, "--mode", "realtime", "--trigger", trigger)
    assert rep["mode"] == "realtime" and rep["mode_source"] == "the run's start record"
    assert timing["mode"] == "realtime" and timing["trigger"] == trigger
    assert rep["start"]["control_rate_hz"] == 20.0 and rep["start"]["law"]["name"] == "dsc-ppc"


def test_report_labels_a_lockstep_run_of_a_statusless_external_controller(tmp_path):
    rep, timing, m = _hil_then_report(tmp_path, "--mode", "lockstep", "--external",
                                      f"{sys.executable} {EXAMPLE}")
    assert rep["mode"] == "lockstep" and timing["mode"] == "lockstep" and timing["trigger"] is None
    assert rep["start"]["law"]["source"] == "external" and m["controller"] == "quaternion-feedback"


def test_spy_shows_the_start_record():
    from sc_rt.tools.spy import ChannelStats
    from sc_rt.wire.startrec import encode_start

    st = ChannelStats("SCRT_HIL_START", keep=float("inf"))
    st.add(0.0, encode_start({"scenario": "paper_faults", "mode": "realtime", "trigger": "event",
                              "control_rate_hz": 100.0, "law": {"name": "pd"}}))
    snap = st.snapshot()
    assert snap["type"] == "start record" and snap["undecodable"] == 0
    assert snap["summary"] == {"mode": "realtime", "trigger": "event", "control_rate_hz": 100.0, "law": "pd",
                               "scenario": "paper_faults"}
    st.add(1.0, b"paper_faults")  # an older start message: raw bytes, not a record
    assert st.snapshot()["undecodable"] == 1
