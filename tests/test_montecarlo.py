"""sc-rt montecarlo: dispersions stay within their bounds, runs are
reproducible from the seed whatever the number of workers."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from sc_rt import _core
from sc_rt.studies.montecarlo import Dispersion, disperse, run_montecarlo
from sc_rt.scenario.model import load_scenario

ROOT = Path(__file__).resolve().parent.parent


def test_dispersions_stay_within_their_bounds():
    scn = load_scenario(ROOT / "scenarios/paper_faults.toml")
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


def test_reproducible_from_the_seed_for_any_number_of_workers():
    scn = load_scenario(ROOT / "scenarios/paper_fault_free.toml")
    a = run_montecarlo(scn, 6, workers=1, seed=3, law="pd", progress=False)
    b = run_montecarlo(scn, 6, workers=2, seed=3, law="pd", progress=False)
    c = run_montecarlo(scn, 6, workers=1, seed=4, law="pd", progress=False)
    assert a["per_run"] == b["per_run"]
    assert a["per_run"] != c["per_run"]
    assert a["fraction_holding_bound"] == sum(r["holds_bound"] for r in a["per_run"]) / 6


def test_cli_writes_the_report(tmp_path):
    out = tmp_path / "mc"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "montecarlo", "scenarios/paper_faults.toml",
                        "--runs", "4", "--workers", "2", "--controller", "dsc", "--out", str(out)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    m = json.loads((out / "montecarlo.json").read_text())
    assert m["runs"] == 4 and len(m["per_run"]) == 4 and (out / "montecarlo.png").exists()
    assert "hold the bound" in r.stdout
