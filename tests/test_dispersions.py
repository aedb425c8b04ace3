"""The [montecarlo] table of a scenario: parsed and validated like every other
key (file, line, key, value), drawn per element within its distribution,
and what a draw that breaks the scenario does (redrawn, or a failed run)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sc_rt.scenario.keys import get_key, scenario_data
from sc_rt.scenario.model import ScenarioError
from sc_rt.scenario.reader import load_scenario, scenario_from_data
from sc_rt.sim.engines import with_overrides
from sc_rt.studies.campaign import NO_SHORTCUTS, plan_campaign, RunStore, draw_run, run_campaign, run_one

ROOT = Path(__file__).resolve().parent.parent
BASE = (ROOT / "scenarios/paper_faults.toml").read_text()

TABLE = """
[montecarlo]
max_redraws = 20

[[montecarlo.disperse]]
key = "spacecraft.dJ"
dist = "uniform"
low = -0.5
high = 0.5

[[montecarlo.disperse]]
key = "faults[1].onset"
dist = "truncnormal"
std = 2.0
low = -3.0
high = 3.0

[[montecarlo.disperse]]
key = "laws.dsc-ppc.k2"
dist = "choice"
values = [3.0, 4.0, 5.0]

[[montecarlo.disperse]]
key = "spacecraft.Jw"
dist = "normal"
mean = 1.0
std = [0.01, 0.0, 0.01, 0.0]
apply = "scale"

[[montecarlo.disperse]]
key = "laws.dsc-ppc.neso_substeps"
dist = "choice"
values = [1, 2]
"""


def scenario(tmp_path: Path, table: str):
    p = tmp_path / "mc.toml"
    p.write_text(BASE + table)
    return load_scenario(p)


def test_every_scenario_reads_back_from_its_data():
    for f in sorted((ROOT / "scenarios").glob("*.toml")):
        s = load_scenario(f)
        assert scenario_data(scenario_from_data(scenario_data(s), f)) == scenario_data(s)


def test_draws_stay_in_their_distributions_per_element(tmp_path):
    s = scenario(tmp_path, TABLE)
    assert [e.key for e in s.montecarlo.disperse][:2] == ["spacecraft.dJ", "faults[1].onset"]
    dJ0 = np.asarray(s.plant.dJ)
    onset0 = s.actuators.faults[1].onset
    seen_k2, seen_sub, dJs = set(), set(), []
    for i in range(100):
        d, values, redraws, _ = draw_run(s, NO_SHORTCUTS, 2, i)
        assert d is not None and redraws == 0
        dJ = np.asarray(d.plant.dJ)
        assert np.all(np.abs(dJ - dJ0) <= 0.5) and np.array_equal(dJ, dJ.T)  # symmetric draw
        dJs.append(dJ)
        assert abs(d.actuators.faults[1].onset - onset0) <= 3.0
        seen_k2.add(d.controller.resolved("dsc-ppc")["k2"])
        seen_sub.add(d.controller.resolved("dsc-ppc")["neso_substeps"])
        Jw = np.asarray(d.plant.Jw)
        assert Jw[1] == s.plant.Jw[1] and Jw[3] == s.plant.Jw[3]  # std 0: untouched
        assert Jw[0] != s.plant.Jw[0]
        assert values["spacecraft.dJ[0][1]"] == dJ[0, 1] and values["faults[1].onset"] == d.actuators.faults[1].onset
        np.testing.assert_array_equal(d.plant.J0, s.plant.J0)
    assert seen_k2 == {3.0, 4.0, 5.0} and seen_sub == {1, 2}
    assert np.std([m[0, 1] for m in dJs]) > 0.1  # the off-diagonal elements are dispersed too
    # the shortcut flags apply first, the table on top of them
    d2, values, _, _ = draw_run(s, NO_SHORTCUTS.__class__(), 2, 0)
    assert "initial.omega_BN_B[0]" in values and "spacecraft.dJ[2][2]" in values


@pytest.mark.parametrize("entry,key,fragment", [
    ('key = "spacecraft.dj"\ndist = "uniform"\nlow = 0\nhigh = 1', "montecarlo.disperse[0].key",
     "did you mean 'spacecraft.dJ'"),
    ('key = "run.controller"\ndist = "normal"\nstd = 1', "montecarlo.disperse[0].key", "not a numeric key"),
    ('key = "faults[7].onset"\ndist = "normal"\nstd = 1', "montecarlo.disperse[0].key", "not a numeric key"),
    ('key = "spacecraft.w0"\ndist = "gamma"', "montecarlo.disperse[0].dist", "dist must be one of"),
    ('key = "spacecraft.w0"\ndist = "uniform"\nlow = 1\nhigh = 0', "montecarlo.disperse[0].low", "low must be <= high"),
    ('key = "spacecraft.w0"\ndist = "uniform"\nlow = 0', "montecarlo.disperse[0].high", "required key is missing"),
    ('key = "spacecraft.w0"\ndist = "normal"\nstd = -1', "montecarlo.disperse[0].std", "std must be >= 0"),
    ('key = "spacecraft.w0"\ndist = "normal"\nstd = 1\nsigma = 2', "montecarlo.disperse[0].sigma", "unknown key"),
    ('key = "spacecraft.w0"\ndist = "normal"\nstd = nan', "montecarlo.disperse[0].std", "finite"),
    ('key = "initial.omega_BN_B"\ndist = "uniform"\nlow = [1, 2]\nhigh = 3', "montecarlo.disperse[0].low",
     "a list of 3 numbers"),
    ('key = "spacecraft.w0"\ndist = "truncnormal"\nstd = 1\nlow = 50\nhigh = 60',
     "montecarlo.disperse[0].low", "cannot be drawn"),
    ('key = "spacecraft.w0"\ndist = "choice"\nvalues = []', "montecarlo.disperse[0].values", "non-empty"),
    ('key = "spacecraft.w0"\ndist = "choice"\nvalues = [1, 2]\nweights = [1]', "montecarlo.disperse[0].weights",
     "2 numbers"),
    ('key = "faults[0].wheel"\ndist = "uniform"\nlow = 1\nhigh = 3', "montecarlo.disperse[0].dist",
     "takes integers"),
    ('key = "laws.dsc-ppc.k9"\ndist = "uniform"\nlow = 1\nhigh = 3', "montecarlo.disperse[0].key",
     "is not a numeric key"),
    ('key = "spacecraft.w0"\ndist = "normal"\nstd = 1\napply = "multiply"', "montecarlo.disperse[0].apply",
     "apply must be one of"),
    ('key = "spacecraft.w0"\ndist = "normal"\nstd = 1\nsymmetric = false', "montecarlo.disperse[0].symmetric",
     "square matrices"),
])  # fmt: skip
def test_bad_entries_are_named_with_file_line_key_and_value(tmp_path, entry, key, fragment):
    with pytest.raises(ScenarioError) as e:
        scenario(tmp_path, "\n[montecarlo]\n\n[[montecarlo.disperse]]\n" + entry + "\n")
    issues = [i for i in e.value.errors if i.key == key]
    assert issues, str(e.value)
    assert fragment in issues[0].message
    text = (tmp_path / "mc.toml").read_text().splitlines()
    line = issues[0].line
    assert line > 0 and (key.rsplit(".", 1)[1] in text[line - 1] or "[[montecarlo.disperse]]" in text[line - 1])
    assert str(tmp_path / "mc.toml") in str(e.value)


def test_bad_top_level_keys_and_duplicates(tmp_path):
    with pytest.raises(ScenarioError) as e:
        scenario(tmp_path, '\n[montecarlo]\non_invalid = "retry"\nmax_redraws = 0\nruns = 5\n'
                           '[[montecarlo.disperse]]\nkey = "spacecraft.w0"\ndist = "normal"\nstd = 1\n'
                           '[[montecarlo.disperse]]\nkey = "spacecraft.w0"\ndist = "normal"\nstd = 2\n')
    msg = str(e.value)
    for fragment in ('montecarlo.on_invalid = "retry"', "montecarlo.max_redraws = 0", "montecarlo.runs = 5: unknown",
                     "dispersed already by montecarlo.disperse[0]"):
        assert fragment in msg, msg


# A dispersion that often breaks the scenario: J0 + dJ with J0 = diag(10, 15, 20) is not
# positive definite, or breaks the triangle inequality, for many draws of +-12 on the diagonal.
WIDE = """
[montecarlo]
on_invalid = "{mode}"
max_redraws = {n}

[[montecarlo.disperse]]
key = "spacecraft.dJ"
dist = "uniform"
low = {low}
high = {high}
"""


def _campaign(tmp_path, mode, n, low=-12.0, high=12.0):
    s = with_overrides(scenario(tmp_path, WIDE.format(mode=mode, n=n, low=low, high=high)), duration=5)
    return plan_campaign(s, NO_SHORTCUTS, seed=1, law="pd")


def test_an_invalid_draw_is_redrawn_within_max_redraws(tmp_path):
    c = _campaign(tmp_path, "redraw", 100)
    res = run_campaign(c, 12, tmp_path / "mc", workers=1, progress=False)
    rows = RunStore(tmp_path / "mc", c.columns()).read().to_pylist()
    assert res["status"]["invalid"] == 0 and all(r["status"] == "ok" for r in rows)
    assert res["redraws_total"] > 0  # some first draws were invalid ...
    for r in rows:  # ... and what ran is a valid inertia
        dJ = np.array([[r[f"spacecraft.dJ[{i}][{j}]"] for j in range(3)] for i in range(3)])
        ev = np.linalg.eigvalsh(np.diag([10.0, 15.0, 20.0]) + dJ)
        assert ev[0] > 0 and ev[0] + ev[1] >= ev[2] * (1 - 1e-9)


def test_an_invalid_draw_counts_as_a_failed_run_with_on_invalid_fail(tmp_path):
    c = _campaign(tmp_path, "fail", 100)
    res = run_campaign(c, 12, tmp_path / "mc", workers=1, progress=False)
    invalid = [f for f in res["failed"] if f["status"] == "invalid"]
    assert res["status"]["invalid"] == len(invalid) > 0
    assert res["holds_bound"] <= 12 - len(invalid)  # invalid runs never count as holding
    assert all("spacecraft.dJ" in f["message"] and "spacecraft.dJ[0][0]" in f["values"] for f in invalid)
    # the same ids come out invalid in a run alone
    assert all(run_one(c, f["run"])["status"] == "invalid" for f in invalid)


def test_a_run_with_no_valid_draw_is_failed_after_max_redraws(tmp_path):
    c = _campaign(tmp_path, "redraw", 3, low=-100.0, high=-90.0)  # J0 + dJ never positive definite
    d, values, redraws, message = draw_run(c.scenario, c.dispersion, 1, 0)
    assert d is None and redraws == 3 and "spacecraft.dJ" in message
    assert 2.0 - 100.0 <= values["spacecraft.dJ[0][0]"] <= 2.0 - 90.0  # the last draw (nominal 2 + draw)
    res = run_campaign(c, 3, tmp_path / "mc", workers=1, progress=False)
    assert res["status"]["invalid"] == 3 and res["holds_bound"] == 0
    assert res["fraction_holding_bound"] == 0.0 and res["runs_breaking_bound"] == [0, 1, 2]


def test_a_table_campaign_stores_its_values_and_reruns_bitwise(tmp_path):
    s = with_overrides(scenario(tmp_path, TABLE), duration=20)
    c = plan_campaign(s, NO_SHORTCUTS, seed=9, law="dsc-ppc")
    run_campaign(c, 4, tmp_path / "mc", workers=2, progress=False)
    rows = RunStore(tmp_path / "mc", c.columns()).read().to_pylist()
    assert {"spacecraft.dJ[1][2]", "faults[1].onset", "laws.dsc-ppc.k2", "spacecraft.Jw[3]",
            "laws.dsc-ppc.neso_substeps"} <= set(rows[0])
    assert "initial.omega_BN_B[0]" not in rows[0]  # with a table the shortcuts are off
    assert repr({k: run_one(c, 2).get(k) for k in rows[2]}) == repr(rows[2])
    assert get_key(scenario_data(s), "faults[1].onset") == s.actuators.faults[1].onset


def test_the_documented_example_reads(tmp_path):
    doc = (ROOT / "docs/SCENARIOS.md").read_text()
    section = doc[doc.index("### `[montecarlo]`"):]
    block = section[section.index("```toml") + len("```toml"):]
    block = block[:block.index("```")]
    s = scenario(tmp_path, "\n" + block)
    assert [e.key for e in s.montecarlo.disperse] == ["spacecraft.dJ", "faults[1].onset", "spacecraft.Jw",
                                                      "laws.dsc-ppc.k2"]
    d, values, _, _ = draw_run(s, NO_SHORTCUTS, 0, 0)
    assert d is not None and values["laws.dsc-ppc.k2"] in (12.0, 16.0, 20.0)
