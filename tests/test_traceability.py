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
    # metrics.json, the file a gate reads, carries them too
    assert json.loads((out / "metrics.json").read_text())["inputs"] == inp


def _sha(name: str) -> str:
    return hashlib.sha256((LIB / f"{name}.toml").read_bytes()).hexdigest()


def test_compare_and_montecarlo_record_their_inputs(tmp_path):
    """compare.json holds each law's inputs, montecarlo.json the campaign's
    base plan's (its runs' draws are in the dataset): the file's hash by
    hashlib, each law's parameters by the core's declared defaults."""
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "compare", "paper_fault_free", "--law", "pd", "--law",
                        "dsc", "--duration", "1", "--out", str(tmp_path / "c")], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    inputs = json.loads((tmp_path / "c" / "compare.json").read_text())["inputs"]
    assert set(inputs) == {"pd", "dsc"}
    table = tomllib.loads((LIB / "paper_fault_free.toml").read_text()).get("laws", {})
    for law, inp in inputs.items():
        assert inp["scenario_sha256"] == _sha("paper_fault_free")
        # a per-axis default is three numbers, a scalar one
        expected = {k: float(v[0]) if len(v) == 1 else [float(x) for x in v]
                    for k, v in dict(_core.law_info(law)["defaults"]).items()}
        expected.update({k: v for k, v in table.get(law, {}).items()})
        assert inp["law_params"] == expected, law
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "montecarlo", "paper_fault_free", "--runs", "2",
                        "--workers", "1", "--set", "run.duration=1.0", "--out", str(tmp_path / "m")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    inp = json.loads((tmp_path / "m" / "montecarlo.json").read_text())["inputs"]
    assert inp["scenario_sha256"] == _sha("paper_fault_free") and inp["sc_rt_version"] == sc_rt.__version__
