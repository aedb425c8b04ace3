"""Python laws (sc_rt.pylaw): the contract, the common controller parts
checked against the C++ Controller::step, and the example PD against the
core's built-in PD on both paper scenarios."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.pylaw import FLAG_LAW_INVALID, PACKED_SLICES, PyController, load_law
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate

from conftest import core_config

ROOT = Path(__file__).resolve().parent.parent
PD_SPEC = str(ROOT / "examples" / "python_laws" / "pd.py") + ":PythonPD"
COMPARED = ("sigma_BN", "omega_BN_B", "wheel_speed", "u_cmd", "u_sat", "wheel_accel", "sigma_DN",
            "sigma_BD", "omega_BD_B", "e1", "e2", "chi", "lam", "flags", "ctrl_mode", "delta2")


@pytest.mark.parametrize("scenario", ["paper_fault_free", "paper_faults"])
def test_python_pd_equals_the_core_pd(scenario):
    scn = load_scenario(scenario)
    core = simulate(scn, law="pd")
    py = simulate(scn, law=PD_SPEC)
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
        runs[name] = np.load(tmp_path / name / "trajectory.npz")
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


@pytest.mark.parametrize("rate", [10.0, 50.0])
def test_common_parts_match_controller_step(rate):
    cfg = core_config("pd", rate)
    cpp = _core.Controller(cfg)
    py = PyController(cfg, _PD)
    seq = _states()
    t0, x0 = seq[0]
    cpp.reset(_core.Measurement(t0, x0[0:3], x0[3:6], x0[6:10]))
    py.reset(t0, x0)
    seen_flags = 0
    for t, x in seq:
        a = np.asarray(_core.step_packed(cpp, t, x))
        b = py.step(t, x)
        assert np.allclose(a, b, rtol=0, atol=1e-12, equal_nan=True), (t, a - b)
        seen_flags |= int(a[PACKED_SLICES["flags"]][0])
    # the sequence went through the branches it was built for
    for f in (_core.FLAG_INVALID_STATE, _core.FLAG_TIME_NOT_ADVANCING, _core.FLAG_SAT_1):
        assert seen_flags & f, f


def test_named_telemetry_bad_commands_and_failures():
    class Named(_PD):
        def step(self, inp):
            return np.zeros(4), {"my_gain": 2.5, "z1": np.ones(3)}

    class Short(_PD):
        def step(self, inp):
            return np.zeros(3)

    x = np.zeros(10)
    ctl = PyController(core_config("pd"), Named)
    ctl.reset(0.0, x)
    out = ctl.step(0.0, x)
    assert ctl.named_telemetry == {"my_gain": 2.5}
    assert list(out[PACKED_SLICES["z1"]]) == [1.0, 1.0, 1.0]
    # a wrong-shaped command or telemetry is a failure of the law, contained
    # like a raise or a NaN (issue #25; it raised out of the controller before)
    class BadTelemetry(_PD):
        def step(self, inp):
            return np.zeros(4), {"x2d": np.ones(2)}

    for cls, what in ((Short, "u_cmd of shape (3,)"), (BadTelemetry, "telemetry 'x2d' of shape (2,)")):
        ctl = PyController(core_config("pd"), cls)
        ctl.reset(0.0, x)
        out = ctl.step(0.0, x)
        assert int(out[PACKED_SLICES["mode"]][0]) == _core.MODE_SAFE
        assert int(out[PACKED_SLICES["flags"]][0]) & _core.FLAG_LAW_INVALID
        assert ctl.law_failures["step"] == 1 and what in ctl.law_failures["last"]["what"]


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
    ctl = PyController(core_config("pd"), ResetOnce)
    assert ctl.reset(0.0, x)
    modes = [int(ctl.step(0.1 * k, x)[PACKED_SLICES["mode"]][0]) for k in range(6)]
    assert modes[:3] == [_core.MODE_NORMAL] * 3 and modes[3:] == [_core.MODE_SAFE] * 3
    f = ctl.law_failures
    assert f["step"] == 1 and f["reset"] == 2 and f["last"]["call"] == "reset"
    assert f["last"]["t"] == pytest.approx(0.5) and "reset exploded" in f["last"]["what"]


@pytest.mark.parametrize("failure", ["nan", "raise"])
def test_an_invalid_law_command_is_safe_and_the_law_re_engages(failure):
    class Flaky(_PD):
        calls = 0

        def step(self, inp):
            Flaky.calls += 1
            if Flaky.calls == 3:
                if failure == "raise":
                    raise ZeroDivisionError("boom")
                return np.full(4, np.nan)
            return super().step(inp)

    x = np.zeros(10)
    x[0:3] = [0.1, -0.1, 0.05]
    ctl = PyController(core_config("pd"), Flaky)
    ctl.reset(0.0, x)
    rows = [ctl.step(0.1 * k, x) for k in range(5)]
    P = PACKED_SLICES
    modes = [int(r[P["mode"]][0]) for r in rows]
    assert modes == [_core.MODE_NORMAL] * 2 + [_core.MODE_SAFE] + [_core.MODE_NORMAL] * 2
    bad = rows[2]
    assert int(bad[P["flags"]][0]) & FLAG_LAW_INVALID and not np.any(bad[P["u_cmd"]])
    assert np.all(np.isfinite(bad[P["sigma_BD"]])) and np.any(bad[P["sigma_BD"]])  # telemetry kept
    assert ctl.law.resets == 2  # engaged at the start and again after the SAFE step


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
