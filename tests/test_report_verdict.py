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
    flags = np.load(out / "trajectory.npz")["flags"]
    t = np.load(out / "trajectory.npz")["t"]
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
