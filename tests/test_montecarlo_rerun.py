"""A campaign is planned once and each run records its draw (issue 38):
``--rerun K`` replays the values run K drew in the campaign in --out, not
a new draw from the command line's seed and table, and ``sc-rt rerun`` of
a run alone's directory replays its plan with those values.

The first two tests fail on the old main: there ``--rerun`` drew run K
again from --seed and the file's [montecarlo] table (a changed seed or
table gave another run K, and nothing said so), and a run alone recorded
no plan to replay; so does the last (a campaign took no plan)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from sc_rt.cli.main import main
from sc_rt.scenario.reader import load_scenario
from sc_rt.studies.campaign import Dispersion, RunStore, disperse, draw_run, run_seed_sequence
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
BASE = re.sub(r"(?m)^duration = 300\.0", "duration = 3.0", (ROOT / "scenarios/paper_faults.toml").read_text())
TABLE = """
[montecarlo]
[[montecarlo.disperse]]
key = "spacecraft.dJ"
dist = "uniform"
low = {low}
high = {high}

[[montecarlo.disperse]]
key = "initial.omega_BN_B"
dist = "normal"
mean = 0.0
std = 0.002
"""


def _file(tmp_path: Path, low: float, high: float) -> Path:
    p = tmp_path / "mc.toml"
    p.write_text(BASE + TABLE.format(low=low, high=high))
    return p


def _values(row: dict) -> dict:
    return {k: v for k, v in row.items() if k.startswith(("spacecraft.dJ", "initial.omega_BN_B"))}


def _inputs(run_dir: Path) -> dict:
    """What a run recorded as its inputs (its trajectory's meta)."""
    return json.loads(str(load_traj(run_dir)["meta_json"]))["inputs"]


def _row(out: Path, run: int) -> dict:
    rows = [r for r in RunStore(out, []).read().to_pylist() if r["run"] == run]
    return rows[0]


def test_rerun_replays_the_recorded_draw_whatever_the_seed_and_table_say_now(tmp_path, capsys):
    scn, out = _file(tmp_path, -0.5, 0.5), tmp_path / "mc"
    assert main(["montecarlo", str(scn), "--runs", "3", "--workers", "1", "--seed", "3", "--law", "pd",
                 "--out", str(out)]) == 0
    ran = _row(out, 1)
    assert ran["status"] == "ok"
    capsys.readouterr()
    # another seed on the command line: run 1 is still the campaign's run 1
    assert main(["montecarlo", str(scn), "--runs", "3", "--seed", "4", "--law", "pd", "--rerun", "1",
                 "--out", str(out)]) == 0
    said = capsys.readouterr()
    assert "run 1 matches its row" in said.out and "replays the draw it recorded (seed 3)" in said.err
    alone = json.loads((out / "rerun-1" / "run.json").read_text())
    assert _values(alone) == _values(ran) and alone["seed"] == 3
    errors = {k: v for k, v in ran.items() if k.startswith("sigma_e_norm.")}
    assert errors and {k: alone[k] for k in errors} == errors  # the same run: the same errors, bitwise
    # a new draw of run 1 from seed 4 is another run (what the old --rerun ran)
    other = draw_run(load_scenario(scn), Dispersion(0, 0, 0, 0, 0, 0), 4, 1)[1]
    assert other != _values(ran)
    # the file's table changed since the campaign: run 2 replays its recorded draw all the same
    _file(tmp_path, -3.0, -2.0)
    assert main(["montecarlo", str(scn), "--runs", "3", "--seed", "3", "--law", "pd", "--rerun", "2",
                 "--out", str(out)]) == 0
    assert "run 2 matches its row" in capsys.readouterr().out
    assert _values(json.loads((out / "rerun-2" / "run.json").read_text())) == _values(_row(out, 2))
    assert set(dict(json.loads(ran["draws"]))) == {"spacecraft.dJ", "initial.omega_BN_B"}  # what was replayed


def test_sc_rt_rerun_of_a_run_alone_replays_its_plan_and_draw(tmp_path):
    scn, out = _file(tmp_path, -0.5, 0.5), tmp_path / "mc"
    assert main(["montecarlo", str(scn), "--seed", "5", "--law", "pd", "--rerun", "0", "--out", str(out)]) == 0
    inputs = _inputs(out / "rerun-0")
    drawn = {k[len("draw "):]: v for k, v in inputs["overrides"].items() if k.startswith("draw ")}
    assert set(drawn) == {"spacecraft.dJ", "initial.omega_BN_B"}
    row = json.loads((out / "rerun-0" / "run.json").read_text())
    assert drawn == dict(json.loads(row["draws"]))  # the plan records the values the row does
    assert main(["rerun", str(out / "rerun-0"), "--out", str(tmp_path / "again")]) == 0
    assert _inputs(tmp_path / "again")["overrides"] == inputs["overrides"]
    first, again = (json.loads((d / "metrics.json").read_text()) for d in (out / "rerun-0", tmp_path / "again"))
    for key in ("sigma_e_norm", "final_wheel_speed", "max_abs_u_cmd"):
        assert again[key] == first[key]  # the same run, bitwise


def test_a_shortcut_runs_scenario_is_the_dispersed_one_bitwise():
    # the values a run records, read back through the file's checks, are the scenario disperse() made
    scn = load_scenario(ROOT / "scenarios/paper_faults.toml")
    d = Dispersion()
    for run in range(3):
        old = disperse(scn, np.random.default_rng(run_seed_sequence(7, run)), d)
        new = draw_run(scn, d, 7, run)[0]
        assert np.array_equal(new.plant.dJ, old.plant.dJ)
        assert np.array_equal(new.initial.sigma_BN, old.initial.sigma_BN)
        assert np.array_equal(new.initial.omega_BN_B, old.initial.omega_BN_B)
        assert [(f.onset, f.end, f.effectiveness) for f in new.actuators.faults] == \
            [(f.onset, f.end, f.effectiveness) for f in old.actuators.faults]


def test_the_campaign_takes_its_base_plan():
    from sc_rt.studies.campaign import plan_campaign

    c = plan_campaign(load_scenario(ROOT / "scenarios/paper_faults.toml"), Dispersion(), 2, law="pd",
                      control_rate_hz=20.0)
    assert c.plan.law.name == "pd" and c.scenario.run.control_rate_hz == 20.0
    plan, rd, _ = c.run_plan(0)
    assert plan.law == c.plan.law and plan.engine == "cpp"
    assert dict(plan.scenario.overrides)["draw spacecraft.dJ"] == dict(rd.values)["spacecraft.dJ"]
