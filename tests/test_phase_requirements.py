"""Requirements per guidance phase (issue 41 item 9): a row's ``phase``
selects a named phase of the scenario's guidance ("before", "slew" and
"hold" of a slew; "hold" of an inertial hold) as its span; the row is judged
over exactly those rows. The phases are checked against the file's own
[guidance] start and duration, the value against numpy on the recorded
rows; a phase the guidance has not, or beside t_from, is refused."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from sc_rt import load_scenario, simulate
from sc_rt.scenario.model import ScenarioError

from test_requirement_matrix import q, rotvec

LIB = Path(__file__).resolve().parent.parent / "python" / "sc_rt" / "scenario" / "library"
ARCSEC = math.pi / 180.0 / 3600.0

ROWS = '''
[[requirements]]
name = "hold_pointing"
kind = "APE"
axis = "norm"
bound = 1e6
unit = "arcsec"
confidence = 0.95
phase = "hold"

[[requirements]]
name = "slew_pointing"
kind = "APE"
axis = "norm"
bound = 1e6
unit = "arcsec"
confidence = 0.95
phase = "slew"
'''


def _file(tmp_path: Path, base: str, extra: str) -> Path:
    f = tmp_path / f"{base}.toml"
    f.write_text((LIB / f"{base}.toml").read_text() + extra)
    return f


def test_a_slews_phases_are_its_own_intervals_and_the_rows_are_judged_over_them(tmp_path):
    f = _file(tmp_path, "slew_rest_to_rest", ROWS)
    g = tomllib.loads(f.read_text())["guidance"]
    scn = load_scenario(f)
    reqs = {r.name: r for r in scn.requirements}
    assert (reqs["hold_pointing"].t_from, reqs["hold_pointing"].t_to) == (g["start"] + g["duration"], None)
    assert (reqs["slew_pointing"].t_from, reqs["slew_pointing"].t_to) == (g["start"], g["start"] + g["duration"])
    run = simulate(scn, engine="cpp")
    t, sigma = np.asarray(run["t"]), np.asarray(run["sigma_BD"])
    err = np.linalg.norm(rotvec(sigma), axis=1) / ARCSEC
    got = {r["name"]: r for r in run.metrics["requirements"]}
    for name, (a, b) in (("hold_pointing", (g["start"] + g["duration"], t[-1])),
                         ("slew_pointing", (g["start"], g["start"] + g["duration"]))):
        rows = (t >= a - 1e-9) & (t <= b + 1e-9)
        assert got[name]["value"] == pytest.approx(q(err[rows], 0.95), rel=1e-9), name


@pytest.mark.parametrize("base, extra, words", [
    ("paper_faults", 'phase = "hold"', "not a phase of this scenario's [guidance] (its phases: none"),
    ("slew_rest_to_rest", 'phase = "cruise"', 'its phases: "before", "slew", "hold"'),
    ("slew_rest_to_rest", 'phase = "hold"\nt_from = 5.0', "t_from and phase both give the span"),
])
def test_a_phase_the_guidance_has_not_or_beside_t_from_is_refused(tmp_path, base, extra, words):
    row = f'\n[[requirements]]\nname = "p"\nkind = "APE"\naxis = "norm"\nbound = 1.0\nunit = "arcsec"\n' \
          f'confidence = 0.95\n{extra}\n'
    with pytest.raises(ScenarioError) as e:
        load_scenario(_file(tmp_path, base, row))
    assert words in str(e.value), str(e.value)
