"""A run is planned once (issue 38 items 1 and 2): the law spec is parsed
where the plan is built and nowhere below it; ``load_scenario`` on a file
naming a Python law or a plugin runs no law code and starts no process (the
law is loaded and probed where the run is planned); ``run_hil`` takes a
plan; the plan round-trips through the run's recorded inputs.

Each of these fails on the main before the plan (noted per test)."""

from __future__ import annotations

import argparse
import hashlib
import inspect
import json
import multiprocessing
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt.scenario.reader import load_scenario
from sc_rt.scenario.schema import ScenarioError
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
PAPER = ROOT / "scenarios" / "paper_fault_free.toml"

#: a Python law whose import has a side effect: it appends a line to the file
#: named by $SCRT_TEST_IMPORTED and to a list of this test module's own
SIDE_EFFECT = '''
import os

import numpy as np

with open(os.environ["SCRT_TEST_IMPORTED"], "a") as f:
    f.write("imported\\n")


class Loud:
    name = "loud"

    def __init__(self, setup):
        self.k = setup.params.get("k", 1.0)
        if not self.k > 0:
            from sc_rt.pylaw import LawParamError

            raise LawParamError("k", f"k must be > 0, got {self.k}")

    def reset(self, inp):
        pass

    def step(self, inp):
        return -self.k * np.ones(4) * 0.0
'''


def _law_scenario(tmp_path: Path, table: str = "") -> Path:
    (tmp_path / "loud.py").write_text(SIDE_EFFECT)
    text = PAPER.read_text().replace('controller = "dsc-ppc"', 'controller = "python:loud.py:Loud"', 1)
    path = tmp_path / "s.toml"
    path.write_text(text + table)
    return path


@pytest.fixture
def imported(tmp_path, monkeypatch):
    """The side-effect file of SIDE_EFFECT (absent until the law is imported)."""
    path = tmp_path / "imported.txt"
    monkeypatch.setenv("SCRT_TEST_IMPORTED", str(path))
    return path


def _no_processes(monkeypatch):
    """Every way to start a process raises (os.fork, subprocess, multiprocessing)."""
    def refuse(*_a, **_k):
        raise AssertionError("a process was started")

    monkeypatch.setattr(os, "fork", refuse)
    monkeypatch.setattr(subprocess, "Popen", refuse)
    monkeypatch.setattr(multiprocessing.Process, "start", refuse)


def test_load_scenario_naming_a_python_law_runs_no_law_code_and_starts_no_process(tmp_path, imported, monkeypatch):
    # fails on the old main: load_scenario imported the law and probed it in a forked child
    path = _law_scenario(tmp_path, "\n[laws.loud]\nk = -1.0\n")
    _no_processes(monkeypatch)
    before = set(sys.modules)
    scn = load_scenario(path)
    assert not imported.exists()  # the module's top level never ran
    assert not [m for m in set(sys.modules) - before if m.startswith("sc_rt_user_law_")]
    assert scn.run.controller == f"python:{tmp_path / 'loud.py'}:Loud"  # a path made absolute, not loaded
    assert dict(scn.controller.table("loud")) == {"k": (-1.0,)}  # the table kept, unchecked here


def test_load_scenario_naming_a_plugin_loads_no_library(tmp_path, monkeypatch):
    # fails on the old main: law_table_name loaded the library (law_info) and check_law forked its probe
    from sc_rt import _core

    text = PAPER.read_text().replace('controller = "dsc-ppc"', 'controller = "plugin:./nowhere/libx.so"', 1)
    (tmp_path / "p.toml").write_text(text)
    _no_processes(monkeypatch)
    monkeypatch.setattr(_core, "law_info", lambda *_a: (_ for _ in ()).throw(AssertionError("loaded")))
    scn = load_scenario(tmp_path / "p.toml")
    assert scn.run.controller == f"plugin:{tmp_path / 'nowhere/libx.so'}"


def test_the_plan_loads_and_probes_the_law_once_with_its_table(tmp_path, imported):
    # fails on the old main: there is no sc_rt.plan (the probe ran in load_scenario)
    from sc_rt.plan.law import PythonLaw
    from sc_rt.plan.run import plan_run

    bad = _law_scenario(tmp_path, "\n[laws.loud]\nk = -1.0\n")
    with pytest.raises(ScenarioError) as e:
        plan_run(bad)
    [issue] = e.value.errors
    assert (issue.key, issue.value) == ("laws.loud.k", -1.0)
    assert issue.message == f"law loud (python:{tmp_path / 'loud.py'}:Loud): k must be > 0, got -1.0"
    assert issue.line == len(bad.read_text().splitlines())  # the file's own line of k
    good = _law_scenario(tmp_path, "\n[laws.loud]\nk = 2.0\n")
    plan = plan_run(good)
    want = hashlib.sha256((tmp_path / "loud.py").read_bytes()).hexdigest()
    assert plan.law == PythonLaw(spec=f"python:{tmp_path / 'loud.py'}:Loud", name="loud",
                                 module=str(tmp_path / "loud.py"), sha256=want)
    assert imported.read_text() == "imported\n"  # imported once, in this process (the probe's child forks)


def _hil_args(argv: list[str]) -> argparse.Namespace:
    from sc_rt.cli.main import build_parser

    return build_parser().parse_args(argv)


class _Reached(Exception):
    pass


def test_hil_parses_the_law_spec_once_and_run_hil_takes_the_plan(tmp_path, monkeypatch):
    # fails on the old main: cmd_hil handed run_hil the scenario and ~20 keyword arguments,
    # and the spec was parsed at each stop (is_python_law in cli/controller.py, hil/runner.py, ...)
    from sc_rt.cli import run_cmds
    from sc_rt.hil import runner
    from sc_rt.plan import law as planlaw
    from sc_rt.plan.law import PythonLaw
    from sc_rt.plan.run import RunPlan

    law_file = ROOT / "examples" / "python_laws" / "pd.py"
    calls, seen = [], []
    real = planlaw.law_ref
    monkeypatch.setattr(planlaw, "law_ref", lambda spec: calls.append(spec) or real(spec))

    def fake_run_hil(plan, **runtime):
        seen.append((plan, runtime))
        raise _Reached

    monkeypatch.setattr(runner, "run_hil", fake_run_hil)
    args = _hil_args(["hil", "paper_fault_free", "--law", f"{law_file}:PythonPD", "--mode", "realtime",
                      "--duration", "2", "--control-rate", "20", "--prefix", "P_", "--trigger", "timer",
                      "--floor", "off", "--time-scale", "2", "--out", str(tmp_path / "o"), "--no-plots"])
    with pytest.raises(_Reached):
        run_cmds.cmd_hil(args)
    assert calls == [f"python:{law_file}:PythonPD"]  # parsed once, where the plan is built
    [(plan, runtime)] = seen
    assert isinstance(plan, RunPlan) and runtime == {}
    assert plan.law == PythonLaw(spec=f"python:{law_file}:PythonPD", name="python-pd", module=str(law_file),
                                 sha256=hashlib.sha256(law_file.read_bytes()).hexdigest())
    assert (plan.engine, plan.timing.mode, plan.timing.time_scale, plan.timing.setup.trigger) == (
        "bench", "realtime", 2.0, "timer")
    assert plan.timing.floor is None and plan.timing.priority is True  # real time: priority by default
    assert (plan.scenario.run.duration, plan.scenario.run.control_rate_hz) == (2.0, 20.0)
    assert plan.bus.prefix == "P_" and plan.outputs.plots is False and plan.outputs.out == tmp_path / "o"
    assert plan.scenario.run.controller == plan.law.spec


def test_run_hil_takes_a_plan_and_a_handful_of_runtime_arguments():
    # fails on the old main: run_hil(scn, *, out, mode, law, ... 20 keyword arguments)
    from sc_rt.hil.runner import run_hil

    params = list(inspect.signature(run_hil).parameters.values())
    assert params[0].name == "plan" and params[0].kind is inspect.Parameter.POSITIONAL_OR_KEYWORD
    assert len(params) <= 4 and all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in params[1:])


def test_the_plan_round_trips_through_the_records_inputs(tmp_path):
    # fails on the old main: no plan, and RunMeta.inputs held no law reference, engine or set-up
    from sc_rt.plan.run import Outputs, plan_from_inputs, plan_run
    from sc_rt.results.present.output import write_run
    from sc_rt.scenario.reader import parse_set
    from sc_rt.sim.isolated import simulate_plan

    plan = plan_run("paper_fault_free", sets=[parse_set("laws.pd.beta1=0.07")], law="pd", engine="cpp",
                    duration=2.0, outputs=Outputs(out=tmp_path / "a", plots=False))
    run = simulate_plan(plan)
    write_run(run, tmp_path / "a", figures=False)
    inputs = json.loads(str(load_traj(tmp_path / "a")["meta_json"]))["inputs"]
    # against independent values: the file's bytes, the overrides as given
    assert inputs["scenario_sha256"] == hashlib.sha256(PAPER.read_bytes()).hexdigest()
    assert inputs["overrides"] == {"set laws.pd.beta1": 0.07, "run.controller": "pd", "run.duration": 2.0}
    assert inputs["plan"]["law"] == {"kind": "builtin", "name": "pd"} and inputs["plan"]["engine"] == "cpp"
    assert inputs["law_params"]["beta1"] == 0.07
    again = plan_from_inputs(inputs, out=tmp_path / "b")
    assert again.inputs() == {**plan.inputs(), "plan": {**plan.inputs()["plan"], "outputs": {
        "out": str(tmp_path / "b"), "plots": False, "mcap": None}}}
    assert again.law == plan.law and again.scenario.run == plan.scenario.run
    rerun = simulate_plan(again)
    for k in ("sigma_BN", "omega_BN_B", "wheel_speed", "u_cmd"):
        assert (rerun[k] == run[k]).all(), k  # the same plan, the same run, bitwise


def test_a_changed_scenario_file_is_not_replayed(tmp_path):
    from sc_rt.plan.run import Outputs, plan_from_inputs, plan_run

    path = tmp_path / "s.toml"
    path.write_text(PAPER.read_text())
    inputs = plan_run(path, duration=1.0, outputs=Outputs(out=tmp_path / "a")).inputs()
    path.write_text(PAPER.read_text() + "\n# edited\n")
    with pytest.raises(ValueError, match="changed since the run"):
        plan_from_inputs(inputs)


def test_rerun_replays_the_plan_a_sim_recorded(tmp_path):
    # fails on the old main: there is no `sc-rt rerun` (and no plan in a run's inputs)
    from sc_rt.cli.main import main

    a, b = tmp_path / "a", tmp_path / "b"
    assert main(["sim", "paper_fault_free", "--law", "pd", "--engine", "cpp", "--duration", "3",
                 "--set", "laws.pd.beta2=0.3", "--out", str(a), "--no-plots"]) == 0
    assert main(["rerun", str(a), "--out", str(b)]) == 0
    first, again = (json.loads(str(load_traj(d)["meta_json"]))["inputs"] for d in (a, b))
    assert again["plan"].pop("outputs") == {"out": str(b), "plots": False, "mcap": None}
    first["plan"].pop("outputs")
    assert again == first  # the same plan: file, overrides, law, engine, timing, bus
    assert first["overrides"] == {"set laws.pd.beta2": 0.3, "run.controller": "pd", "run.duration": 3.0}
    ta, tb = load_traj(a), load_traj(b)
    for k in ("sigma_BN", "omega_BN_B", "wheel_speed", "u_cmd"):
        assert np.array_equal(ta[k], tb[k]), k


def test_rerun_of_a_run_without_a_plan_is_one_line(tmp_path, capsys):
    from sc_rt.cli.main import main

    assert main(["rerun", str(tmp_path / "nothing"), "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"sc-rt rerun: {tmp_path / 'nothing'}: no run to replay"), err


@pytest.mark.lcm
def test_rerun_replays_the_plan_a_lockstep_hil_run_recorded(tmp_path):
    """The bench's plan (mode, trigger, prefix, the law's reference) through
    the record and back: the rerun records the same plan, and a lockstep
    run equals its rerun bitwise (both equal the offline run, docs/HIL.md)."""
    import lcmnet

    lcmnet.require()
    a, b = tmp_path / "a", tmp_path / "b"
    r = lcmnet.run_cli(["hil", "paper_fault_free", "--mode", "lockstep", "--law", "pd", "--duration", "2",
                        "--prefix", "RP_", "--set", "laws.pd.beta1=0.04", "--out", str(a), "--no-plots"])
    assert r.returncode == 0, r.stderr
    r = lcmnet.run_cli(["rerun", str(a), "--out", str(b)])
    assert r.returncode == 0, r.stderr
    first, again = (json.loads(str(load_traj(d)["meta_json"]))["inputs"] for d in (a, b))
    assert again["plan"].pop("outputs")["out"] == str(b)
    first["plan"].pop("outputs")
    assert again == first
    assert first["plan"]["engine"] == "bench" and first["plan"]["timing"]["mode"] == "lockstep"
    assert first["plan"]["bus"]["prefix"] == "RP_" and first["plan"]["law"] == {"kind": "builtin", "name": "pd"}
    ta, tb = load_traj(a), load_traj(b)
    for k in ("sigma_BN", "omega_BN_B", "wheel_speed", "u_cmd"):
        assert np.array_equal(ta[k], tb[k]), k
