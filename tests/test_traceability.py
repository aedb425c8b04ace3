"""Every run, offline too, records what it was made from (issue 41 item 5):
the scenario file and its SHA-256, the overrides, the law's parameters as
run (defaults filled in), sc-rt's version and commit; report.html shows
them. Checked against hashlib, the core's declared defaults and the file's
own table, and git, not against the record itself."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
import tomllib
from pathlib import Path

import sc_rt
from sc_rt import _core
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
LIB = ROOT / "python" / "sc_rt" / "scenario" / "library"


def test_a_sim_records_its_inputs(tmp_path):
    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", "paper_faults", "--engine", "cpp", "--duration",
                        "2", "--control-rate", "20", "--out", str(out), "--no-plots"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    meta = json.loads(str(load_traj(out)["meta_json"]))
    inp = meta["inputs"]
    src = LIB / "paper_faults.toml"
    assert Path(inp["scenario_file"]).resolve() == src.resolve()
    assert inp["scenario_sha256"] == hashlib.sha256(src.read_bytes()).hexdigest()
    assert inp["overrides"] == {"run.duration": 2.0, "run.control_rate_hz": 20.0}
    # the law's parameters: the core's declared defaults under the file's own [laws.dsc-ppc] table
    table = tomllib.loads(src.read_text()).get("laws", {}).get("dsc-ppc", {})
    expected = {k: float(v[0]) for k, v in dict(_core.law_info("dsc-ppc")["defaults"]).items()}
    expected.update({k: float(v) for k, v in table.items()})
    assert inp["law_params"] == expected
    assert inp["sc_rt_version"] == sc_rt.__version__
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True)
    if head.returncode == 0:  # a checkout: the commit it runs
        assert inp["sc_rt_commit"].startswith(head.stdout.strip())
    html = (out / "report.html").read_text()
    assert inp["scenario_sha256"] in html and "override run.duration" in html
