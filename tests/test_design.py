"""sc_rt.studies.design: linearisation, PD design, margins, sampled-data stability (docs/DESIGN.md)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import control
import numpy as np
import pytest

from sc_rt.scenario.variants import with_law_params
from sc_rt import _core
from sc_rt.studies import design as D
from sc_rt.cli import main
from sc_rt.model.plant_params import DisturbanceParams
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate

ROOT = Path(__file__).resolve().parents[1]
FAULT_FREE = ROOT / "scenarios" / "paper_fault_free.toml"
FAULTS = ROOT / "scenarios" / "paper_faults.toml"


@pytest.fixture(scope="module")
def paper():
    return load_scenario(FAULT_FREE)


@pytest.fixture(scope="module")
def paper_faults():
    return load_scenario(FAULTS)


def replace(scn, **groups):
    """The scenario with fields of its sub-dataclasses replaced: replace(s, plant=dict(w0=0))."""
    return dataclasses.replace(scn, **{k: dataclasses.replace(getattr(scn, k), **v)
                                       for k, v in groups.items()})


def unlimited_wheels(scn):
    return replace(scn, actuators=dict(umin=np.full(4, -1e6), umax=np.full(4, 1e6)))


# --------------------------------------------------------------------------- #
# Linearisation


def test_mrp_add_composes_the_rotations(rng):
    # mrp_add is the core's (8) with sigma_DN negated; check it against an
    # independent implementation (scipy's rotations: R(sigma_BN) = R(sigma_BD) R(sigma_DN)
    # for the DCMs, i.e. the transposes of scipy's active matrices) and the
    # published composition formula.
    from scipy.spatial.transform import Rotation

    for _ in range(20):
        a, b = rng.uniform(-0.5, 0.5, 3), rng.uniform(-0.5, 0.5, 3)
        c = D.mrp_add(a, b)
        dcm = Rotation.from_mrp(a).as_matrix().T @ Rotation.from_mrp(b).as_matrix().T
        np.testing.assert_allclose(Rotation.from_mrp(c).as_matrix().T, dcm, atol=1e-14)
        aa, bb = a @ a, b @ b
        formula = ((1 - bb) * a + (1 - aa) * b - 2 * np.cross(a, b)) / (1 + aa * bb - 2 * (a @ b))
        if formula @ formula <= 1.0:  # the core returns the short set
            np.testing.assert_allclose(c, formula, atol=1e-14)


@pytest.mark.parametrize("inertia", D.INERTIAS)
def test_numeric_linearisation_of_the_real_plant_is_the_analytic_double_integrator(paper, inertia):
    an = D.error_model(paper, inertia)
    J = paper.plant.J0 if inertia == "nominal" else paper.plant.J
    np.testing.assert_allclose(an.B[3:6], -np.linalg.solve(J, paper.plant.Cbar * paper.plant.Jw))
    np.testing.assert_array_equal(an.A[0:3, 3:6], 0.25 * np.eye(3))  # G(0) = I/4
    # At rest (no desired motion, no gravity gradient, wheels at rest) the real
    # error equations linearise to exactly x1' = x2/4, x2' = B u: only the
    # finite-difference error of control.linearize remains.
    nu = D.linearize_error(paper, 0.0, inertia, desired=False, gravity=False)
    np.testing.assert_allclose(nu.A, an.A, atol=1e-8)
    np.testing.assert_allclose(nu.B, an.B, atol=1e-8)


def test_numeric_linearisation_along_the_paper_motion_adds_only_small_transport_terms(paper):
    an = D.error_model(paper, "true")
    gp = paper.core_config().guidance
    for t in (0.0, 50.0):
        nu = D.linearize_error(paper, t, "true")
        np.testing.assert_allclose(nu.B, an.B, atol=1e-8)  # the input map is exact
        np.testing.assert_allclose(nu.A[0:3], an.A[0:3], atol=1e-8)  # kinematics at x2 = 0
        dev = np.abs(nu.A - an.A).max()
        wd = np.linalg.norm(_core.omega_d(gp, t))
        # gyroscopic and transport terms of (21): O(|omega_d|), and present
        assert 0.1 * wd < dev < 3.0 * wd, (t, dev, wd)


# --------------------------------------------------------------------------- #
# PD design


def test_default_pd_design_follows_the_envelope_rule_and_feeds_the_scenarios(paper, paper_faults):
    pd = D.default_pd_design(paper)
    Ts = math.log(50.0) / 0.08  # 2 % of the slowest envelope, gamma_z = 0.08 1/s
    assert pd.zeta == 1.0 and pd.settling_time == pytest.approx(Ts, rel=1e-12)
    assert pd.beta1 == pytest.approx(4 * pd.wn**2) and pd.beta2 == pytest.approx(2 * pd.wn)
    # the closed loop x1'' + beta2 x1' + beta1/4 x1 = 0 from rest settles to 2 % at Ts
    sys = control.ss([[0, 1], [-pd.beta1 / 4, -pd.beta2]], [[0], [1]], [[1, 0]], [[0]])
    t = np.linspace(0, 2 * Ts, 20001)
    x = control.initial_response(sys, t, [1.0, 0.0]).outputs
    assert abs(np.interp(Ts, t, x)) == pytest.approx(0.02, rel=1e-6)
    assert np.all(np.abs(x[t > Ts * 1.0001]) < 0.02) and np.any(np.abs(x[t < Ts * 0.999]) > 0.02)
    # the scenario files and the core's defaults carry these gains (4 digits)
    # the core's PD declares these gains as its defaults (4 digits), which the paper files run
    core = dict(_core.law_info("pd")["defaults"])
    assert core["beta1"][0] == pytest.approx(pd.beta1, rel=1e-4)
    assert core["beta2"][0] == pytest.approx(pd.beta2, rel=1e-4)
    for scn in (paper, paper_faults):
        assert scn.controller.table("pd") == ()
        assert (scn.controller.resolved("pd")["beta1"], scn.controller.resolved("pd")["beta2"]) == (
            core["beta1"][0], core["beta2"][0])


@pytest.mark.parametrize("zeta", [0.5, 0.7, 1.0, 1.5])
def test_settling_time_agrees_with_python_control_step_info(zeta):
    pd = D.design_pd(wn=0.3, zeta=zeta)
    sys = control.tf([pd.beta1 / 4], [1, pd.beta2, pd.beta1 / 4])
    info = control.step_info(sys, T=np.linspace(0, 3 * pd.settling_time, 30001),
                             SettlingTimeThreshold=0.02)
    assert info["SettlingTime"] == pytest.approx(pd.settling_time, rel=1e-3)
    again = D.design_pd(settling_time=pd.settling_time, zeta=zeta)
    assert again.wn == pytest.approx(0.3, rel=1e-9)
    with pytest.raises(ValueError):
        D.design_pd(wn=0.3, settling_time=10.0)


# --------------------------------------------------------------------------- #
# Margins against the closed forms of the double integrator with PD
#
# Tolerances: continuous pm, wgc, delay margin to 1e-9 (closed form, only the
# root finder's error); the ZOH gain margin 2/(m beta2 T) is exact (L is real
# at the Nyquist frequency) to 1e-9; the ZOH phase is the half-sample lag
# wgc T/2 to O((wgc T)^2), so pm_zoh and pm_zoh+delay are checked to
# (wgc T)^2 rad, which is 1/20 (10 Hz) to 1/2000 (1 kHz) of the effect of
# the ZOH itself; the Pade case to 1e-6 deg (Pade(5) of a 1.2 ms delay is
# exact at wgc ~ 0.25 rad/s to far below that).


@pytest.mark.parametrize("rate", [10.0, 1000.0])
@pytest.mark.parametrize("inertia", D.INERTIAS)
def test_margins_match_the_closed_forms(paper, rate, inertia):
    pd = D.default_pd_design(paper)
    m = np.diag(D.input_matrices(paper, inertia).M)
    assert D.coupling(paper, inertia)["coupling"] == pytest.approx([0, 0, 0], abs=1e-12)
    rows = D.pd_margins(paper, pd, rate=rate, inertias=(inertia,))
    assert len(rows) == 12
    T = 1.0 / rate
    by = {(r["case"], r["axis"]): r for r in rows}
    for i, ax in enumerate("xyz"):
        cf = D.closed_form_pd_margins(pd.beta1, pd.beta2, m[i], rate)
        tol = math.degrees((cf["wgc"] * T) ** 2)
        c = by["continuous", ax]
        assert c["pm"] == pytest.approx(cf["pm"], rel=1e-9)
        assert c["wgc"] == pytest.approx(cf["wgc"], rel=1e-9)
        assert c["delay_margin"] == pytest.approx(cf["delay_margin"], rel=1e-9)
        assert math.isinf(c["gm"]) and c["stable"]
        gm, pm, _, _, wgc, _ = control.stability_margins(
            D.axis_loop(paper, pd.beta1, pd.beta2, i, inertia=inertia))
        assert (pm, wgc) == (pytest.approx(c["pm"], abs=1e-6), pytest.approx(c["wgc"], rel=1e-6))
        z = by["zoh", ax]
        assert z["gm"] == pytest.approx(cf["gm_zoh"], rel=1e-9)
        assert z["wpc"] == pytest.approx(math.pi * rate, rel=1e-12)
        assert z["pm"] == pytest.approx(cf["pm_zoh"], abs=tol)
        assert c["pm"] - z["pm"] > 10 * tol  # the hold is in the loop
        d = by["zoh+delay", ax]
        assert d["pm"] == pytest.approx(cf["pm_zoh+delay"], abs=tol)
        assert d["gm"] < z["gm"] and d["stable"] and z["stable"]
        p = by["pade", ax]
        assert p["pm"] == pytest.approx(cf["pm"] - math.degrees(cf["wgc"] * D.DEFAULT_LATENCY_S),
                                        abs=1e-6)
        # python-control agrees on the continuous loops with latency (not on the
        # sampled ones: sc_rt.studies.design.margins.loop_margins); its polynomial
        # root search overflows harmlessly on these 21-state loops
        with np.errstate(over="ignore"):
            gm, pm, _, wpc, wgc, _ = control.stability_margins(
                D.axis_loop(paper, pd.beta1, pd.beta2, i, case="pade", inertia=inertia,
                            latency=D.DEFAULT_LATENCY_S))
        assert (gm, wpc) == (pytest.approx(p["gm"], rel=1e-6), pytest.approx(p["wpc"], rel=1e-6))
        assert (pm, wgc) == (pytest.approx(p["pm"], abs=1e-6), pytest.approx(p["wgc"], rel=1e-6))
        for r in (c, z, d, p):
            assert 1.0 - 1e-9 <= r["ms"] < 1.1


def test_faults_couple_the_axes_and_loop_at_a_time_sees_it(paper_faults):
    healthy = D.coupling(paper_faults, "true")
    faulty = D.coupling(paper_faults, "true", t=30.0)  # RW1, RW2 at half effectiveness
    assert max(healthy["coupling"]) < 1e-12 and max(faulty["coupling"]) > 0.1
    im = D.input_matrices(paper_faults, "true", t=30.0)
    np.testing.assert_allclose(im.effectiveness, [0.5, 0.5, 1.0, 1.0], atol=1e-6)


# --------------------------------------------------------------------------- #
# Sampled-data model of DSC+PPC


def _linear_probe(paper, chi, rate=100.0, steps=300):
    """A scenario whose C++ closed loop is linear to O(1e-4): no desired motion,
    gravity or disturbance, a constant envelope (gamma = 0) and alpha = 1 (the
    observer's sig terms are then linear)."""
    x10 = np.array([1.0, -2.0, 1.5]) * 1e-7
    scn = replace(
        paper,
        plant=dict(w0=0.0, disturbance=DisturbanceParams(amp=np.zeros(3), freq=np.zeros(3))),
        guidance=dict(sigma_d0=np.zeros(3), omega_cos=np.zeros(3), omega_sin=np.zeros(3)),
        initial=dict(sigma_BN=x10, omega_BN_B=np.array([2.0, 1.0, -1.0]) * 1e-8),
    )
    c = scn.controller
    scn = dataclasses.replace(scn, controller=dataclasses.replace(
        c, ppc=dataclasses.replace(c.ppc, chi0=np.array(chi), chiinf=np.array(chi), gamma=np.zeros(3))))
    scn = with_law_params(scn, "dsc-ppc", neso_alpha=1.0, neso_substeps=2)
    return scn, simulate(scn, engine="cpp", control_rate_hz=rate, duration=steps / rate)


@pytest.mark.parametrize("chi_x, grows", [(0.02, False), (0.008, True)])
def test_sampled_model_reproduces_the_cpp_closed_loop(paper, chi_x, grows):
    rate, N = 100.0, 300
    scn, res = _linear_probe(paper, [chi_x, 0.03, 0.05], rate, N)
    tr = ex = res.trajectory
    assert res.metrics["saturated_fraction"] == 0.0
    Phi = D.sampled_closed_loop(scn, "dsc-ppc", rate, 0.0, observer="local-gain")
    rho = np.max(np.abs(np.linalg.eigvals(Phi)))
    assert (rho > 1.0) == grows
    # the model's state at step 1, from the run's step 0 (see SAMPLED_STATES)
    idx = {n: slice(D.SAMPLED_STATES.index(f"{n}[0]"), None) for n in
           ("x1", "x2", "x2d", "x2bar_prev", "vs", "z1", "z2", "x2_prev", "Bu_prev")}
    s = np.zeros(len(D.SAMPLED_STATES))

    def put(name, v):
        i = idx[name].start
        s[i:i + len(v)] = v

    x2d0 = tr["omega_BD_B"][0] - ex["e2"][0]
    put("x1", tr["sigma_BD"][1])
    put("x2", tr["omega_BD_B"][1])
    put("x2d", x2d0)
    put("x2bar_prev", x2d0)  # (37): x2d(0) = x2bar(0)
    put("vs", ex["vs"][0])
    put("z1", tr["z1"][0])
    put("z2", tr["z2"][0])
    put("x2_prev", tr["omega_BD_B"][0])
    put("Bu_prev", np.array(_core.SpacecraftModel(scn.core_config().spacecraft).B) @ tr["u_sat"][0])
    states = [s]
    for _ in range(N - 1):
        states.append(Phi @ states[-1])
    S = np.array(states)
    x1_lin, x1_sim = S[:, 0:3], tr["sigma_BD"][1:N + 1]
    z2_lin, z2_sim = S[:, idx["z2"].start:idx["z2"].start + 3], tr["z2"][0:N]
    assert np.abs(x1_lin - x1_sim).max() < 1e-3 * np.abs(x1_sim).max()
    assert np.abs(z2_lin - z2_sim).max() < 1e-3 * np.abs(z2_sim).max()
    growth = np.abs(x1_sim[-50:, 0]).max() / np.abs(x1_sim[:50, 0]).max()
    assert (growth > 3.0) if grows else (growth < 0.5)


def _core_step_derivative(scn, law, rate, a, b, h0=2e-4):
    """d(Command)/d(measurements) of the C++ controller along the measurement
    sequence (h a_k, h b_k), h -> 0: central differences at h0, h0/2, h0/4 and
    two Richardson steps (error O(h0^6) plus rounding; the PPC's logarithms
    cancel at small h, so plain central differences stop at ~1e-11)."""
    fields = ("u_cmd", "u_sat", "x2d", "vs", "z1", "z2")

    def run(h):
        ctl = _core.Controller(scn.core_config(law))
        cmds = []
        for k in range(len(a)):
            m = _core.Measurement(k / rate, h * a[k], h * b[k], np.zeros(4))
            if k == 0:
                ctl.reset(m)
            cmd = ctl.step(m)
            cmds.append({f: np.array(getattr(cmd, f)) for f in fields})
        return cmds

    def central(h):
        p, m = run(h), run(-h)
        return [{f: (p[k][f] - m[k][f]) / (2 * h) for f in fields} for k in range(len(a))]

    d = [central(h0 / 2**j) for j in range(3)]
    for level in (1, 2):
        w = 4.0**level
        d = [[{f: (w * d[j + 1][k][f] - d[j][k][f]) / (w - 1) for f in fields}
              for k in range(len(a))] for j in range(len(d) - 1)]
    return d[0]


@pytest.mark.parametrize("law", ["dsc-ppc", "dsc"])
@pytest.mark.parametrize("rate", [10.0, 100.0])
def test_linearised_controller_step_is_the_cores_step(paper_faults, rng, law, rate):
    # The law of the sampled model (controller_step) is written out in Python;
    # it must stay the derivative of the C++ DscLaw::step. With alpha = 1
    # (the observer's sig terms are then linear, local-gain exact), no desired
    # motion and w0 = 0 the core's step is smooth at the origin: drive it with a
    # random measurement sequence and compare every step's u_cmd, x2d, vs, z1, z2
    # with the linear map applied to the same measurements, to 1e-12.
    scn = replace(paper_faults, plant=dict(w0=0.0),
                  guidance=dict(sigma_d0=np.zeros(3), omega_bias=np.zeros(3),
                                omega_cos=np.zeros(3), omega_sin=np.zeros(3)))
    for name in ("dsc-ppc", "dsc"):
        scn = with_law_params(scn, name, neso_alpha=1.0, neso_substeps=3)
    N = 30
    a, b = rng.standard_normal((N, 3)), rng.standard_normal((N, 3))
    ref = _core_step_derivative(scn, law, rate, a, b)
    assert np.all(np.abs(ref[1]["u_cmd"]) > 1e-3)  # the laws act
    B = np.array(_core.SpacecraftModel(scn.core_config().spacecraft).B)
    si = {n: D.SAMPLED_STATES.index(f"{n}[0]") for n in
          ("x1", "x2", "x2d", "x2bar_prev", "vs", "z1", "z2", "x2_prev", "Bu_prev")}
    oi = {n: D.CONTROLLER_OUTPUTS.index(f"{n}[0]") for n in ("u", "x2d", "x2bar", "vs", "z1", "z2")}
    size = {"u": 4, "vs": 4}
    s = np.zeros(len(D.SAMPLED_STATES))

    def put(name, v):
        s[si[name]:si[name] + len(v)] = v

    def out(y, name):
        return y[oi[name]:oi[name] + size.get(name, 3)]

    # the state after the core's step 0 (reset: x2d = x2bar, vs = 0)
    put("x2d", ref[0]["x2d"])
    put("x2bar_prev", ref[0]["x2d"])
    put("vs", ref[0]["vs"])
    put("z1", ref[0]["z1"])
    put("z2", ref[0]["z2"])
    put("x2_prev", b[0])
    put("Bu_prev", B @ ref[0]["u_sat"])
    err = dict.fromkeys(("u_cmd", "x2d", "vs", "z1", "z2"), 0.0)
    mag = dict(err)
    for k in range(1, N):
        put("x1", a[k])
        put("x2", b[k])
        y = D.controller_step(scn, law, rate, k / rate, observer="local-gain") @ s
        got = {"u_cmd": out(y, "u"), "x2d": out(y, "x2d"), "vs": out(y, "vs"), "z1": out(y, "z1"),
               "z2": out(y, "z2")}
        for f in err:
            err[f] = max(err[f], np.abs(got[f] - ref[k][f]).max())
            mag[f] = max(mag[f], np.abs(ref[k][f]).max())
        for name in ("x2d", "vs", "z1", "z2"):
            put(name, got[name])
        put("x2bar_prev", out(y, "x2bar"))
        put("x2_prev", b[k])
        put("Bu_prev", B @ got["u_cmd"])
    assert mag["vs"] == 0.0 and err["vs"] == 0.0  # no saturation: the compensator stays at 0
    for f in ("u_cmd", "x2d", "z1", "z2"):
        assert err[f] <= 1e-12 * mag[f], (f, err[f], mag[f])


@pytest.mark.parametrize("rate", [10.0, 100.0, 1000.0])
def test_critical_gain_follows_the_half_sample_rule(paper, rate):
    lim = D.stability_limit(paper, "dsc-ppc", rate)
    rule = D.critical_r_estimate(paper, rate)  # 4 sqrt(2 k2 f)
    assert lim.r_crit == pytest.approx([rule] * 3, rel=0.01)
    assert lim.axis == "x" and lim.t_loss_s == pytest.approx(lim.t_crit_s[0], abs=1e-3)
    # the DSC law without PPC (r = 1) is stable at every rate
    assert D.stability_limit(paper, "dsc", rate, grid=5.0).t_loss_s is None


# --------------------------------------------------------------------------- #
# Prediction against simulation (engine="cpp")


@pytest.mark.parametrize("which, rate, duration", [("fault_free", 100.0, 40.0),
                                                   ("fault_free", 1000.0, 50.0),
                                                   ("faults", 1000.0, 50.0)])
def test_predicted_loss_of_stability_matches_the_simulated_growth_onset(
        paper, paper_faults, which, rate, duration):
    scn = paper if which == "fault_free" else paper_faults
    pred = D.stability_limit(scn, "dsc-ppc", rate)
    sim = D.simulated_loss_of_stability(scn, "dsc-ppc", rate, duration=duration)
    i = "xyz".index(pred.axis)
    assert sim["lam_at_onset"][i] < 1e-2 and sim["saturated_at_onset"][i] == 0.0  # small signal
    assert sim["onset_s"][i] == pytest.approx(pred.t_loss_s, rel=0.10)
    # the bound itself breaks well after: growth from ~1e-9..1e-6 takes time
    assert sim["first_bound_violation_s"] > pred.t_loss_s + 5.0


def test_the_10hz_break_at_4s_is_saturation_not_the_sampled_loop(paper):
    pred = D.stability_limit(paper, "dsc-ppc", 10.0)
    assert pred.t_loss_s == pytest.approx(9.8, abs=0.1)
    real = D.simulated_loss_of_stability(paper, "dsc-ppc", 10.0, duration=20.0)
    assert real["first_bound_violation_s"] == pytest.approx(4.1, abs=0.05)
    assert real["first_bound_violation_s"] < pred.t_loss_s
    assert real["saturated_fraction_before_violation"] == 1.0  # every wheel step saturated
    free = D.simulated_loss_of_stability(unlimited_wheels(paper), "dsc-ppc", 10.0, duration=20.0)
    # with the wheels unlimited the bound holds past the predicted loss, and the
    # error grows only after it (masked by a slower transient until ~11.5 s)
    assert free["first_bound_violation_s"] > pred.t_loss_s + 3.0
    assert pred.t_loss_s <= free["onset_s"][0] < 1.25 * pred.t_loss_s
    # what sc-rt design prints about it
    why = D.compare_loss_of_stability(pred, real, free)
    assert (why["t_loss_s"], why["first_bound_violation_s"]) == (pred.t_loss_s, 4.1)
    assert why["first_bound_violation_axis"] == "z"
    text = why["explanation"]
    assert "4.10 s" in text and f"{pred.t_loss_s:.2f} s" in text and "100% of the control steps" in text
    assert f"until {free['first_bound_violation_s']:.2f} s" in text


@pytest.mark.parametrize("which", ["fault_free", "faults"])
@pytest.mark.parametrize("rate", [10.0, 100.0])
def test_smallest_stable_chiinf_brackets_the_simulation(paper, paper_faults, which, rate):
    scn = paper if which == "fault_free" else paper_faults
    chi_min = np.array(D.stability_limit(scn, "dsc-ppc", rate).chiinf_min)
    assert np.all(chi_min > 100 * np.array(scn.controller.ppc.chiinf))  # the paper's is unreachable

    def run(factor):
        c = scn.controller
        s = dataclasses.replace(scn, controller=dataclasses.replace(
            c, ppc=dataclasses.replace(c.ppc, chiinf=factor * chi_min)))
        return simulate(s, engine="cpp", control_rate_hz=rate).metrics["first_bound_violation_s"]

    assert run(1.1) is None  # the bound holds for the whole 300 s
    assert run(0.9) is not None


# --------------------------------------------------------------------------- #
# Command line


@pytest.mark.slow
def test_design_cli_writes_its_files(tmp_path, capsys):
    out = tmp_path / "design"
    assert main(["design", str(FAULT_FREE), "--rate", "100", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "zoh+delay" in text and "t_loss" in text
    for name in ("design.json", "bode.png", "nichols.png", "spectral_radius.png"):
        assert (out / name).stat().st_size > 1000, name
    d = json.loads((out / "design.json").read_text())
    assert d["rate_hz"] == 100.0 and d["pd"]["beta1"] == pytest.approx(0.05693, rel=1e-4)
    assert len(d["margins"]) == len(D.CASES) * len(D.INERTIAS) * 3
    lim = d["sampled_data"]["limits"]
    assert set(lim) == {"dsc-ppc", "dsc"} and set(lim["dsc-ppc"]) == {"10", "100", "1000"}
    assert lim["dsc-ppc"]["100"]["t_loss_s"] == pytest.approx(19.4, abs=0.1)
    assert lim["dsc"]["100"]["t_loss_s"] is None
    # the margins are labelled as the PD loop's
    assert "margins of the PD baseline loop, not of DSC+PPC" in text and "PD loop u = -B+" in text
    # chiinf against the half-sample rule's smallest stable chiinf (within its 1 %)
    p, k2 = d["chiinf_check"], 4.0  # paper k2 [1/s]
    scn = load_scenario(FAULT_FREE)
    ppc = scn.controller.ppc
    assert scn.controller.resolved("dsc-ppc")["k2"] == k2
    rule = (1 / ppc.dmin + 1 / ppc.dmax) / (2 * 4 * math.sqrt(2 * k2 * 100.0))
    np.testing.assert_allclose(p["chiinf_min"], rule, rtol=0.01)
    np.testing.assert_allclose(p["ratio"], ppc.chiinf / rule, rtol=0.01)
    assert not any(p["stable_at_end"])  # the paper's chiinf is far below it
    for ax, r in zip("xyz", p["ratio"]):
        assert f"{ax}: chiinf = " in text and f"ratio chiinf/chiinf_min = {r:.2e}" in text
    # the predicted loss and the run's first violation, side by side
    los = d["loss_of_stability"]
    assert los["t_loss_s"] == lim["dsc-ppc"]["100"]["t_loss_s"]
    assert los["first_bound_violation_s"] == pytest.approx(31.65, abs=0.05)  # docs/DESIGN.md
    assert los["onset_s"] == pytest.approx(los["t_loss_s"], rel=0.10)
    assert "grow from the error floor" in los["explanation"] and los["explanation"] in text


def _exit_code(argv) -> int:
    """main's exit code, whether it returns it or argparse exits with it."""
    try:
        return main(argv)
    except SystemExit as e:
        return e.code


def test_design_cli_rejects_a_bad_scenario_and_rate(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(FAULT_FREE.read_text().replace("umin = -7.0", "umin = 70.0"))
    assert _exit_code(["design", str(bad), "--out", str(tmp_path / "o"), "--no-plots"]) == 2
    assert "umin" in capsys.readouterr().err
    assert _exit_code(["design", str(FAULT_FREE), "--rate", "-5", "--out", str(tmp_path / "o")]) == 2
    assert not (tmp_path / "o").exists()


def test_the_sampled_study_of_a_law_takes_that_laws_table():
    """A dsc study reads [laws.dsc], not dsc-ppc's table (each law has its own
    since issue #26): a gain set only for dsc reaches only the dsc loop."""
    scn = with_law_params(load_scenario("paper_faults"), "dsc", k2=7.5, neso_substeps=3)
    dsc, ppc = D.SampledLoop(scn, "dsc", None), D.SampledLoop(scn, "dsc-ppc", None)
    assert dsc.g.k2 == 7.5 and ppc.g.k2 == scn.controller.resolved("dsc-ppc")["k2"] != 7.5
    n_dsc, n_ppc = D.observer_gains(scn, "linear-part", 1e-5, "dsc"), D.observer_gains(scn, "linear-part", 1e-5)
    np.testing.assert_array_equal(n_dsc[0], np.broadcast_to(scn.controller.resolved("dsc")["neso_k2"], (3,)))
    np.testing.assert_array_equal(n_ppc[0], np.broadcast_to(scn.controller.resolved("dsc-ppc")["neso_k2"], (3,)))
