"""Every engine runs the law it names or refuses it (issue #25, case 1 and
item 4): engine (python, cpp, unsampled, the sensed loop) x law kind
(built-in, plugin, Python class) x command (sim, compare, montecarlo, hil
lockstep). A run is proved to be its law by a law-specific signature in its
output, not by its label: the first command, which for each law here is a
value computed independently of the run (the built-in RFT's one step of
the core, the quaternion-feedback plugin's formula in numpy, the Python
law's fixed command). A refusal is exit 2 and one line, nothing written.

Before, `sim --engine unsampled --law plugin:...` ran the built-in RFT under
the plugin's name (bitwise --law rft)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.scenario.reader import load_scenario

import lcmnet
import plugbuild
from test_laws import _qf_expected
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
FIXED = np.array([1e-3, -2e-3, 3e-3, -4e-3])
PYLAW = '''
import numpy as np


class Fixed:
    name = "fixed-command"

    def __init__(self, setup):
        pass

    def reset(self, inp):
        pass

    def step(self, inp):
        return np.array([1e-3, -2e-3, 3e-3, -4e-3])
'''


@pytest.fixture(scope="module")
def laws(tmp_path_factory) -> dict[str, str]:
    d = tmp_path_factory.mktemp("door")
    plugbuild.build(ROOT / "examples" / "quaternion_feedback", d / "qf")
    (d / "fixedlaw.py").write_text(PYLAW)
    return {"builtin": "rft", "plugin": f"plugin:{d / 'qf' / 'libquaternion_feedback.so'}",
            "python": f"{d / 'fixedlaw.py'}:Fixed"}


def _x0(scn) -> np.ndarray:
    return np.concatenate([scn.initial.sigma_BN, scn.initial.omega_BN_B, scn.initial.wheel_speed])


def _signature(kind: str, spec: str, scn) -> np.ndarray:
    """The law's first command, computed apart from the run."""
    x = _x0(scn)
    if kind == "python":
        return FIXED
    if kind == "plugin":
        return _qf_expected(scn, x)  # the plugin's default gains k = 0.08, c = 0.4
    ctl = _core.Controller(scn.core_config(law=spec))
    m = _core.Measurement(0.0, x[0:3], x[3:6], x[6:10])
    ctl.reset(m)
    return np.asarray(ctl.step(m).u_cmd)


def _cli(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "sc_rt.cli", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=300)


def _refused(r: subprocess.CompletedProcess, out: Path) -> None:
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not out.exists()


# engine -> law kinds it runs (the others it refuses)
# issue #26 item 4: a Python law runs inside the core's controller, so on the cpp engine too
SIM = {"python": {"builtin", "plugin", "python"}, "cpp": {"builtin", "plugin", "python"}, "unsampled": {"builtin"}}


@pytest.mark.parametrize("engine", sorted(SIM))
@pytest.mark.parametrize("kind", ["builtin", "plugin", "python"])
def test_sim(laws, tmp_path, engine, kind):
    spec, out = laws[kind], tmp_path / "o"
    r = _cli(["sim", "paper_fault_free", "--engine", engine, "--law", spec, "--duration", "2", "--out", str(out),
              "--no-plots"], tmp_path)
    if kind not in SIM[engine]:
        return _refused(r, out)
    assert r.returncode == 0, r.stderr
    u0 = load_traj(out)["u_cmd"][0]
    want = _signature(kind, spec, load_scenario("paper_fault_free"))
    np.testing.assert_allclose(u0, want, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("engine", ["python", "cpp"])
@pytest.mark.parametrize("kind", ["builtin", "plugin", "python"])
def test_sim_with_sensors(laws, tmp_path, engine, kind):
    """The sensed loop (an estimate in the loop) runs every kind of law (a
    Python law inside the core's controller: issue #26 item 4).
    The law sees the estimate, not the truth, so its first command is near
    its truth-fed signature, not equal to it: the run is the law whose
    signature is nearest, far nearer than the others'."""
    spec, out = laws[kind], tmp_path / "o"
    r = _cli(["sim", "paper_faults_sensors", "--engine", engine, "--law", spec, "--duration", "2", "--out",
              str(out), "--no-plots"], tmp_path)
    assert r.returncode == 0, r.stderr
    u0 = load_traj(out)["u_cmd"][0]
    scn = load_scenario("paper_faults_sensors")
    dist = {k: float(np.linalg.norm(u0 - _signature(k, laws[k], scn))) for k in ("builtin", "plugin", "python")}
    nearest = min(dist, key=dist.get)
    assert nearest == kind and all(dist[k] > 10 * dist[kind] for k in dist if k != kind), dist


@pytest.mark.parametrize("kind", ["builtin", "plugin", "python"])
def test_compare(laws, tmp_path, kind):
    spec, out = laws[kind], tmp_path / "o"
    r = _cli(["compare", "paper_fault_free", "--law", spec, "--law", "pd", "--duration", "2", "--out", str(out)],
             tmp_path)
    assert r.returncode == 0, r.stderr
    rows = json.loads((out / "compare.json").read_text())["rows"]
    assert [x["valid"] for x in rows] == [True, True]


@pytest.mark.parametrize("kind", ["builtin", "plugin", "python"])
def test_montecarlo(laws, tmp_path, kind):
    spec, out = laws[kind], tmp_path / "o"
    r = _cli(["montecarlo", "paper_fault_free", "--runs", "2", "--workers", "1", "--law", spec, "--out", str(out)],
             tmp_path)
    assert r.returncode == 0, r.stderr  # a Python law too: each worker registers it (issue #26 item 4)
    assert json.loads((out / "montecarlo.json").read_text())["status"]["ok"] == 2


@pytest.mark.lcm
@pytest.mark.parametrize("kind", ["builtin", "plugin", "python"])
def test_hil_lockstep(laws, tmp_path, kind):
    lcmnet.require()
    spec, out = laws[kind], tmp_path / "o"
    r = lcmnet.run_cli(["hil", "paper_fault_free", "--law", spec, "--mode", "lockstep", "--duration", "2", "--out",
                        str(out), "--no-plots"])
    assert r.returncode == 0, r.stderr
    u0 = load_traj(out)["u_cmd"][0]
    np.testing.assert_allclose(u0, _signature(kind, spec, load_scenario("paper_fault_free")), rtol=1e-9, atol=1e-12)
