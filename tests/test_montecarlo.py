"""sc-rt montecarlo: dispersions stay within their bounds; the scenario
itself (in-memory changes included) reaches the workers; runs are
reproducible from (seed, run id) whatever the workers and their order; a
run alone equals the run inside its campaign; seeding is O(1) in the id;
the statistics; bad options exit 2 with one line."""

from __future__ import annotations

import json
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.cli.main import main
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate, with_overrides
from sc_rt.studies.campaign import (plan_campaign, Dispersion, RunStore, clopper_pearson,
                                    draw_run, rerun, run_campaign, run_one, run_seed_sequence,
                                    tolerance_bound, wilks_order, wilks_runs)
from sc_rt.studies.campaign.figure import figure
from sc_rt.studies.campaign.stats import wilks_confidence
from sc_rt.studies.montecarlo import disperse, run_montecarlo

ROOT = Path(__file__).resolve().parent.parent
FAULTS = ROOT / "scenarios/paper_faults.toml"
FREE = ROOT / "scenarios/paper_fault_free.toml"


def same(a, b) -> bool:
    """Bitwise equality of rows (repr of a float is exact; NaN equals NaN)."""
    return repr(a) == repr(b)


def test_dispersions_stay_within_their_bounds():
    scn = load_scenario(FAULTS)
    d = Dispersion()
    J_nom = np.asarray(scn.plant.J0 + scn.plant.dJ)
    R0 = _core.mrp_to_dcm(np.asarray(scn.initial.sigma_BN))
    rng = np.random.default_rng(7)
    for _ in range(200):
        s = disperse(scn, rng, d)
        J = np.asarray(s.plant.J)
        assert np.all(np.abs(np.diag(J) / np.diag(J_nom) - 1) <= d.inertia + 1e-12)
        assert np.all(np.linalg.eigvalsh(J) > 0)
        np.testing.assert_array_equal(s.plant.J0, scn.plant.J0)  # the controller's model is kept
        for f, f0 in zip(s.actuators.faults, scn.actuators.faults):
            assert f.wheel == f0.wheel
            assert f.onset >= 0 and abs(f.onset - f0.onset) <= d.onset + 1e-12
            assert 0 <= f.effectiveness <= 1 and abs(f.effectiveness - f0.effectiveness) <= d.effectiveness + 1e-12
        R = _core.mrp_to_dcm(np.asarray(s.initial.sigma_BN))
        angle = np.arccos(np.clip((np.trace(R @ R0.T) - 1) / 2, -1, 1))
        assert angle <= d.attitude + 1e-9
        assert np.all(np.abs(np.asarray(s.initial.omega_BN_B) - scn.initial.omega_BN_B) <= d.rate + 1e-15)


def test_a_scenario_pickles_and_keeps_its_numbers():
    scn = load_scenario(FAULTS)
    before = simulate(scn, engine="python", duration=3).metrics  # builds the closure cache
    assert "_fast" in scn.plant.__dict__
    copy = pickle.loads(pickle.dumps(scn))
    assert "_fast" not in copy.plant.__dict__  # rebuilt lazily on the other side
    after = simulate(copy, engine="python", duration=3).metrics
    assert same({k: v for k, v in before.items() if k != "wall_s"},
                {k: v for k, v in after.items() if k != "wall_s"})


def test_an_in_memory_override_reaches_the_workers():
    scn = with_overrides(load_scenario(FREE), duration=5)  # the file says 300 s
    res = run_montecarlo(scn, 3, workers=2, law="pd", progress=False)
    rate = scn.run.control_rate_hz
    assert [r["steps"] for r in res["per_run"]] == [int(5 * rate) + 1] * 3


def test_reproducible_from_the_seed_for_any_number_of_workers_and_order():
    scn = with_overrides(load_scenario(FREE), duration=60)
    a = run_montecarlo(scn, 6, workers=1, seed=3, law="pd", progress=False)
    b = run_montecarlo(scn, 6, workers=2, seed=3, law="pd", progress=False, batch_size=1)
    c = run_montecarlo(scn, 6, workers=1, seed=4, law="pd", progress=False)
    assert [r["run"] for r in a["per_run"]] == list(range(6))
    assert same(a["per_run"], b["per_run"])
    assert not same(a["per_run"], c["per_run"])
    assert a["fraction_holding_bound"] == sum(r["holds_bound"] for r in a["per_run"]) / 6


def test_a_run_alone_equals_the_run_inside_its_campaign(tmp_path):
    scn = with_overrides(load_scenario(FAULTS), duration=40)
    c = plan_campaign(scn, Dispersion(), seed=11)
    run_campaign(c, 6, tmp_path / "mc", workers=2, progress=False)
    rows = RunStore(tmp_path / "mc", c.columns()).read().to_pylist()
    alone = run_one(c, 4)
    assert same({k: alone.get(k) for k in rows[4]}, rows[4])
    row = rerun(c, 4, tmp_path / "rerun", plots=False)  # --rerun: full outputs
    assert same(row, alone)
    metrics = json.loads((tmp_path / "rerun" / "metrics.json").read_text())
    assert metrics["steps"] == rows[4]["steps"]
    assert (tmp_path / "rerun" / "trajectory.arrow").exists()


def test_seeding_is_o1_in_the_run_id(monkeypatch):
    # the same stream as the i-th child of SeedSequence(seed) (older campaigns keep their numbers) ...
    ss = run_seed_sequence(5, 1000)
    assert ss.spawn_key == (1000,)
    np.testing.assert_array_equal(ss.generate_state(4),
                                  np.random.SeedSequence(5).spawn(1001)[1000].generate_state(4))
    # ... built from (seed, id) directly: every seed sequence a draw of id 10**6 makes is
    # keyed by that id, and none is a parent to spawn from (no iteration over the ids before it)
    made = []
    real = np.random.SeedSequence

    def recording(*args, **kw):
        made.append(kw.get("spawn_key", ()))
        return real(*args, **kw)

    monkeypatch.setattr(np.random, "SeedSequence", recording)
    scn = load_scenario(FAULTS)
    s, values, redraws, _ = draw_run(scn, Dispersion(), 5, 10**6)
    assert s is not None and redraws == 0
    assert made and all(key[:1] == (10**6,) for key in made)
    assert len(made) <= 2  # the shortcuts' stream and the table's


# --------------------------------------------------------------------------- #
# Statistics.


@pytest.mark.parametrize("k,n", [(0, 10), (3, 10), (10, 10), (59, 59), (97, 100), (1, 1000)])
def test_clopper_pearson_is_scipys_exact_interval(k, n):
    from scipy.stats import binomtest

    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    lo, hi = clopper_pearson(k, n)
    assert lo == pytest.approx(ci.low, abs=1e-12) and hi == pytest.approx(ci.high, abs=1e-12)
    assert lo <= k / n <= hi


def test_wilks_run_counts_and_orders():
    assert wilks_runs(0.95, 0.95) == 59  # 95/95 one-sided first order
    assert 1 - 0.95**59 >= 0.95 > 1 - 0.95**58
    assert wilks_runs(0.95, 0.95, order=2) == 93
    assert wilks_runs(0.99, 0.95) == 299
    assert wilks_order(58) == 0 and wilks_order(59) == 1 and wilks_order(92) == 1 and wilks_order(93) == 2
    for n in (59, 93, 200, 1000):
        k = wilks_order(n)
        assert wilks_confidence(n, k, 0.95) >= 0.95 > wilks_confidence(n, k + 1, 0.95)
    assert tolerance_bound(list(range(58)))["bound"] is None
    assert tolerance_bound([float(i) for i in range(59)])["bound"] == 58.0  # the maximum
    assert tolerance_bound([float(i) for i in range(93)])["bound"] == 91.0  # the second largest


def test_the_figure_says_no_run_left_the_bound_instead_of_a_bar_at_zero():
    summary = {"final_metric": "sigma_e_norm.300", "status": {"invalid": 0}, "runs": 3,
               "fraction_holding_bound_ci95": [0.3, 1.0], "fraction_holding_bound": 1.0,
               "scenario": "s", "law": "pd"}
    rows = [{"sigma_e_norm.300": 1e-6, "first_bound_violation_s": None}] * 3
    fig = figure(summary, rows)
    right = fig.axes[1]
    assert not right.patches  # no bar
    assert any("no run left the bound" in t.get_text() for t in right.texts)
    rows = rows[:2] + [{"sigma_e_norm.300": 0.5, "first_bound_violation_s": 12.0}]
    fig = figure(dict(summary, fraction_holding_bound=2 / 3), rows)
    assert fig.axes[1].patches and not fig.axes[1].texts


# --------------------------------------------------------------------------- #
# The command.


@pytest.mark.parametrize("option,value", [
    ("--runs", "0"), ("--runs", "-3"), ("--runs", "abc"), ("--workers", "-1"), ("--workers", "0"),
    ("--seed", "-1"), ("--inertia", "5"), ("--inertia", "nan"), ("--inertia", "1"),
    ("--effectiveness", "-1"), ("--onset", "inf"), ("--attitude", "4"), ("--rate", "-0.1"),
    ("--control-rate", "0"), ("--batch", "0"), ("--rerun", "-2"), ("--law", "lqr"),
    ("--backend", "spark"), ("--scheduler", "localhost"), ("--scheduler", "tcp://h:99999"),
    ("--scheduler-file", "no/such/file.json"), ("--confidence", "1"), ("--confidence", "0"),
    ("--confidence", "abc"), ("--coverage", "0"), ("--coverage", "1.5"),
])  # fmt: skip
def test_bad_options_exit_2_with_one_line_naming_them(option, value, capsys, tmp_path):
    rc = main(["montecarlo", str(FAULTS), option, value, "--out", str(tmp_path / "mc")])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1 and f"{option} {value}" in err
    assert not (tmp_path / "mc").exists()  # nothing started


def test_cli_writes_the_report_and_the_dataset(tmp_path):
    out = tmp_path / "mc"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "montecarlo", "scenarios/paper_faults.toml",
                        "--runs", "4", "--workers", "2", "--controller", "dsc", "--out", str(out)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    m = json.loads((out / "montecarlo.json").read_text())
    assert m["runs"] == 4 and m["dataset"]["rows"] == 4 and (out / "montecarlo.png").exists()
    assert "per_run" not in m and len(m["fraction_holding_bound_ci95"]) == 2
    import pyarrow.parquet as pq

    t = pq.read_table(out / "runs")
    assert sorted(t.column("run").to_pylist()) == [0, 1, 2, 3]
    columns = {"seed", "status", "spacecraft.dJ[0][0]", "faults[0].onset", "first_bound_violation_s"}
    assert columns <= set(t.column_names)
    assert "hold the bound" in r.stdout and r.stderr == ""  # no progress bar without a terminal
    # the same command again refuses to mix campaigns; --resume has nothing left to do
    assert main(["montecarlo", str(FAULTS), "--runs", "4", "--out", str(out)]) == 2
    written = {p.name: p.read_bytes() for p in (out / "runs").glob("*.parquet")}
    assert written
    assert main(["montecarlo", str(FAULTS), "--runs", "4", "--controller", "dsc", "--resume",
                 "--out", str(out)]) == 0
    # nothing left to do: the dataset's files are the ones written before, unchanged, and nothing more
    assert {p.name: p.read_bytes() for p in (out / "runs").glob("*.parquet")} == written
    assert sorted(pq.read_table(out / "runs").column("run").to_pylist()) == [0, 1, 2, 3]
    assert main(["montecarlo", str(FAULTS), "--runs", "4", "--resume", "--out", str(out)]) == 2  # other law


@pytest.mark.slow
def test_an_unreachable_scheduler_is_named_and_exits_2(capsys, tmp_path):
    import socket
    import time

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.monotonic()
    rc = main(["montecarlo", str(FAULTS), "--runs", "2", "--scheduler", f"tcp://127.0.0.1:{port}",
               "--out", str(tmp_path / "mc")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and f"tcp://127.0.0.1:{port}" in err
    assert time.monotonic() - t0 < 60  # a hang guard, not a speed test (the timeout is 3 s)
    assert not (tmp_path / "mc" / "runs").exists()
