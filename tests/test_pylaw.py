"""Python laws (sc_rt.pylaw): the contract, a Python law inside the core's
Controller (the pybind11 trampoline) checked step by step against the C++
PD through every branch of Controller::step, its failures contained by the
core's policy, and the example PD against the core's built-in PD on both
paper scenarios and every engine."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.pylaw import FLAG_LAW_INVALID, LawParamError, load_law, register
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate

from conftest import core_config
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
PD_SPEC = str(ROOT / "examples" / "python_laws" / "pd.py") + ":PythonPD"
COMPARED = ("sigma_BN", "omega_BN_B", "wheel_speed", "u_cmd", "u_sat", "wheel_accel", "sigma_DN",
            "sigma_BD", "omega_BD_B", "e1", "e2", "chi", "lam", "flags", "ctrl_mode", "delta2")


@pytest.mark.parametrize("scenario,engine", [("paper_fault_free", "python"), ("paper_faults", "python"),
                                             ("paper_faults", "cpp")])
def test_python_pd_equals_the_core_pd(scenario, engine):
    scn = load_scenario(scenario)
    core = simulate(scn, law="pd", engine=engine)
    py = simulate(scn, law=PD_SPEC, engine=engine)
    assert len(core) == len(py) == int(scn.run.duration * scn.run.control_rate_hz) + 1
    for k in COMPARED:
        a, b = np.asarray(core[k], float), np.asarray(py[k], float)
        assert np.allclose(a, b, rtol=0, atol=1e-12), (k, np.max(np.abs(a - b)))
    assert py.meta.law == "python-pd" and py.metrics["controller"] == "python-pd"
    for k in ("first_bound_violation_s", "saturated_fraction", "safe_steps"):
        assert py.metrics[k] == core.metrics[k], k


def test_cli_sim_with_a_python_law_equals_the_builtin(tmp_path):
    runs = {}
    for name, law in (("core", "pd"), ("py", PD_SPEC)):
        r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", "paper_faults", "--law", law,
                            "--duration", "20", "--no-plots", "--out", str(tmp_path / name)],
                           capture_output=True, text=True, cwd=tmp_path, timeout=120)
        assert r.returncode == 0, r.stderr
        runs[name] = load_traj(tmp_path / name)
    for k in COMPARED:
        assert np.allclose(runs["core"][k], runs["py"][k], rtol=0, atol=1e-12), k
    assert "python-pd" in (tmp_path / "py" / "metrics.json").read_text()


class _PD:
    """The PD for the step-by-step comparison (no file import)."""

    def __init__(self, setup):
        pd = dict(_core.law_info("pd")["defaults"])  # the built-in PD's gains (a default config's law table is empty)
        self.B_pinv, self.b1, self.b2 = setup.model.B_pinv, pd["beta1"][0], pd["beta2"][0]
        self.resets = 0

    def reset(self, inp):
        self.resets += 1

    def step(self, inp):
        return -self.B_pinv @ (self.b1 * inp.e.sigma_BD + self.b2 * inp.e.omega_BD_B), {
            "e1": inp.e.sigma_BD, "e2": inp.e.omega_BD_B}


def _states():
    """A measurement sequence through every branch of Controller::step:
    normal steps, saturation, an invalid (NaN) state, an out-of-range rate
    (finite: telemetry kept), re-engagement, time repeated and going back."""
    rng = np.random.default_rng(7)
    seq = []
    t = 0.0
    for k in range(40):
        x = np.concatenate([rng.uniform(-0.3, 0.3, 3), rng.uniform(-0.02, 0.02, 3),
                            rng.uniform(-50, 50, 4)])
        if k == 5:
            x[0:3] = [0.9, -0.8, 0.7]  # a large error: saturates
        if k == 10:
            x[3] = np.nan  # invalid: SAFE, no telemetry
        if k == 15:
            x[3:6] = [5.0, 0, 0]  # finite but beyond max_rate: SAFE with telemetry
        if k == 20:
            seq.append((t, x))  # the same time again: FLAG_TIME_NOT_ADVANCING
        if k == 25:
            t -= 0.05  # back in time
        seq.append((t, x))
        t += 0.1
    return seq


def _controller(cls, rate: float = 10.0, params=()):
    """The core's Controller running the Python law ``cls`` (sc_rt.pylaw.register)."""
    cfg = core_config("pd", rate)
    cfg.law = register(cls)
    cfg.law_params = list(params)
    return _core.Controller(cfg)


def _step(ctl, t, x):
    return ctl.step(_core.Measurement(t, x[0:3], x[3:6], x[6:10]))


FIELDS = ("u_cmd", "u_sat", "sigma_DN", "sigma_BD", "omega_BD_B", "e1", "e2", "z1", "z2", "chi", "lam", "x2d",
          "vs", "rho_hat", "mode", "flags")


@pytest.mark.parametrize("rate", [10.0, 50.0])
def test_a_python_pd_in_the_controller_matches_the_core_pd(rate):
    """The trampoline against the C++ PD, step by step, through every branch
    of Controller::step (saturation, an invalid state, a finite state past
    the safety limit, re-engagement, time repeated and going back)."""
    cpp = _core.Controller(core_config("pd", rate))
    py = _controller(_PD, rate)
    assert py.law_name == "_PD" and py.law_code == -1 and py.telemetry_names == []
    seq = _states()
    t0, x0 = seq[0]
    for c in (cpp, py):
        c.reset(_core.Measurement(t0, x0[0:3], x0[3:6], x0[6:10]))
    seen_flags = 0
    for t, x in seq:
        a, b = _step(cpp, t, x), _step(py, t, x)
        for k in FIELDS:
            assert np.allclose(getattr(a, k), getattr(b, k), rtol=0, atol=1e-12, equal_nan=True), (t, k)
        seen_flags |= a.flags
    for f in (_core.FLAG_INVALID_STATE, _core.FLAG_TIME_NOT_ADVANCING, _core.FLAG_SAT_1):
        assert seen_flags & f, f
    assert py.law_failures["step"] == 0 and py.law_failures["reset"] == 0


def test_named_telemetry_bad_commands_and_failures():
    class Named(_PD):
        telemetry_names = ("my_gain", "tau_x")

        def step(self, inp):
            return np.zeros(4), {"my_gain": 2.5, "z1": np.ones(3), "rho_hat": 0.5}

    x = np.zeros(10)
    ctl = _controller(Named)
    assert ctl.telemetry_names == ["my_gain", "tau_x"]
    ctl.reset(_core.Measurement(0.0, x[0:3], x[3:6], x[6:10]))
    c = _step(ctl, 0.0, x)
    assert c.telemetry[0] == 2.5 and c.telemetry[1] == 0.0 and list(c.z1) == [1.0, 1.0, 1.0] and c.rho_hat == 0.5

    # a wrong-shaped command or telemetry, or an undeclared name, is a failure
    # of the law, contained by the core like a raise or a NaN
    class Short(_PD):
        def step(self, inp):
            return np.zeros(3)

    class BadTelemetry(_PD):
        def step(self, inp):
            return np.zeros(4), {"x2d": np.ones(2)}

    class Undeclared(_PD):
        def step(self, inp):
            return np.zeros(4), {"my_gain": 1.0}

    for cls, what in ((Short, "u_cmd of shape (3,)"), (BadTelemetry, "telemetry 'x2d' of shape (2,)"),
                      (Undeclared, "telemetry 'my_gain' is not declared")):
        ctl = _controller(cls)
        ctl.reset(_core.Measurement(0.0, x[0:3], x[3:6], x[6:10]))
        c = _step(ctl, 0.0, x)
        assert c.mode == _core.MODE_SAFE and c.flags & _core.FLAG_LAW_INVALID
        f = ctl.law_failures
        assert f["step"] == 1 and what in f["last"]["what"], f


# What a law's step returns, not reshaped or converted: each a contained failure
# of the law, naming the shape or dtype (issue 40: these were accepted).
_NOT_A_COMMAND = [
    (np.zeros((2, 2)), "u_cmd of shape (2, 2), expected (4,)"),
    (np.zeros((4, 1)), "u_cmd of shape (4, 1), expected (4,)"),
    (np.zeros((1, 4)), "u_cmd of shape (1, 4), expected (4,)"),
    ([[0.0, 0.0], [0.0, 0.0]], "u_cmd of shape (2, 2), expected (4,)"),
    (0.0, "u_cmd of shape (), expected (4,)"),
    (np.zeros(4, bool), "u_cmd of dtype bool, expected real numbers"),
    ([True, False, True, False], "u_cmd of dtype bool, expected real numbers"),
    (np.zeros(4, complex), "u_cmd of dtype complex128, expected real numbers"),
    (np.array([0.0, 0.0, 0.0, 1j]), "u_cmd of dtype complex128, expected real numbers"),
    ([0.0, 0.0, None, 0.0], "u_cmd of dtype object, expected real numbers"),
    ("0000", "u_cmd of dtype <U4, expected real numbers"),
    ([[0.0], [0.0, 0.0]], "u_cmd is not an array of numbers"),
    ((np.zeros(4), {"z1": np.ones((3, 1))}), "telemetry 'z1' of shape (3, 1), expected (3,)"),
    ((np.zeros(4), {"rho_hat": np.ones((1, 1))}), "telemetry 'rho_hat' of shape (1, 1), expected (1,) or a scalar"),
    ((np.zeros(4), {"rho_hat": True}), "telemetry 'rho_hat' of dtype bool"),
    ((np.zeros(4), {"vs": np.zeros(4, complex)}), "telemetry 'vs' of dtype complex128"),
]


@pytest.mark.parametrize("returned, what", _NOT_A_COMMAND, ids=[w for _, w in _NOT_A_COMMAND])
def test_a_step_result_of_another_shape_or_dtype_is_a_law_failure(returned, what):
    class Returns(_PD):
        def step(self, inp):
            return returned

    x = np.zeros(10)
    ctl = _controller(Returns)
    ctl.reset(_core.Measurement(0.0, x[0:3], x[3:6], x[6:10]))
    c = _step(ctl, 0.0, x)
    assert c.mode == _core.MODE_SAFE and c.flags & _core.FLAG_LAW_INVALID and list(c.u_cmd) == [0.0] * 4
    f = ctl.law_failures
    assert f["step"] == 1 and what in f["last"]["what"], f


@pytest.mark.parametrize("returned", [
    [0, 0, 1, 0], (0.0, 0.0, 1.0, 0.0), np.array([0, 0, 1, 0], np.int32), np.array([0, 0, 1, 0], np.float32),
    (np.array([0, 0, 1, 0], np.uint8), {"rho_hat": 2, "z1": [1, 2, 3]}),
    (np.array([0.0, 0.0, 1.0, 0.0]), {"rho_hat": np.array([2.0]), "z1": np.arange(1.0, 4.0)}),
], ids=["ints", "tuple", "int32", "float32", "uint8+telemetry", "float64+telemetry"])
def test_real_numbers_of_the_right_shape_are_a_command(returned):
    class Returns(_PD):
        def step(self, inp):
            return returned

    x = np.zeros(10)
    ctl = _controller(Returns)
    ctl.reset(_core.Measurement(0.0, x[0:3], x[3:6], x[6:10]))
    c = _step(ctl, 0.0, x)
    assert c.mode != _core.MODE_SAFE and ctl.law_failures["step"] == 0, ctl.law_failures
    assert list(c.u_cmd) == [0.0, 0.0, 1.0, 0.0]
    if isinstance(returned, tuple) and len(returned) == 2:
        assert c.rho_hat == 2.0 and list(c.z1) == [1.0, 2.0, 3.0]


class ColumnCommand(_PD):
    """A law whose command is a (4, 1) column from t = 0.5 s (its probe at rest passes)."""

    def step(self, inp):
        return np.zeros((4, 1)) if inp.t >= 0.5 else np.zeros(4)


def test_a_run_of_a_law_returning_a_column_counts_its_failures_and_is_invalid():
    run = simulate(load_scenario("paper_fault_free"), law=ColumnCommand, duration=1.0)
    f = run.metrics["law_failures"]
    assert f["step"] == int(np.sum(run["t"] >= 0.5)) > 0, f
    assert "u_cmd of shape (4, 1), expected (4,)" in f["last"]["what"], f
    assert run.metrics["valid"] is False


class Exits(_PD):
    """A law that calls sys.exit(3) from t = 0.5 s."""

    def step(self, inp):
        if inp.t >= 0.5:
            sys.exit(3)
        return super().step(inp)


class Interrupts(_PD):
    """A law that raises KeyboardInterrupt itself from t = 0.5 s."""

    def step(self, inp):
        if inp.t >= 0.5:
            raise KeyboardInterrupt
        return super().step(inp)


@pytest.mark.parametrize("law, says", [(Exits, "SystemExit(3) raised by the law"),
                                       (Interrupts, "KeyboardInterrupt raised by the law")])
def test_a_law_that_exits_or_interrupts_itself_is_a_named_failure(law, says):
    """Issue 40 item 7: a law's own sys.exit(3) or KeyboardInterrupt is its
    failure, contained and named (it read "step at t = 0.5 s: 3" and an
    empty message), not the bench's end; the run goes on, invalid."""
    run = simulate(load_scenario("paper_fault_free"), law=law, duration=1.0)
    f = run.metrics["law_failures"]
    assert f["step"] == int(np.sum(run["t"] >= 0.5)) > 0, f
    assert says in f["last"]["what"], f
    assert run.metrics["valid"] is False and run["t"][-1] == 1.0


def test_telemetry_names_and_parameters_are_checked_at_setup():
    class TooMany(_PD):
        telemetry_names = [f"v{i}" for i in range(_core.LAW_MAX_TELEMETRY + 1)]

    class Slot(_PD):
        telemetry_names = ("z1",)

    for cls, what in ((TooMany, "at most"), (Slot, "not a fixed slot")):
        with pytest.raises(ValueError, match=what):
            _controller(cls)

    class Gains(_PD):
        def __init__(self, setup):
            super().__init__(setup)
            self.kp = setup.params.get("kp", 1.0)
            if not self.kp > 0:
                raise LawParamError("kp", "must be > 0")

    assert _controller(Gains, params=[("kp", [2.0])]).law_failures["step"] == 0
    with pytest.raises(ValueError, match=r"laws\.Gains\.kp: must be > 0"):
        _controller(Gains, params=[("kp", [-1.0])])
    with pytest.raises(ValueError, match=r"laws\.Gains\.kd: unknown parameter of law Gains"):
        _controller(Gains, params=[("kd", [1.0])])


def test_a_law_whose_reset_raises_at_reengagement_is_contained():
    class ResetOnce(_PD):
        resets = 0

        def reset(self, inp):
            ResetOnce.resets += 1
            if ResetOnce.resets > 1:
                raise RuntimeError("reset exploded")
            return super().reset(inp)

        def step(self, inp):
            if 0.25 < inp.t < 0.35:
                return np.full(4, np.nan)  # one SAFE step: the next one re-engages (reset)
            return super().step(inp)

    x = np.zeros(10)
    ctl = _controller(ResetOnce)
    ctl.reset(_core.Measurement(0.0, x[0:3], x[3:6], x[6:10]))
    assert ctl.law_failures["reset"] == 0
    modes = [_step(ctl, 0.1 * k, x).mode for k in range(6)]
    assert modes[:3] == [_core.MODE_NORMAL] * 3 and modes[3:] == [_core.MODE_SAFE] * 3
    f = ctl.law_failures
    assert f["step"] == 1 and f["reset"] == 2 and f["last"]["call"] == "reset"
    assert f["last"]["t"] == pytest.approx(0.5) and "RuntimeError: reset exploded" in f["last"]["what"]


@pytest.mark.parametrize("failure", ["nan", "raise"])
def test_an_invalid_law_command_is_safe_and_the_law_re_engages(failure):
    resets = []

    class Flaky(_PD):
        calls = 0

        def reset(self, inp):
            resets.append(inp.t)

        def step(self, inp):
            Flaky.calls += 1
            if Flaky.calls == 3:
                if failure == "raise":
                    raise ZeroDivisionError("boom")
                return np.full(4, np.nan)
            return super().step(inp)

    x = np.zeros(10)
    x[0:3] = [0.1, -0.1, 0.05]
    ctl = _controller(Flaky)
    ctl.reset(_core.Measurement(0.0, x[0:3], x[3:6], x[6:10]))
    rows = [_step(ctl, 0.1 * k, x) for k in range(5)]
    assert [r.mode for r in rows] == [_core.MODE_NORMAL] * 2 + [_core.MODE_SAFE] + [_core.MODE_NORMAL] * 2
    bad = rows[2]
    assert bad.flags & FLAG_LAW_INVALID and not np.any(bad.u_cmd)
    assert np.all(np.isfinite(bad.sigma_BD)) and np.any(bad.sigma_BD)  # telemetry kept
    assert resets == [0.0, pytest.approx(0.3)]  # engaged at the start and again after the SAFE step
    want = "ZeroDivisionError: boom" if failure == "raise" else "non-finite command"
    assert ctl.law_failures["last"]["what"] == want


def test_a_python_law_is_not_loaded_in_a_process_that_did_not_register_it():
    cfg = core_config("pd")
    cfg.law = "python:nosuch_module_xyz:Law"
    with pytest.raises(ValueError, match="not loaded here"):
        _core.Controller(cfg)


@pytest.mark.parametrize("spec,word", [("nosuchmodule_xyz:Law", "cannot import"),
                                       (PD_SPEC.replace("PythonPD", "Missing"), "no class"),
                                       ("missing_file.py:Law", "no such file"),
                                       ("numpy:ndarray", "no reset")])
def test_load_law_errors_are_one_line(spec, word):
    with pytest.raises(ValueError, match=word) as e:
        load_law(spec)
    assert "\n" not in str(e.value)


def test_cli_refuses_a_bad_law_before_running(tmp_path):
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", "paper_faults", "--law",
                        "nosuchmodule_xyz:Law", "--out", str(tmp_path / "o")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "--law" in r.stderr and "nosuchmodule_xyz" in r.stderr
    assert not (tmp_path / "o").exists()


def test_a_config_names_a_python_law_by_its_registry_spec_in_any_form():
    """file.py:Class (without python:) in a config runs: the config carries
    the spec the registry knows (before, the bench's telemetry names of such
    a law were lost: the controller was refused as an unknown law)."""
    scn = load_scenario("paper_faults")
    for spec in (PD_SPEC, "python:" + PD_SPEC):
        cfg = scn.core_config(law=spec)
        assert cfg.law == "python:" + PD_SPEC
        assert _core.Controller(cfg).law_name == "python-pd"
