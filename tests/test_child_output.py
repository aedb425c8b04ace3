"""The bench's children cannot block or bloat a run through their output or
their memory (issue 40 item 3): a plugin that writes 16 KB to stderr at every
step runs a lockstep run to its end, every state answered and the
trajectory bitwise the offline run's (before: its controller blocked on the
full pipe after 64 KB, the rows zeroed, the run valid), its stderr kept in a
capped file; a Python law that prints without end leaves a capped
controller_stdout.txt; a Python law whose memory grows without end is killed
at the documented limit and the run is invalid, named."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sc_rt.hil.procs import OUTPUT_CAP_BYTES

import lcmnet
from trajcmp import load_traj


def _metrics(out):
    return json.loads((out / "metrics.json").read_text())


@pytest.mark.lcm
def test_a_law_flooding_stderr_neither_blocks_its_controller_nor_fills_the_disk(plugins, tmp_path):
    lcmnet.require()
    law = f"plugin:{plugins['chatty']}"
    out, off = tmp_path / "hil", tmp_path / "sim"
    r = lcmnet.run_cli(["hil", "paper_fault_free", "--law", law, "--mode", "lockstep", "--duration", "20",
                        "--out", str(out), "--no-plots"])
    assert r.returncode == 0, r.stderr[-2000:]
    m = _metrics(out)
    assert m["valid"] is True and m["steps"] == 201
    hil = load_traj(out)
    assert np.all(np.isfinite(hil["latency_us"])), "a state the controller did not answer"
    err = (out / "controller_stderr.txt").read_bytes()
    # 201 steps x 16 x 1023 bytes written: the first OUTPUT_CAP_BYTES kept, the rest counted
    written = 201 * 16 * 1023
    assert err[:OUTPUT_CAP_BYTES].count(b"x") > OUTPUT_CAP_BYTES - 4096  # (the controller's own lines too)
    assert len(err) < OUTPUT_CAP_BYTES + 200 and b"more bytes dropped" in err
    dropped = int(err.rsplit(b"[sc-rt: ", 1)[1].split()[0])
    assert written - OUTPUT_CAP_BYTES <= dropped <= written
    s = lcmnet.run_cli(["sim", "paper_fault_free", "--law", law, "--engine", "cpp", "--duration", "20",
                        "--out", str(off), "--no-plots"], netns=False)
    assert s.returncode == 0, s.stderr[-2000:]
    sim = load_traj(off)
    for k in ("sigma_BN", "omega_BN_B", "u_cmd", "u_sat"):
        assert np.array_equal(hil[k], sim[k]), k


PRINTS = '''
import numpy as np


class Prints:
    name = "prints"

    def __init__(self, setup):
        pass

    def reset(self, inp):
        pass

    def step(self, inp):
        print("y" * 8191)
        return np.zeros(4)
'''

GROWS = '''
import numpy as np


class Grows:
    name = "grows"

    def __init__(self, setup):
        self.kept = []

    def reset(self, inp):
        pass

    def step(self, inp):
        self.kept.append(np.ones(50 * 1024 * 1024 // 8))  # 50 MB, touched
        return np.zeros(4)
'''


@pytest.mark.lcm
def test_a_python_law_printing_without_end_leaves_a_capped_file(tmp_path):
    lcmnet.require()
    (tmp_path / "prints.py").write_text(PRINTS)
    out = tmp_path / "o"
    r = lcmnet.run_cli(["hil", "paper_fault_free", "--law", f"{tmp_path / 'prints.py'}:Prints", "--mode",
                        "lockstep", "--duration", "20", "--out", str(out), "--no-plots"])
    assert r.returncode == 0, r.stderr[-2000:]
    text = (out / "controller_stdout.txt").read_bytes()
    assert len(text) < OUTPUT_CAP_BYTES + 200 and b"more bytes dropped" in text
    assert _metrics(out)["valid"] is True


@pytest.mark.lcm
def test_a_controller_over_its_memory_limit_fails_the_run(tmp_path):
    lcmnet.require()
    (tmp_path / "grows.py").write_text(GROWS)
    out = tmp_path / "o"
    r = lcmnet.run_cli(["hil", "paper_fault_free", "--law", f"{tmp_path / 'grows.py'}:Grows", "--mode",
                        "lockstep", "--duration", "300", "--controller-memory-limit", "600", "--out", str(out),
                        "--no-plots"])
    assert r.returncode == 1, r.stderr[-2000:]
    m = _metrics(out)
    assert m["valid"] is False and "over the limit of 600 MB" in m["invalid_reason"], m.get("invalid_reason")
    assert m["partial"] is True and m["steps"] < 3001
    assert m["controller_peak_rss_mb"] > 600
    # the log's report gives the live reason, from the bench's end record (it said only "the log ends early")
    rep = lcmnet.run_cli(["report", str(out / "run.lcmlog"), "--no-plots", "--out", str(tmp_path / "rep")],
                         netns=False)
    assert rep.returncode == 0, rep.stderr
    mr = _metrics(tmp_path / "rep")
    assert mr["valid"] is False and "over the limit of 600 MB" in mr["invalid_reason"], mr.get("invalid_reason")
