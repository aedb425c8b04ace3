"""--set KEY=VALUE on the commands that read a scenario (issue 41 item 5):
the run equals, bitwise, the run of a copy of the file with that key edited;
the pair is validated like the file (exit 2, one line naming the key) and
recorded in the run's inputs."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
from trajcmp import load_traj

LIB = Path(__file__).resolve().parent.parent / "python" / "sc_rt" / "scenario" / "library"


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "sc_rt.cli", *args], capture_output=True, text=True, timeout=300)


def test_set_runs_what_the_edited_file_runs_and_is_recorded(tmp_path):
    text = (LIB / "paper_faults.toml").read_text()
    edited, n = re.subn(r"(?m)^k1 = [^\n#]*", "k1 = 0.25", text, count=1)
    assert n == 1
    f = tmp_path / "edited.toml"
    f.write_text(edited.replace('name = "paper_faults"', 'name = "paper_faults"', 1))
    a, b = tmp_path / "set", tmp_path / "file"
    r = _cli("sim", "paper_faults", "--engine", "cpp", "--duration", "20", "--set", "laws.dsc-ppc.k1=0.25",
             "--out", str(a), "--no-plots")
    assert r.returncode == 0, r.stderr
    r = _cli("sim", str(f), "--engine", "cpp", "--duration", "20", "--out", str(b), "--no-plots")
    assert r.returncode == 0, r.stderr
    ta, tb = load_traj(a), load_traj(b)
    for k in ("sigma_BN", "u_cmd"):
        assert np.array_equal(ta[k], tb[k]), k
    inputs = json.loads(str(ta["meta_json"]))["inputs"]
    assert inputs["overrides"]["set laws.dsc-ppc.k1"] == 0.25 and inputs["law_params"]["k1"] == 0.25


def test_a_bad_set_is_refused_in_one_line_naming_the_key(tmp_path):
    for pair, words in (("laws.dsc-ppc.k1=-5", "laws.dsc-ppc.k1"), ("nokey", "--set"),
                        ("run.duration.x=1", "run.duration is not a table")):
        r = _cli("sim", "paper_faults", "--set", pair, "--out", str(tmp_path / "o"))
        assert r.returncode == 2, (pair, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and words in lines[0], (pair, r.stderr)
        assert not (tmp_path / "o").exists()
