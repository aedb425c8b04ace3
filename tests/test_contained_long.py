"""A contained plugin run of any length comes back to its parent (issue 40
item 7): a run longer than the engine's in-memory chunks is on disk in a
temporary directory, which the child that made it used to remove as its copy
of the run went, so that ``compare`` and ``montecarlo`` failed on it
("Failed to open local file .../trajectory.arrow"). The child now hands the
directory over; the parent removes it with its own copy."""

from __future__ import annotations

import gc
import json
import subprocess
import sys

import numpy as np

from sc_rt import load_scenario
from sc_rt.sim.isolated import simulate_isolated


def test_a_long_isolated_run_is_read_in_the_parent_and_its_directory_removed_after(plugins):
    scn = load_scenario("ppc_feasible_1khz")
    law = f"plugin:{plugins['qf']}"
    run = simulate_isolated(scn, law=law, engine="cpp", duration=70.0)
    assert run.is_stored and len(run) == 70_001
    t = run["t"]  # read from the file the child wrote
    np.testing.assert_allclose(t, np.arange(70_001) / 1000.0, rtol=0, atol=1e-9)
    where = run.path.parent
    assert where.exists()
    del run, t
    gc.collect()
    assert not where.exists()  # removed with the parent's copy, not left behind


def test_compare_of_a_long_plugin_run(plugins, tmp_path):
    law = f"plugin:{plugins['qf']}"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "compare", "ppc_feasible_1khz", "--law", law,
                        "--law", "pd", "--duration", "70", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    rows = json.loads((tmp_path / "compare.json").read_text())["rows"]
    assert [row["valid"] for row in rows] == [True, True]
