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


def test_every_command_that_reads_a_scenario_takes_set(tmp_path):
    """The bus and study commands too (emulator, controller, design, floor,
    config; check lists it as an error of the file): a key the file has not is one line naming it, exit 2,
    nothing started or written."""
    cmds = {"emulator": ["emulator", "paper_faults", "--out", str(tmp_path / "e")],
            "controller": ["controller", "paper_faults", "--law", str(tmp_path / "law.py") + ":Law"],
            "design": ["design", "paper_faults", "--no-plots", "--out", str(tmp_path / "d")],
            "floor": ["floor", "paper_faults", "--json", "--no-cache"],
            "config": ["config", "paper_faults", "--out", str(tmp_path / "c.bin")]}
    (tmp_path / "law.py").write_text("class Law:\n    def __init__(self, setup): pass\n"
                                     "    def reset(self, inp): pass\n    def step(self, inp): return [0.0] * 4\n")
    for name, args in cmds.items():
        r = _cli(*args, "--set", "run.no_such_key=1")
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and "run.no_such_key" in lines[0], (name, r.stderr)
    assert not any((tmp_path / x).exists() for x in ("e", "d", "c.bin"))
    r = _cli("check", "paper_faults", "--set", "run.no_such_key=1")
    assert r.returncode == 2 and "run.no_such_key = 1: unknown key" in r.stdout, r.stdout


def test_design_with_set_designs_for_the_edited_file(tmp_path):
    """design reads the inertia it is given: --set of J0 equals a copy of
    the file with J0 edited (design.json compared whole), and differs from
    the file's own design."""
    text = (LIB / "paper_faults.toml").read_text()
    new = "[[30.0, 0.0, 0.0], [0.0, 25.0, 0.0], [0.0, 0.0, 20.0]]"
    edited, n = re.subn(r"(?m)^J0 = \[\[.*\]\]", f"J0 = {new}", text, count=1)
    assert n == 1
    f = tmp_path / "edited.toml"
    f.write_text(edited)
    r1 = _cli("design", "paper_faults", "--set", f"spacecraft.J0={new}", "--no-plots", "--out", str(tmp_path / "a"))
    r2 = _cli("design", str(f), "--no-plots", "--out", str(tmp_path / "b"))
    r0 = _cli("design", "paper_faults", "--no-plots", "--out", str(tmp_path / "o"))
    assert r1.returncode == r2.returncode == r0.returncode == 0, r1.stderr + r2.stderr + r0.stderr
    a, b, o = (json.loads((tmp_path / x / "design.json").read_text()) for x in "abo")
    for d in (a, b, o):
        d.pop("scenario_path")
    assert a == b and a != o


def test_set_reaches_an_entry_of_an_array_as_montecarlo_keys_do(tmp_path):
    """``--set magnetorquers.faults[0].onset=...`` (the key a [montecarlo]
    dispersion names) edits that entry; the scenario read equals the one read
    from a copy of the file with the entry edited as text; an entry the file
    has not is one line."""
    from sc_rt.scenario.reader import load_scenario

    text = (LIB / "day_hold.toml").read_text()
    edited, n = re.subn(r"(?m)^onset = 1\.0e9 ", "onset = 3600.0 ", text)
    edited, m = re.subn(r"(?m)^(kind = \"stuck\"\n)dipole = 0\.0 ", r"\1dipole = -12.5 ", edited)
    assert n == m == 1
    f = tmp_path / "day_hold.toml"
    f.write_text(edited)
    by_hand = load_scenario(f)
    by_set = load_scenario("day_hold", sets=[("magnetorquers.faults[0].onset", 3600.0),
                                             ("magnetorquers.faults[0].dipole", -12.5)])
    assert by_set.plant.magnetorquers.faults == by_hand.plant.magnetorquers.faults
    assert by_set.plant.magnetorquers.faults[0].onset == 3600.0
    assert by_set.plant.magnetorquers.faults[0].dipole == -12.5
    for pair, words in (("magnetorquers.faults[1].onset=5", "magnetorquers.faults[1] is not in the file "
                                                             "(magnetorquers.faults has 1 entry)"),
                        ("faults[0].onset=5", "faults is not in the file"),
                        ("run[0]=1", "run is a table, not an array")):
        r = _cli("sim", "day_hold", "--set", pair, "--out", str(tmp_path / "o"))
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and words in lines[0], (pair, r.stderr)
        assert not (tmp_path / "o").exists()
