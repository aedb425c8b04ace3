"""``sc-rt report LOG`` reaches the live run's verdict from the log alone
(issue 40 item 4): a lockstep run whose Python law throws from t = 1 s is
invalid live (the controller's summary counts the failures) and its log's
report is invalid too, from the rows the controller flagged
FLAG_LAW_INVALID, with the same count of failed steps. Before, the report
rebuilt it as ``valid: true``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sc_rt.pylaw import FLAG_LAW_INVALID

import lcmnet
from trajcmp import load_traj

LAW = '''
import numpy as np


class Throws:
    name = "throws-after-1s"

    def __init__(self, setup):
        pass

    def reset(self, inp):
        pass

    def step(self, inp):
        if inp.t >= 1.0:
            raise RuntimeError("deliberate failure")
        return np.zeros(4)
'''


@pytest.mark.lcm
def test_report_of_a_log_gives_the_live_runs_law_failures(tmp_path):
    lcmnet.require()
    law = tmp_path / "throws.py"
    law.write_text(LAW)
    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", "paper_fault_free", "--law", f"{law}:Throws", "--mode", "lockstep", "--duration",
                        "3", "--out", str(out), "--no-plots"])
    assert r.returncode == 1 and "INVALID" in r.stderr, r.stderr
    live = json.loads((out / "metrics.json").read_text())
    assert live["valid"] is False and "law failed" in live["invalid_reason"]
    # independent of the metrics: the rows the run recorded with the law's flag
    flags = load_traj(out)["flags"]
    t = load_traj(out)["t"]
    failed = (flags & FLAG_LAW_INVALID) != 0
    assert failed.any() and np.all(t[failed] >= 1.0 - 1e-9)
    rep = lcmnet.run_cli(["report", str(out / "run.lcmlog"), "--no-plots", "--out", str(tmp_path / "rep")],
                         netns=False)
    assert rep.returncode == 0, rep.stderr
    m = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert m["valid"] is False and "law failed" in m["invalid_reason"], m.get("invalid_reason")
    assert m["law_invalid_steps"] == int(failed.sum()) == live["law_invalid_steps"]
    assert f"t = {float(t[failed][0]):.4g} s" in m["invalid_reason"]


def test_report_html_of_an_invalid_offline_run_says_invalid_in_its_headline(tmp_path):
    """issue 40 item 9: the verdict's headline of report.html starts with
    INVALID and the run's reason (before: an invalid run's page never said
    so near the top)."""
    import subprocess
    import sys

    law = tmp_path / "throws.py"
    law.write_text(LAW)
    out = tmp_path / "sim"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", "paper_fault_free", "--law", f"{law}:Throws",
                        "--engine", "cpp", "--duration", "3", "--out", str(out), "--no-plots"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 1, r.stderr
    reason = json.loads((out / "metrics.json").read_text())["invalid_reason"]
    html = (out / "report.html").read_text()
    head = html[html.index('<p id="verdict-bound">'):]
    assert head.startswith('<p id="verdict-bound">INVALID: ')
    assert reason.split(";")[0].replace("'", "&#x27;") in head[:600]


def test_report_of_a_log_with_another_plants_states_is_invalid(tmp_path):
    """Issue 40 item 4: every plant session of a log. A hil run's log lists
    its one plant; the same log with the states of a second plant (a copy
    of each state under another session, as another bench on the same URL
    would publish them, after the run's own) reports two plants and is
    invalid, as the live run is for a bench collision."""
    import lcm
    from sc_rt_lcm import plant_state_t

    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", "paper_fault_free", "--duration", "5", "--out", str(out), "--no-plots"],
                       timeout=180)
    assert r.returncode == 0, r.stderr
    events = [(e.timestamp, e.channel, e.data) for e in lcm.EventLog(str(out / "run.lcmlog"), "r")]
    ours = {plant_state_t.decode(d).session for _ts, ch, d in events if ch == "SCRT_STATE"}
    assert len(ours) == 1
    other = ours.pop() ^ 0x5A5A5A5A
    forged = []
    for ts, ch, data in events:
        if ch == "SCRT_STATE":
            m = plant_state_t.decode(data)
            m.session = other
            forged.append((ts + 1, ch, m.encode()))
    log = lcm.EventLog(str(tmp_path / "two.lcmlog"), "w", overwrite=True)
    for ts, ch, data in events + forged[:30]:
        log.write_event(ts, ch, data)
    log.close()
    reports = {}
    for name, path in (("one", out / "run.lcmlog"), ("two", tmp_path / "two.lcmlog")):
        rr = lcmnet.run_cli(["report", str(path), "--out", str(tmp_path / name), "--no-plots"], timeout=120)
        assert rr.returncode == 0, rr.stderr
        reports[name] = (json.loads((tmp_path / name / "report.json").read_text()),
                         json.loads((tmp_path / name / "metrics.json").read_text()))
    rep, m = reports["one"]
    assert [p["states"] for p in rep["plant_sessions"]] == [51] and m["valid"] is True
    rep, m = reports["two"]
    assert [p["session"] for p in rep["plant_sessions"]][1] == other and rep["plant_sessions"][1]["states"] == 30
    assert m["valid"] is False and "states of 2 plants" in m["invalid_reason"], m.get("invalid_reason")


def _conflicts_by_hand(msgs) -> int:
    """An independent count: per (session, seq), the messages that differ from
    the one before them of the same key, in log order."""
    last: dict = {}
    n = 0
    for session, seq, state_seq, u in msgs:
        if not np.all(np.isfinite(u)):
            continue
        k = (session, seq)
        if k in last and last[k] != (state_seq, tuple(u)):
            n += 1
        last[k] = (state_seq, tuple(u))
    return n


def test_command_conflicts_in_a_log_are_counted_as_the_plant_counts_them():
    from sc_rt.logs.report import command_conflicts
    from sc_rt.wire.codec import TYPES, numpy_dtype

    rng = np.random.default_rng(4)
    dt = numpy_dtype(TYPES["wheel_cmd_t"])
    genuine = [(7, k, k, rng.normal(size=4)) for k in range(200)]
    repeats = [genuine[k] for k in (3, 50, 51)]  # a controller's repeated answer: no conflict
    racing = [(7, k, k, np.array([9.0, -7.0, 9.0, -7.0])) for k in (10, 11, 120)]  # its session and seq
    other = [(8, k, k, rng.normal(size=4)) for k in range(5)]  # another session's seq: not a conflict
    nan = [(7, 12, 12, np.full(4, np.nan))]  # the plant drops it
    msgs = genuine[:60] + repeats + racing + nan + other + genuine[60:]
    rec = np.zeros(len(msgs), dt)
    for i, (session, seq, state_seq, u) in enumerate(msgs):
        rec[i]["session"], rec[i]["seq"], rec[i]["state_seq"], rec[i]["u_cmd"] = session, seq, state_seq, u
    assert command_conflicts(rec) == _conflicts_by_hand(msgs) == 3
    assert command_conflicts(rec[: 60 + len(repeats)]) == 0
    assert command_conflicts(rec[:0]) == 0
