"""Every law's parameters in one scenario (issue #26, items 1 and 2): the
built-in laws take their gains through the same door as a plugin (their
own table, ``[laws.NAME]``), so one file serves ``compare`` across a
built-in, a plugin and a Python law, each with its own table; older files
keep loading; a log written before the change still reports.

Each law is proved to run with its own table by its first command, computed
here in numpy from that table (refmath), not by the law."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.logs.logread import read_log
from sc_rt.scenario.overrides import with_overrides
from sc_rt.plan.run import plan_run
from sc_rt.scenario.reader import load_scenario
from sc_rt.scenario.schema import ScenarioError
from sc_rt.sim.engines import simulate

from test_laws import _qf_expected
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
PY_PD = f"{ROOT}/examples/python_laws/pd.py:PythonPD"

TABLES = """
[laws.pd]
beta1 = 0.2
beta2 = 0.5

[laws.quaternion-feedback]
k = 0.05
c = 0.3

[laws.python-pd]
beta1 = 0.3
beta2 = 0.7
"""


def _pd_first(scn, beta1, beta2) -> np.ndarray:
    """-B+ (beta1 x1 + beta2 x2) at the initial state, in numpy."""
    import refmath

    x = np.concatenate([scn.initial.sigma_BN, scn.initial.omega_BN_B])
    x1 = refmath.mrp_sub(x[0:3], scn.guidance.sigma_d0)
    wd = scn.guidance.omega_bias + scn.guidance.omega_cos
    x2 = x[3:6] - refmath.R(x1) @ wd
    p = scn.plant
    B = -np.linalg.inv(p.J0) @ p.Cbar @ np.diag(p.Jw)
    return -np.linalg.pinv(B) @ (beta1 * x1 + beta2 * x2)


@pytest.fixture
def many(tmp_path):
    path = tmp_path / "many.toml"
    path.write_text((ROOT / "scenarios" / "paper_fault_free.toml").read_text() + TABLES)
    return path


def test_each_law_runs_its_own_table(many, plugins):
    scn = load_scenario(many)
    assert [name for name, _ in scn.controller.laws] == ["dsc-ppc", "pd", "quaternion-feedback", "python-pd"]
    plugin = "plugin:" + str(plugins["qf"])
    first = {law: simulate(with_overrides(scn, law=law), engine="cpp", duration=1.0)["u_cmd"][0]
             for law in ("pd", plugin)}
    first["py"] = simulate(scn, law=PY_PD, duration=1.0)["u_cmd"][0]
    x0 = np.concatenate([scn.initial.sigma_BN, scn.initial.omega_BN_B, scn.initial.wheel_speed])
    np.testing.assert_allclose(first["pd"], _pd_first(scn, 0.2, 0.5), rtol=1e-9)
    np.testing.assert_allclose(first["py"], _pd_first(scn, 0.3, 0.7), rtol=1e-9)
    np.testing.assert_allclose(first[plugin], _qf_expected(scn, x0, k=0.05, c=0.3), rtol=1e-9)
    # the file's own law runs its table (the paper's values) as before: not the PD's
    assert not np.allclose(simulate(scn, engine="cpp", duration=1.0)["u_cmd"][0], first["pd"])


@pytest.mark.slow  # ~6 s: four runs and the plugin's child process
def test_compare_runs_a_built_in_a_plugin_and_a_python_law_from_one_file(many, plugins, tmp_path):
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "compare", str(many), "--duration", "20",
                        "--law", "dsc-ppc", "--law", "pd", "--law", "plugin:" + str(plugins["qf"]), "--law", PY_PD,
                        "--out", str(tmp_path / "c")], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    rows = json.loads((tmp_path / "c" / "compare.json").read_text())["rows"]
    assert [row["law"] for row in rows] == ["dsc-ppc", "pd", "quaternion-feedback", "python-pd"]
    assert all(row["valid"] for row in rows)


@pytest.mark.parametrize("old, new, key, fragment", [
    ("beta1 = 0.2", "beta1 = -0.2", "laws.pd.beta1", "must be > 0, got -0.2"),
    ("beta2 = 0.5", "beta2 = 0.5\nbeta3 = 1", "laws.pd.beta3", "unknown parameter"),
    ("beta2 = 0.5", "beta2 = [0.5, 0.5]", "laws.pd.beta2", "must be one number"),
])
def test_a_table_of_a_built_in_law_is_checked_by_that_law(many, old, new, key, fragment):
    text = many.read_text().replace(old, new, 1)
    many.write_text(text)
    with pytest.raises(ScenarioError) as e:
        load_scenario(many)
    [x] = e.value.errors
    assert x.key == key and fragment in x.message, str(e.value)
    assert key.split(".")[-1] in text.splitlines()[x.line - 1]


def test_an_older_file_loads_with_one_note_and_runs_the_same(tmp_path):
    # the paper file as it was written before [laws]: the tables of its four laws under [controller]
    new = (ROOT / "scenarios" / "paper_faults.toml").read_text()
    start, end = new.index("[laws.dsc-ppc]"), new.index("[controller.safety]")
    table = new[start:end]
    neso = "\n".join(line.replace("neso_", "", 1) for line in table.splitlines() if line.startswith("neso_"))
    dsc = "\n".join(line for line in table.splitlines() if line[:2] in ("k1", "k2", "k3", "k4", "k6", "ta"))
    old = new[:start] + (f"[controller.neso]\n{neso}\n\n[controller.dsc]\n{dsc}\n\n"
                         "[controller.pd]\nbeta1 = 0.3\nbeta2 = 0.6\n\n") + new[end:]
    path = tmp_path / "old.toml"
    path.write_text(old)
    scn = load_scenario(path)
    assert len(scn.deprecations) == 1 and "[controller.dsc], [controller.neso], [controller.pd]" in scn.deprecations[0]
    assert scn.controller.resolved("pd")["beta1"] == 0.3
    assert scn.controller.resolved("dsc")["neso_alpha"] == 0.7  # the paper's two laws share the old tables
    same = simulate(load_scenario(ROOT / "scenarios" / "paper_faults.toml"), engine="cpp", duration=30.0)
    run = simulate(scn, engine="cpp", duration=30.0)
    assert np.array_equal(run["sigma_BN"], same["sigma_BN"]) and np.array_equal(run["z2"], same["z2"])
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", str(path), "--engine", "cpp", "--duration", "1",
                        "--no-plots", "--out", str(tmp_path / "o")], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("sc-rt: note:") == 1 and "write them so" in r.stderr
    # a bad value in an older table is named where it is written
    path.write_text(old.replace("beta1 = 0.3", "beta1 = 0.0"))
    with pytest.raises(ScenarioError) as e:
        load_scenario(path)
    assert [x.key for x in e.value.errors] == ["controller.pd.beta1"]


def test_a_log_written_before_the_change_still_reports(tmp_path):
    """tests/data/v1_paper_faults_lockstep_3s.lcmlog: a 3 s lockstep run of
    paper_faults written by sc-rt before this change (its controller_config_t
    of the older layout). Its configuration reads (the gains moved into the
    law's table), and its report equals the run the code makes now."""
    log = ROOT / "tests" / "data" / "v1_paper_faults_lockstep_3s.lcmlog"
    d = read_log(log)
    assert d.channels["SCRT_CONFIG"]["undecodable"] == 0
    [(_, cfg)] = d.messages["SCRT_CONFIG"]
    assert cfg.law == "dsc-ppc" and cfg.law_api_version == _core.LAW_API_VERSION
    table = dict(zip(cfg.law_param_keys, (v for v in np.split(np.array(cfg.law_param_values),
                                                                   np.cumsum(cfg.law_param_len)[:-1]))))
    assert table["k2"].tolist() == [4.0] and table["neso_k1"].tolist() == [0.2, 0.2, 0.2]
    core = _core.ControllerConfig.from_lcm_bytes(cfg.encode())  # the core takes it as a config of today
    assert core.law == "dsc-ppc" and dict(core.law_params)["tau"] == [0.1]
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "report", str(log), "--out", str(tmp_path / "r")],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    m = json.loads((tmp_path / "r" / "metrics.json").read_text())
    sim = simulate(load_scenario("paper_faults"), engine="python", duration=3.0).metrics
    for k in ("steps", "first_bound_violation_s", "max_abs_u_cmd", "saturated_fraction"):
        assert m[k] == sim[k], k


def _python_law_file(tmp_path: Path) -> Path:
    """paper_fault_free running examples/python_laws/pd.py:PythonPD, named in the
    file by a path relative to it, with the law's own table."""
    text = (ROOT / "scenarios" / "paper_fault_free.toml").read_text()
    rel = Path("../" * len(tmp_path.relative_to("/").parts)) / ROOT.relative_to("/") / "examples/python_laws/pd.py"
    text = text.replace("[controller]\n", f'[controller]\nlaw = "python:{rel.as_posix()}:PythonPD"\n', 1)
    text = text.replace('controller = "dsc-ppc"', "", 1)
    path = tmp_path / "pylaw.toml"
    path.write_text(text + "\n[laws.python-pd]\nbeta1 = 0.3\nbeta2 = 0.7\n")
    return path


def test_a_scenario_names_a_python_law_which_gets_its_table(tmp_path):
    scn = load_scenario(_python_law_file(tmp_path))
    assert scn.run.controller == f"python:{ROOT}/examples/python_laws/pd.py:PythonPD"  # made absolute
    run = simulate(scn, duration=1.0)  # the python engine runs it
    assert run.meta.law == "python-pd"
    np.testing.assert_allclose(run["u_cmd"][0], _pd_first(scn, 0.3, 0.7), rtol=1e-9)
    # inside the core's Controller (issue #26 item 4): the cpp engine runs it too, bitwise the same
    cpp = simulate(scn, duration=1.0, engine="cpp")
    for k in ("sigma_BN", "omega_BN_B", "wheel_speed", "u_cmd", "e1", "e2", "flags"):
        assert np.array_equal(run[k], cpp[k]), k
    bad = tmp_path / "bad.toml"
    bad.write_text((tmp_path / "pylaw.toml").read_text().replace("pd.py:PythonPD", "pd.py:NoSuchLaw"))
    with pytest.raises(ScenarioError) as e:  # the law is loaded where the run is planned (issue 38 item 2)
        plan_run(bad)
    [x] = e.value.errors
    assert x.key == "controller.law" and "has no class NoSuchLaw" in x.message


@pytest.mark.lcm
def test_a_python_law_named_by_the_scenario_runs_in_lockstep_bitwise(tmp_path):
    import lcmnet

    lcmnet.require()
    path = _python_law_file(tmp_path)
    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", str(path), "--mode", "lockstep", "--duration", "10", "--out", str(out), "--no-plots"])
    assert r.returncode == 0, r.stderr + r.stdout
    hil = load_traj(out)
    sim = simulate(load_scenario(path), duration=10.0)
    for name in ("sigma_BN", "omega_BN_B", "wheel_speed", "u_cmd"):
        assert np.array_equal(hil[name], sim[name]), name


def test_the_fixed_telemetry_slots_are_recorded_offline():
    """x2d and rho_hat (LawOutput's slots) are run fields of both engines,
    bitwise equal; RFT's rho_hat follows its adaptation law computed here
    from the recorded sliding variable (e2 = s), and DSC's x2d is x2 - e2 (27)."""
    scn = load_scenario("paper_faults")
    rft = {e: simulate(scn, engine=e, law="rft", duration=30.0) for e in ("python", "cpp")}
    assert np.array_equal(rft["python"]["rho_hat"], rft["cpp"]["rho_hat"])
    p = scn.controller.resolved("rft")
    s_norm = np.linalg.norm(rft["cpp"]["e2"], axis=1)
    dt = 1.0 / scn.run.control_rate_hz
    a = np.exp(-p["leak"] * dt)
    rho = [p["rho0"]]
    for k in range(1, len(s_norm)):
        rho.append(a * rho[-1] + (1 - a) / p["leak"] * p["gain"] * s_norm[k - 1])
    np.testing.assert_allclose(rft["cpp"]["rho_hat"], rho, rtol=1e-12, atol=1e-15)
    assert rft["cpp"]["rho_hat"][-1] > 0
    dsc = {e: simulate(scn, engine=e, duration=30.0) for e in ("python", "cpp")}
    assert np.array_equal(dsc["python"]["x2d"], dsc["cpp"]["x2d"])
    np.testing.assert_allclose(dsc["cpp"]["x2d"], dsc["cpp"]["omega_BD_B"] - dsc["cpp"]["e2"], rtol=0, atol=1e-15)
    assert np.abs(dsc["cpp"]["x2d"]).max() > 1e-3
    assert np.all(rft["cpp"]["x2d"] == 0.0)  # a law that does not use the slot leaves it at 0
