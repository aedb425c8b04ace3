"""Offline closed loop: both engines, both paper scenarios, every law."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt.results.record.run import CORE_FIELDS
from sc_rt.scenario.reader import load_scenario
from sc_rt.results.present.output import write_run
from sc_rt.scenario.overrides import with_overrides
from sc_rt.sim.engines import simulate
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ("paper_fault_free", "paper_faults")
LAWS = ("dsc-ppc", "dsc", "pd", "rft")
METRIC_KEYS = {
    "scenario", "controller", "engine", "control_rate_hz", "duration_s", "steps", "wall_s", "finite",
    "first_bound_violation_s", "first_bound_violation_axis", "sigma_e_norm", "omega_e_norm",
    "max_abs_omega_e_after_70s", "max_observer_error_after_30s", "max_abs_u_cmd",
    "max_abs_wheel_accel", "saturated_fraction", "final_wheel_speed",
}
# The physical trajectory and what drives it. (lam = x1/chi is a ratio of two
# quantities near 1e-6 late in a run and is left out of the relative check.)
COMPARED = ("sigma_BN", "omega_BN_B", "wheel_speed", "sigma_BD", "omega_BD_B", "u_cmd", "u_sat",
            "wheel_accel", "z2", "delta2")


@pytest.fixture(scope="module")
def scenarios():
    return {s: load_scenario(ROOT / "scenarios" / f"{s}.toml") for s in SCENARIOS}


@pytest.mark.parametrize("scenario", SCENARIOS)
@pytest.mark.parametrize("law", LAWS)
def test_python_and_cpp_engines_agree(scenarios, scenario, law):
    scn = scenarios[scenario]
    a = simulate(scn, law=law, engine="python")
    b = simulate(scn, law=law, engine="cpp")
    assert len(a.trajectory["t"]) == len(b.trajectory["t"]) == 3001
    for k in COMPARED:
        x, y = a.trajectory[k], b.trajectory[k]
        rel = np.linalg.norm(x - y) / max(np.linalg.norm(y), 1e-300)
        assert rel <= 1e-9, f"{k}: relative difference {rel:.3e}"
    # The C++ plant twin repeats the Python plant's operations in the same
    # order and the controller is the same compiled code: the two engines
    # agree to the last bit (test_plant.py holds the plants bit-identical).
    assert a.trajectory.keys() == b.trajectory.keys() >= set(CORE_FIELDS)
    for k in a.trajectory:
        x, y = a.trajectory[k], b.trajectory[k]
        if not np.array_equal(x, y, equal_nan=x.dtype.kind == "f"):
            rows = np.flatnonzero(np.any((x != y).reshape(len(x), -1), axis=1))
            diff = np.max(np.abs(x.astype(float) - y.astype(float)))
            raise AssertionError(
                f"{k}: not bit-identical in {rows.size} rows, the first at t = "
                f"{a.trajectory['t'][rows[0]]:.1f} s (max |diff| {diff:.3e})"
            )
    assert a.metrics.keys() == b.metrics.keys()
    assert METRIC_KEYS <= a.metrics.keys()
    assert a.metrics["finite"] and b.metrics["finite"]


def test_delta2_is_the_true_lumped_disturbance(scenarios):
    # delta_2 = x2_dot - A - B sat(u) (docs/MODEL.md section 4): check it from the
    # trajectory by a finite difference of omega_BD_B between samples where
    # the dynamics are smooth (fault-free, after the initial transient).
    scn = scenarios["paper_fault_free"]
    res = simulate(scn, law="dsc", engine="python", control_rate_hz=100.0, duration=60.0)
    tr = res.trajectory
    from sc_rt import _core

    model = _core.SpacecraftModel(scn.core_config().spacecraft)
    # A at the samples, recomputed independently of the simulator via the core
    cfg = scn.core_config()
    k = np.arange(4000, 5900)
    h = tr["t"][1] - tr["t"][0]
    x2dot_fd = (tr["omega_BD_B"][k + 1] - tr["omega_BD_B"][k - 1]) / (2 * h)
    for j, i in enumerate(k[::100]):
        m = _core.Measurement(tr["t"][i], tr["sigma_BN"][i], tr["omega_BN_B"][i], tr["wheel_speed"][i])
        e = _core.tracking_errors(model, m, tr["sigma_DN"][i], _core.omega_d(cfg.guidance, tr["t"][i]),
                                  _core.omega_d_dot(cfg.guidance, tr["t"][i]))
        delta = x2dot_fd[j * 100] - e.A - model.B @ tr["u_sat"][i]
        # central difference across a ZOH boundary: O(h) error in x2_dot
        np.testing.assert_allclose(tr["delta2"][i], delta, atol=2e-4)


def test_metrics_and_trajectory_files(scenarios, tmp_path):
    res = simulate(scenarios["paper_faults"], law="pd", engine="cpp", duration=100.0)
    write_run(res, tmp_path, figures=False)
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert METRIC_KEYS <= m.keys()
    # checkpoints follow the run's duration: none past its end
    assert list(m["sigma_e_norm"]) == ["30", "70", "100"] and m["sigma_e_norm"]["100"] is not None
    assert m["max_observer_error_after_30s"] is None  # PD has no observer
    z = load_traj(tmp_path)
    for k in CORE_FIELDS:
        assert z[k].shape[0] == 1001, k
    assert z["bound_ok"].dtype == bool and z["bound_ok"].shape == (1001, 3)


def test_bound_check_is_independent_of_the_controller(scenarios):
    scn = scenarios["paper_fault_free"]
    res = simulate(scn, law="dsc-ppc", engine="cpp", duration=30.0)
    p = scn.controller.ppc
    chi = (np.array(p.chi0) - p.chiinf) * np.exp(-np.outer(res["t"], p.gamma)) + p.chiinf
    inside = (res["sigma_BD"] > -np.array(p.dmin) * chi) & (res["sigma_BD"] < np.array(p.dmax) * chi)
    np.testing.assert_array_equal(res["bound_ok"], inside)
    # the case exercises the flags: at 10 Hz the sampled loop leaves the
    # envelope (a violation on some axis, and rows back inside after it)
    viol = ~res["bound_ok"]
    assert viol.any() and not viol.all(), "the case must violate the bound for the flag check to mean anything"
    # the controller's own flags (bits 0..2, FLAG_BOUND_X/Y/Z) are set exactly
    # on the rows and axes outside the bound, from the first violation on
    flags = res["flags"]
    from sc_rt import _core

    bits = np.array([_core.FLAG_BOUND_X, _core.FLAG_BOUND_Y, _core.FLAG_BOUND_Z])
    flagged = (flags[:, None] & bits) != 0
    assert flagged.any()
    np.testing.assert_array_equal(flagged, viol)
    k = int(np.flatnonzero(viol.any(axis=1))[0])
    assert not flagged[:k].any() and flagged[k].any()
    # and the metrics report that row and its (first) axis
    assert res.metrics["first_bound_violation_s"] == res["t"][k]
    assert res.metrics["first_bound_violation_axis"] == int(np.flatnonzero(flagged[k])[0]) + 1


def _constructed_run(t, sigma_BD, ppc):
    """A run holding only t and sigma_BD (the rest at its fill values), its
    bound check and metrics computed as every producer does."""
    from sc_rt.results.judge.metrics import finish_run
    from sc_rt.results.record.run import Run, RunMeta

    t = np.asarray(t, float)
    meta = RunMeta(scenario="constructed", law="pd", engine="python", control_rate_hz=1.0,
                   duration_s=float(t[-1]), ppc={k: tuple(map(float, v)) for k, v in ppc.items()},
                   umin=(-1.0,) * 4, umax=(1.0,) * 4)
    return finish_run(Run(meta, {"t": t, "sigma_BD": np.asarray(sigma_BD, float)}))


def test_bound_verdict_on_trajectories_with_a_known_answer():
    # a constant envelope: chi(t) = chi0 = chiinf = 0.2, dmin = 0.5, dmax = 1,
    # so the bound is the open interval (-0.1, 0.2) on every axis
    const = dict(chi0=[0.2] * 3, chiinf=[0.2] * 3, gamma=[0.3] * 3, dmin=[0.5] * 3, dmax=[1.0] * 3)
    t = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    sigma = np.array([
        [0.0, 0.19, -0.09],    # inside
        [0.1, -0.05, 0.15],    # inside
        [0.05, 0.2, -0.11],    # y on the upper edge (open interval), z below: outside
        [0.21, 0.0, 0.0],      # x above: outside
        [0.0, 0.0, 0.0],       # back inside
        [-0.1, 0.0, 0.0],      # x on the lower edge: outside
    ])
    run = _constructed_run(t, sigma, const)
    expected = np.array([[1, 1, 1], [1, 1, 1], [1, 0, 0], [0, 1, 1], [1, 1, 1], [0, 1, 1]], bool)
    np.testing.assert_array_equal(run["bound_ok"], expected)
    # the first violation: t = 2 s; two axes at once, the first of them (y) reported
    assert run.metrics["first_bound_violation_s"] == 2.0
    assert run.metrics["first_bound_violation_axis"] == 2

    # a decaying envelope: chi0 = 1, chiinf = 0, gamma = ln 2, so chi = 2^-t:
    # 0.4 is inside at t = 1 (chi = 0.5) and outside at t = 2 (chi = 0.25)
    decay = dict(chi0=[1.0] * 3, chiinf=[0.0] * 3, gamma=[np.log(2.0)] * 3, dmin=[1.0] * 3,
                 dmax=[1.0] * 3)
    sigma = np.array([[0.0, 0.0, 0.9], [0.0, 0.0, 0.4], [0.0, 0.0, 0.4], [0.0, 0.0, 0.0]])
    run = _constructed_run([0.0, 1.0, 2.0, 3.0], sigma, decay)
    np.testing.assert_array_equal(run["bound_ok"][:, 2], [True, True, False, True])
    assert run["bound_ok"][:, :2].all()
    assert run.metrics["first_bound_violation_s"] == 2.0
    assert run.metrics["first_bound_violation_axis"] == 3

    # never outside: no violation time, no axis
    run = _constructed_run(t, np.zeros((6, 3)), const)
    assert run["bound_ok"].all()
    assert run.metrics["first_bound_violation_s"] is None
    assert run.metrics["first_bound_violation_axis"] is None


def test_rate_override_adapts_the_plant_step(scenarios):
    scn = with_overrides(scenarios["paper_faults"], control_rate_hz=100.0)
    assert scn.run.plant_step == pytest.approx(0.01) and scn.run.plant_substeps == 1
    scn = with_overrides(scenarios["paper_faults"], control_rate_hz=5.0)
    assert scn.run.plant_step == pytest.approx(0.1) and scn.run.plant_substeps == 2


def test_diverging_plant_stops_with_a_message(scenarios):
    # an absurd initial rate: the controller refuses the state (SAFE, zero
    # command), the gyroscopic term overflows, and the run stops cleanly
    scn = scenarios["paper_fault_free"]
    scn = dataclasses.replace(scn, initial=dataclasses.replace(scn.initial, omega_BN_B=np.array([1e154, 1e154, 0.0])))
    res = simulate(scn, engine="python", duration=10.0)
    assert res.diverged and "non-finite" in res.message
    assert res.metrics["finite"] is False and res.metrics["diverged"] is True
    assert 1 <= len(res.trajectory["t"]) < 101
    assert np.all(np.isfinite(res.trajectory["sigma_BN"]))


@pytest.mark.slow  # ~1.5-6 s: two sc-rt sim processes and the figures
def test_cli_sim_writes_results_and_rejects_bad_scenarios(tmp_path):
    out = tmp_path / "sim"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", "scenarios/paper_faults.toml",
                        "--engine", "cpp", "--duration", "20", "--out", str(out)],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert (out / "metrics.json").exists() and (out / "attitude_error.png").exists()
    bad = tmp_path / "bad.toml"
    bad.write_text((ROOT / "scenarios/paper_faults.toml").read_text().replace("umin = -7.0", "umin = 70.0"))
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", str(bad)], capture_output=True,
                       text=True, cwd=ROOT)
    assert r.returncode == 2
    assert "umin" in r.stderr and "bad.toml:" in r.stderr
