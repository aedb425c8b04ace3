"""The [[requirements]] of a scenario and their evaluation on a run (issue #27;
sc_rt.scenario.tables.requirements, sc_rt.results.judge.requirements, docs/REQUIREMENTS.md).

The statistics are checked against answers known by construction or computed
here independently with numpy/scipy, never with the module's own helpers:

1. RPE of a sine against windows longer and shorter than its period, and
   against a direct numpy computation of ECSS-E-ST-60-10C's definition
   (3.2.12: every instant against the mean of its window) with the
   window-max bound beside it; MPE of a ramp (a drift);
2. the nearest-rank quantile against numpy's ``inverted_cdf`` and the
   empirical CDF's definition (scipy.stats.ecdf);
3. the settling time of an exponential decay; the half-cone angle of a
   constructed rotation (Rodrigues, scipy's Rotation);
4. the knowledge error against the core's own ``att_est_error``;
5. the envelope requirement against the metrics' first violation;
6. the schema: each bad row is a ScenarioError with file, line, key and
   value, exit 2 from the CLI; the verdict and the console table.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from sc_rt.results.judge.metrics import finish_run
from sc_rt.results.judge.pointing import cone_vector, mrp_subtract, nearest_rank
from sc_rt.results.record.run import Run, RunMeta
from sc_rt.results.judge.verdict import verdict_line
from sc_rt.scenario.model import ScenarioError
from sc_rt.scenario.reader import load_scenario
from sc_rt.scenario.tables.requirements import Requirement

ROOT = Path(__file__).resolve().parent.parent
ARCSEC = math.pi / 648000.0
RATE = 10.0  # [Hz] the constructed runs' grid
#: an envelope nothing here comes near (the constructed runs are judged by their requirements)
WIDE = {k: (v,) * 3 for k, v in dict(chi0=1.0, chiinf=1.0, gamma=0.0, dmin=1.0, dmax=1.0).items()}


def req(name: str, kind: str, **kw) -> dict:
    """A requirement row as RunMeta carries it (the scenario's dataclass, as a dict)."""
    return dataclasses.asdict(Requirement(name=name, kind=kind, **kw))


def about_x(theta: np.ndarray) -> np.ndarray:
    """MRPs (N, 3) of rotations by theta [rad] about the body x axis: the
    rotation vector's x component is theta exactly (|theta| < pi)."""
    s = np.zeros((len(theta), 3))
    s[:, 0] = np.tan(np.asarray(theta, float) / 4.0)
    return s


def run_of(t: np.ndarray, sigma_BD: np.ndarray, reqs: list[dict], **arrays) -> Run:
    """A run of ``t`` and ``sigma_BD`` (and ``arrays``), finished as every producer does."""
    meta = RunMeta(scenario="constructed", law="pd", engine="python", control_rate_hz=RATE,
                   duration_s=float(t[-1]), ppc=WIDE, umin=(-7.0,) * 4, umax=(10.0,) * 4,
                   requirements=tuple(reqs))
    return finish_run(Run(meta, {"t": t, "sigma_BD": sigma_BD, **arrays}))


def result(run: Run, name: str) -> dict:
    return next(r for r in run.metrics["requirements"] if r["name"] == name)


def grid(duration: float) -> np.ndarray:
    return np.arange(int(round(duration * RATE)) + 1) / RATE


# --------------------------------------------------------------------------------------------- #
# 1. RPE of a sine, MPE of a ramp


def rpe_numpy(e: np.ndarray, n: int, p: float) -> float:
    """RPE written out (ECSS-E-ST-60-10C 3.2.12, temporal): non-overlapping windows of n samples from
    the first, |e(t) - the mean of t's window| at every instant, numpy's inverted-CDF quantile over them."""
    per = np.concatenate([np.abs(e[k:k + n] - e[k:k + n].mean()) for k in range(0, len(e) - n + 1, n)])
    return float(np.quantile(per, p, method="inverted_cdf"))


def rpe_bound_numpy(e: np.ndarray, n: int, p: float) -> float:
    """The window-max bound beside it: max |e - window mean| per window, the quantile over the windows."""
    per = [np.max(np.abs(e[k:k + n] - e[k:k + n].mean())) for k in range(0, len(e) - n + 1, n)]
    return float(np.quantile(per, p, method="inverted_cdf"))


@pytest.mark.parametrize("window, period, expect", [
    (20.0, 2.0, "amplitude"),   # ten whole periods per window: the mean is 0, the peak sampled: exactly A
    (200.0, 7.3, "amplitude"),  # many periods, not whole: close to A
    (0.2, 200.0, "zero"),       # two samples of a slow sine: at most A pi dt / P
    (5.0, 20.0, "between"),     # a quarter period
])
def test_rpe_of_a_sine_against_numpy_and_its_limits(window, period, expect):
    A = 40.0 * ARCSEC
    t = grid(600.0)
    theta = A * np.sin(2.0 * np.pi * t / period)
    r = result(run_of(t, about_x(theta), [req("rpe", "RPE", axis="x", bound=1000.0, unit="arcsec",
                                              confidence=0.95, interpretation="temporal", window=window)]), "rpe")
    assert r["status"] == "pass" and r["unit"] == "arcsec"
    n = int(round(window * RATE))
    direct = rpe_numpy(theta, n, 0.95) / ARCSEC
    assert r["value"] == pytest.approx(direct, rel=1e-9)
    assert r["margin"] == pytest.approx(1000.0 - direct, rel=1e-9)
    assert r["windows"] == len(t) // n and r["samples"] == (len(t) // n) * n
    bound = rpe_bound_numpy(theta, n, 0.95) / ARCSEC
    assert r["window_max_bound"] == pytest.approx(bound, rel=1e-9) and r["window_max_bound"] >= r["value"]
    if expect == "amplitude":  # the window-max statistic reaches the peak; the index, the sine's own p95
        tol = 1e-9 if period == 2.0 else 0.02
        assert r["window_max_bound"] == pytest.approx(40.0, rel=tol)
        # |A sin| over whole periods: a fraction 0.95 of the time below A sin(pi/2 (1 - 0.05))... to a sample
        assert 40.0 * np.sin(np.pi / 2 * 0.95) * 0.98 < r["value"] <= 40.0 * (1 + 1e-9)
    elif expect == "zero":
        assert 0 < r["value"] <= r["window_max_bound"] <= 40.0 * math.pi * (1.0 / RATE) / period * (1 + 1e-9)
        assert r["value"] < 0.01 * 40.0
    else:
        assert 0.1 * 40.0 < r["value"] < 40.0


def test_rpe_norm_of_a_cone_sweep_is_its_radius():
    """The pointing axis going round a cone of half-angle a (a coning error of
    constant size): the rotation vector turns, its mean over whole turns is 0,
    so over windows of whole turns the RPE of the norm is a (and the APE is a)."""
    a, period = 25.0 * ARCSEC, 4.0
    t = grid(400.0)
    phase = 2.0 * np.pi * t / period
    phi = np.stack([a * np.cos(phase), a * np.sin(phase), 0.0 * t], axis=1)  # rotation vectors
    ang = np.linalg.norm(phi, axis=1)
    sigma = np.tan(ang / 4.0)[:, None] * phi / ang[:, None]
    run = run_of(t, sigma, [
        req("rpe", "RPE", axis="norm", bound=30.0, unit="arcsec", confidence=0.9973,
            interpretation="temporal", window=8.0),
        req("ape", "APE", axis="norm", bound=30.0, unit="arcsec", confidence=0.5, interpretation="temporal"),
        req("mpe", "MPE", axis="norm", bound=30.0, unit="arcsec", confidence=0.9973,
            interpretation="temporal", window=8.0),
    ])
    assert result(run, "rpe")["value"] == pytest.approx(25.0, rel=1e-6)
    assert result(run, "ape")["value"] == pytest.approx(25.0, rel=1e-9)
    assert result(run, "mpe")["value"] == pytest.approx(0.0, abs=1e-6)


def test_mpe_of_a_ramp_is_the_window_mean_of_the_drift():
    r_drift = 0.05 * ARCSEC  # [rad/s]
    t = grid(300.0)
    theta = r_drift * t
    w, t0, p = 10.0, 50.0, 0.9
    run = run_of(t, about_x(theta), [req("mpe", "MPE", axis="x", bound=20.0, unit="arcsec", confidence=p,
                                         interpretation="temporal", window=w, t_from=t0)])
    r = result(run, "mpe")
    # windows [t0 + k w, t0 + (k+1) w) of n samples; their means r (t0 + k w + (n - 1) dt / 2), increasing in k
    n, dt = int(w * RATE), 1.0 / RATE
    n_win = int((300.0 - t0 + dt) * RATE) // n
    k = math.ceil(p * n_win)  # nearest rank
    expected = 0.05 * (t0 + (k - 1) * w + (n - 1) * dt / 2.0)
    assert r["windows"] == n_win == 25
    assert r["value"] == pytest.approx(expected, rel=1e-9)
    assert r["passed"] is (expected <= 20.0) and r["status"] == ("pass" if expected <= 20.0 else "fail")
    # a drift has no relative error beyond the ramp inside one window: at the k-th of its n instants
    # r dt |k - (n - 1) / 2| from the window's mean, the same in every window: RPE is the p-quantile of
    # those; the window-max bound their largest, r w' / 2, w' = (n - 1) dt
    run = run_of(t, about_x(theta), [req("rpe", "RPE", axis="x", bound=1.0, unit="arcsec", confidence=p,
                                         interpretation="temporal", window=w, t_from=t0)])
    inside = 0.05 * dt * np.abs(np.arange(n) - (n - 1) / 2.0)
    assert result(run, "rpe")["value"] == pytest.approx(np.quantile(inside, p, method="inverted_cdf"), rel=1e-9)
    assert result(run, "rpe")["window_max_bound"] == pytest.approx(0.05 * (n - 1) * dt / 2.0, rel=1e-9)


def pairs_numpy(e: np.ndarray, n_first: int, n: int, shift: int) -> list[float]:
    """PDE/PRE written out: windows of n samples tiling e[:n_first], each against the window shift samples later."""
    return [abs(e[k + shift:k + shift + n].mean() - e[k:k + n].mean())
            for k in range(0, n_first - n + 1, n) if k + shift + n <= len(e)]


@pytest.mark.parametrize("window, separation", [(10.0, 30.0), (5.0, 5.0), (2.0, 47.3)])
def test_pde_of_a_ramp_is_the_drift_over_the_separation(window, separation):
    """A drift r t: every pair of windows S apart differs by r S in its mean,
    whatever the window; PRE (pairs reaching past the span) the same."""
    r_drift = 0.02 * ARCSEC  # [rad/s]
    t = grid(300.0)
    theta = r_drift * t
    rows = [req("pde", "PDE", axis="x", bound=5.0, unit="arcsec", confidence=0.9973, interpretation="temporal",
                window=window, separation=separation, t_from=50.0, t_to=200.0),
            req("pre", "PRE", axis="x", bound=5.0, unit="arcsec", confidence=0.9973, interpretation="temporal",
                window=window, separation=separation, t_from=50.0, t_to=200.0)]
    run = run_of(t, about_x(theta), rows)
    pde, pre = result(run, "pde"), result(run, "pre")
    shift = int(round(separation * RATE))
    exact = 0.02 * shift / RATE  # [arcsec] r times the separation on the grid
    n = int(round(window * RATE))
    span = theta[(t >= 50.0 - 1e-9)] / ARCSEC
    first = int(np.sum((t >= 50.0 - 1e-9) & (t <= 200.0 + 1e-9)))
    direct_pde = pairs_numpy(span[:first], first, n, shift)
    direct_pre = pairs_numpy(span, first, n, shift)
    assert pde["pairs"] == len(direct_pde) and pre["pairs"] == len(direct_pre) > pde["pairs"]
    assert pde["value"] == pytest.approx(exact, rel=1e-9) and pre["value"] == pytest.approx(exact, rel=1e-9)
    assert pde["value"] == pytest.approx(np.quantile(direct_pde, 0.9973, method="inverted_cdf"), rel=1e-9)
    assert pde["separation_s"] == pytest.approx(shift / RATE) and pde["window_s"] == pytest.approx(n / RATE)
    assert pde["passed"] is (exact <= 5.0)


@pytest.mark.parametrize("window, period, separation", [
    (10.0, 5.0, 12.5),   # whole periods per window: every mean 0, no drift at all
    (2.0, 20.0, 10.0),   # a window shorter than the period, half a period apart: the means swing
    (30.0, 7.0, 3.5),    # many periods, not whole
])
def test_pde_of_a_sine_against_numpy(window, period, separation):
    A = 40.0 * ARCSEC
    t = grid(400.0)
    theta = A * np.sin(2.0 * np.pi * t / period)
    run = run_of(t, about_x(theta), [req("pde", "PDE", axis="x", bound=100.0, unit="arcsec", confidence=0.9,
                                         interpretation="temporal", window=window, separation=separation)])
    r = result(run, "pde")
    n, shift = int(round(window * RATE)), int(round(separation * RATE))
    direct = pairs_numpy(theta / ARCSEC, len(t), n, shift)
    assert r["value"] == pytest.approx(np.quantile(direct, 0.9, method="inverted_cdf"), rel=1e-7, abs=1e-9)
    if window / period == round(window / period):
        assert r["value"] == pytest.approx(0.0, abs=1e-9)
    else:  # the means of two windows half a period apart are opposite: at most 2 A sin(pi W/P)/(pi W/P) apart
        x = math.pi * window / period
        assert 0.0 < r["value"] <= 2.0 * 40.0 * abs(math.sin(x)) / x * (1 + 1e-6) + 1e-9


def test_momentum_margin_is_the_largest_total_wheel_momentum():
    t = grid(20.0)
    ws = np.zeros((len(t), 4))
    ws[:, 0] = 50.0 + 10.0 * np.sin(t)
    ws[:, 3] = -30.0 * t / 20.0
    Cbar = np.array([[1.0, 0.0, 0.0, 0.6], [0.0, 1.0, 0.0, 0.64], [0.0, 0.0, 1.0, 0.48]])
    Jw = np.array([0.1, 0.1, 0.1, 0.2])
    meta = RunMeta(scenario="c", law="pd", engine="python", control_rate_hz=RATE, duration_s=20.0, ppc=WIDE,
                   umin=(-7.0,) * 4, umax=(10.0,) * 4, Cbar=tuple(map(tuple, Cbar)), Jw=tuple(Jw),
                   requirements=(req("h", "momentum_margin", bound=7.0, unit="N m s"),
                                 req("hm", "momentum_margin", bound=7000.0, unit="mN m s", t_to=5.0)))
    run = finish_run(Run(meta, {"t": t, "sigma_BD": np.zeros((len(t), 3)), "wheel_speed": ws}))
    h = np.array([np.linalg.norm(Cbar @ (Jw * w)) for w in ws])  # the momentum row by row
    r, rm = result(run, "h"), result(run, "hm")
    assert r["value"] == pytest.approx(h.max(), rel=1e-12) and r["passed"] is bool(h.max() <= 7.0)
    assert f"at {t[np.argmax(h)]:g} s" in r["note"]
    assert rm["value"] == pytest.approx(1000.0 * h[t <= 5.0 + 1e-9].max(), rel=1e-12)
    old = finish_run(Run(dataclasses.replace(meta, Cbar=(), Jw=()), {"t": t, "sigma_BD": np.zeros((len(t), 3)),
                                                                     "wheel_speed": ws}))
    assert result(old, "h")["status"] == "not evaluated" and "Cbar" in result(old, "h")["note"]


# --------------------------------------------------------------------------------------------- #
# 2. Quantiles


@pytest.mark.parametrize("n", [1, 2, 7, 100, 371, 2401])
@pytest.mark.parametrize("p", [0.5, 0.9, 0.95, 0.9973, 1.0])
def test_nearest_rank_is_numpys_inverted_cdf_and_the_ecdf_definition(n, p):
    from scipy.stats import ecdf

    x = np.random.default_rng(n).standard_exponential(n)
    q = nearest_rank(x, p)
    assert q == np.quantile(x, p, method="inverted_cdf")
    cdf = ecdf(x).cdf
    assert cdf.evaluate(q) >= p - 1e-12  # at least a fraction p of the samples are <= q
    below = x[x < q]
    assert below.size == 0 or cdf.evaluate(below.max()) < p  # and q is the smallest such sample


def test_ape_is_the_quantile_of_the_rotation_angle_over_the_span():
    rng = np.random.default_rng(5)
    t = grid(200.0)
    sigma = rng.normal(0.0, 2e-5, (len(t), 3))
    angle = 4.0 * np.arctan(np.linalg.norm(sigma, axis=1)) / ARCSEC
    run = run_of(t, sigma, [req("ape", "APE", axis="norm", bound=30.0, unit="arcsec", confidence=0.9973,
                                interpretation="temporal", t_from=60.0, t_to=150.0)])
    r = result(run, "ape")
    span = (t >= 60.0 - 1e-9) & (t <= 150.0 + 1e-9)
    expected = np.quantile(angle[span], 0.9973, method="inverted_cdf")
    assert r["value"] == pytest.approx(expected, rel=1e-12) and r["samples"] == span.sum() == 901
    assert r["span_s"] == [60.0, 150.0]
    assert r["passed"] is bool(expected <= 30.0)
    # in deg the same number, converted
    run = run_of(t, sigma, [req("ape", "APE", axis="norm", bound=0.01, unit="deg", confidence=0.9973,
                                interpretation="temporal", t_from=60.0, t_to=150.0)])
    assert result(run, "ape")["value"] == pytest.approx(expected / 3600.0, rel=1e-12)


# --------------------------------------------------------------------------------------------- #
# 3. Settling and the cone


@pytest.mark.parametrize("A_arcsec, tau, band", [(3600.0, 12.0, 30.0), (500.0, 7.3, 2.0)])
def test_settling_time_of_an_exponential_decay(A_arcsec, tau, band):
    t = grid(200.0)
    theta = A_arcsec * ARCSEC * np.exp(-t / tau)
    exact = tau * math.log(A_arcsec / band)  # the decay enters the band at this time
    first = math.ceil(exact * RATE) / RATE   # the first sample at or after it
    assert abs(exact * RATE - round(exact * RATE)) > 1e-3  # not on the grid: no rounding question
    run = run_of(t, about_x(theta), [req("s", "settling", axis="x", bound=band, unit="arcsec", settle_by=60.0)])
    r = result(run, "s")
    assert r["value"] == pytest.approx(first, abs=1e-12) and r["unit"] == "s"
    assert r["margin"] == pytest.approx(60.0 - first, abs=1e-12)
    assert r["passed"] is (first <= 60.0)


def test_settling_counts_a_late_excursion_and_a_run_that_never_settles():
    t = grid(200.0)
    theta = 3600.0 * ARCSEC * np.exp(-t / 5.0)
    theta[t == 50.0] = 40.0 * ARCSEC  # one sample out of the 30 arcsec band at 50 s
    run = run_of(t, about_x(theta), [req("s", "settling", axis="norm", bound=30.0, unit="arcsec", settle_by=60.0)])
    assert result(run, "s")["value"] == pytest.approx(50.1)
    theta[-1] = 40.0 * ARCSEC  # out at the end: never settled
    run = run_of(t, about_x(theta), [req("s", "settling", axis="norm", bound=30.0, unit="arcsec", settle_by=60.0),
                                     req("after", "APE", axis="norm", bound=30.0, unit="arcsec", confidence=0.9,
                                         interpretation="temporal", t_from="after_settling", settling="s")])
    r, after = result(run, "s"), result(run, "after")
    assert r["passed"] is False and r["value"] is None and "never settled" in r["note"]
    assert after["status"] == "not evaluated" and "never settled" in after["note"]


def test_after_settling_starts_the_span_at_the_settling_time():
    t = grid(100.0)
    theta = 3600.0 * ARCSEC * np.exp(-t / 5.0)
    run = run_of(t, about_x(theta), [
        req("s", "settling", axis="norm", bound=30.0, unit="arcsec", settle_by=60.0),
        req("ape", "APE", axis="norm", bound=30.0, unit="arcsec", confidence=1.0, interpretation="temporal",
            t_from="after_settling", settling="s")])
    ts = result(run, "s")["value"]
    r = result(run, "ape")
    assert r["span_s"][0] == ts and r["samples"] == int(np.sum(t >= ts - 1e-9))
    assert r["value"] == pytest.approx(theta[t >= ts - 1e-9].max() / ARCSEC, rel=1e-9)  # p = 1: the max


def rodrigues_cone(axis: np.ndarray, angle: float, b: np.ndarray) -> float:
    """The angle between b and b rotated by ``angle`` about unit ``axis``:
    cos = cos(angle) + (1 - cos(angle)) (axis . b)^2."""
    c = math.cos(angle) + (1.0 - math.cos(angle)) * float(axis @ b) ** 2
    return math.acos(min(1.0, max(-1.0, c)))


def test_cone_half_angle_of_constructed_rotations():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(3)
    b = np.array([0.3, -0.2, 0.9])
    b /= np.linalg.norm(b)
    for _ in range(50):
        e = rng.normal(size=3)
        e /= np.linalg.norm(e)
        angle = rng.uniform(1e-6, 0.5)
        sigma = np.tan(angle / 4.0) * e
        got = np.linalg.norm(cone_vector(sigma[None, :], b)[0])
        assert got == pytest.approx(rodrigues_cone(e, angle, b), rel=1e-9, abs=1e-15)
        moved = Rotation.from_rotvec(angle * e).apply(b)
        assert got == pytest.approx(math.acos(np.clip(moved @ b, -1, 1)), rel=1e-6, abs=1e-9)
    # about the boresight: no cone error; perpendicular to it: the whole angle
    assert np.linalg.norm(cone_vector((np.tan(0.3 / 4.0) * b)[None, :], b)) == pytest.approx(0.0, abs=1e-15)
    perp = np.cross(b, [1.0, 0.0, 0.0])
    perp /= np.linalg.norm(perp)
    assert np.linalg.norm(cone_vector((np.tan(0.3 / 4.0) * perp)[None, :], b)) == pytest.approx(0.3, rel=1e-12)


def test_cone_requirement_through_a_run():
    t = grid(50.0)
    b = np.array([0.0, 0.0, 1.0])
    # 20 arcsec about x (tilts z by 20 arcsec) and 100 arcsec about z (a roll about the boresight)
    phi = np.tile([20.0 * ARCSEC, 0.0, 100.0 * ARCSEC], (len(t), 1))
    ang = np.linalg.norm(phi, axis=1)
    sigma = np.tan(ang / 4.0)[:, None] * phi / ang[:, None]
    run = run_of(t, sigma, [req("cone", "APE", axis="cone", boresight=tuple(b), bound=25.0, unit="arcsec",
                                confidence=0.95, interpretation="temporal"),
                            req("norm", "APE", axis="norm", bound=25.0, unit="arcsec", confidence=0.95,
                                interpretation="temporal")])
    expected = rodrigues_cone(phi[0] / ang[0], ang[0], b) / ARCSEC
    assert 19.9 < expected < 20.1
    assert result(run, "cone")["value"] == pytest.approx(expected, rel=1e-9) and result(run, "cone")["passed"]
    norm = result(run, "norm")
    assert norm["value"] == pytest.approx(ang[0] / ARCSEC, rel=1e-9) and not norm["passed"]


def test_mrp_helpers_agree_with_the_core():
    from sc_rt import _core

    rng = np.random.default_rng(9)
    a, b = rng.uniform(-0.6, 0.6, (20, 3)), rng.uniform(-0.6, 0.6, (20, 3))
    got = mrp_subtract(a, b)
    for i in range(20):
        np.testing.assert_allclose(got[i], _core.mrp_subtract(a[i], b[i]), atol=1e-14)


# --------------------------------------------------------------------------------------------- #
# 4.-5. Knowledge error, wheels, commands, envelope on real runs


def test_knowledge_error_is_the_estimate_against_the_truth():
    from sc_rt.sim.engines import simulate

    scn = load_scenario("ppc_feasible_10hz_sensors")
    scn = dataclasses.replace(scn, requirements=(
        Requirement("ake", "AKE", axis="norm", bound=10.0, unit="arcsec", confidence=0.95, interpretation="temporal",
                    t_from=5.0),
        Requirement("rke", "RKE", axis="norm", bound=10.0, unit="arcsec", confidence=0.95, interpretation="temporal",
                    t_from=5.0, window=2.0),
        Requirement("ape", "APE", axis="norm", bound=60.0, unit="arcsec", confidence=0.95, interpretation="temporal",
                    t_from=5.0)))
    run = simulate(scn, engine="cpp", duration=30.0)
    t = run["t"]
    span = (t >= 5.0 - 1e-9) & run.present("att_est_error")
    # the core's own estimation error (rotation vector of the truth relative to the estimate)
    core = np.linalg.norm(run["att_est_error"][span], axis=1) / ARCSEC
    ake = result(run, "ake")
    assert ake["value"] == pytest.approx(np.quantile(core, 0.95, method="inverted_cdf"), rel=1e-6)
    assert result(run, "rke")["status"] in ("pass", "fail")
    # the performance error of a sensed run is the truth against the reference, not what the law saw
    true_angle = 4.0 * np.arctan(np.linalg.norm(run["sigma_BD_true"][t >= 5.0 - 1e-9], axis=1)) / ARCSEC
    assert result(run, "ape")["value"] == pytest.approx(np.quantile(true_angle, 0.95, method="inverted_cdf"),
                                                        rel=1e-12)
    # with sensors each pointing row carries its counterpart, at the same p, span and window
    ape, rke = result(run, "ape"), result(run, "rke")
    assert ape["counterpart"] == {"kind": "AKE", "value": pytest.approx(ake["value"], rel=1e-12), "unit": "arcsec"}
    assert ake["counterpart"]["kind"] == "APE" and ake["counterpart"]["value"] == pytest.approx(ape["value"])
    assert rke["counterpart"]["kind"] == "RPE" and "beside it RPE" in rke["note"]
    from sc_rt.results.present.html_requirements import requirements_table

    html = requirements_table(run.metrics["requirements"])
    assert f"AKE {ake['value']:.4g} arcsec" in html and "beside it" in html


def test_knowledge_without_sensors_is_not_applicable_and_ensemble_left_to_a_campaign():
    t = grid(20.0)
    run = run_of(t, about_x(1e-5 * t), [
        req("ake", "AKE", axis="norm", bound=10.0, unit="arcsec", confidence=0.95, interpretation="temporal"),
        req("ens", "APE", axis="norm", bound=10.0, unit="arcsec", confidence=0.95, interpretation="ensemble"),
        req("ok", "APE", axis="norm", bound=1e6, unit="arcsec", confidence=0.95, interpretation="temporal")])
    ake, ens = result(run, "ake"), result(run, "ens")
    assert ake["status"] == "not applicable" and ake["passed"] is None and "[sensors]" in ake["note"]
    assert ens["status"] == "not evaluated" and ens["passed"] is None and "sc-rt montecarlo" in ens["note"]
    line = verdict_line(run.metrics, "x")
    assert line.startswith("x: 1/1 requirements met, 1 not applicable, 1 across runs only (sc-rt montecarlo), "
                           "worst margin ok"), line


def test_wheel_speed_and_command_are_the_largest_magnitudes():
    t = grid(10.0)
    ws = np.zeros((len(t), 4))
    ws[:, 2] = -100.0 - t  # wheel 3: -110 rad/s (1050 rpm) at 10 s, the largest
    u = np.zeros((len(t), 4))
    u[37, 1] = -8.5
    run = run_of(t, np.zeros((len(t), 3)), [req("w", "wheel_speed_margin", bound=1100.0, unit="rpm"),
                                            req("u", "max_command", bound=7.0, unit="rad/s^2")],
                 wheel_speed=ws, u_cmd=u)
    w, c = result(run, "w"), result(run, "u")
    assert w["value"] == pytest.approx(110.0 * 60.0 / (2.0 * math.pi)) and w["passed"]
    assert "wheel 3 at 10 s" in w["note"]
    assert c["value"] == 8.5 and c["margin"] == pytest.approx(-1.5) and c["passed"] is False
    assert "wheel 2 at 3.7 s" in c["note"]


def test_the_envelope_requirement_is_the_metrics_first_violation():
    # a constant envelope (-0.1, 0.2) on every axis; the error leaves it on y at t = 12.3 s
    ppc = {k: (v,) * 3 for k, v in dict(chi0=0.2, chiinf=0.2, gamma=0.0, dmin=0.5, dmax=1.0).items()}
    t = grid(30.0)
    sigma = np.zeros((len(t), 3))
    sigma[:, 0] = 0.19  # 95 % of the upper bound on x: inside
    sigma[t >= 12.3 - 1e-9, 1] = -0.11
    meta = RunMeta(scenario="c", law="pd", engine="python", control_rate_hz=RATE, duration_s=30.0, ppc=ppc,
                   umin=(-7.0,) * 4, umax=(10.0,) * 4, requirements=(req("env", "envelope"),))
    m = finish_run(Run(meta, {"t": t, "sigma_BD": sigma})).metrics
    r = m["requirements"][0]
    assert m["first_bound_violation_s"] == pytest.approx(12.3) and m["first_bound_violation_axis"] == 2
    assert r["first_violation_s"] == m["first_bound_violation_s"] and r["first_violation_axis"] == 2
    assert r["passed"] is False and r["value"] == pytest.approx(0.11 / 0.1) and r["margin"] == pytest.approx(-0.1)
    # the paper's verdict line is unchanged for a scenario that asks for the envelope only
    assert verdict_line(m, "x") == "x: left its prescribed bound at 12.30 s (axis y)"
    sigma[:, 1] = 0.0
    m = finish_run(Run(meta, {"t": t, "sigma_BD": sigma})).metrics
    assert m["requirements"][0]["passed"] and m["requirements"][0]["value"] == pytest.approx(0.95)
    assert m["first_bound_violation_s"] is None and verdict_line(m, "x").startswith("x: bound held 30 s")


def test_the_paper_run_keeps_its_verdict_through_its_envelope_requirement():
    from sc_rt.sim.engines import simulate

    m = simulate(load_scenario("paper_faults"), engine="cpp").metrics
    (r,) = m["requirements"]
    assert r["kind"] == "envelope" and r["first_violation_s"] == m["first_bound_violation_s"] == pytest.approx(4.1)
    assert verdict_line(m, "paper DSC+PPC").startswith("paper DSC+PPC: left its prescribed bound at 4.10 s (axis z)")


def test_a_run_without_requirements_is_not_judged_by_the_envelope(capsys):
    from sc_rt.cli.common import print_metrics
    from sc_rt.sim.engines import simulate

    scn = dataclasses.replace(load_scenario("paper_faults"), requirements=())
    m = simulate(scn, engine="cpp", duration=20.0).metrics
    assert m["requirements"] == [] and m["first_bound_violation_s"] is not None  # the metric is still there
    assert verdict_line(m, "p") == "p: no requirements stated"
    print_metrics(m)
    out = capsys.readouterr().out
    assert re.search(r"requirements\s+no requirements stated", out)
    # the envelope is not what it asks: its metric stays in metrics.json, the console does not show it
    assert "first bound violation" not in out and "envelope" not in out


# --------------------------------------------------------------------------------------------- #
# 6. The schema, the CLI, the worked example

HEAD = (ROOT / "scenarios" / "paper_fault_free.toml").read_text()
HEAD = HEAD[:HEAD.index("[[requirements]]")] + HEAD[HEAD.index("[run]"):]  # without its own requirement


def write(tmp_path: Path, rows: str) -> Path:
    p = tmp_path / "req.toml"
    p.write_text(HEAD + "\n" + rows)
    return p


def line_of(path: Path, text: str, nth: int = 0) -> int:
    lines = [i + 1 for i, line in enumerate(path.read_text().splitlines()) if line.strip().startswith(text)]
    return lines[nth]


def issues(path: Path) -> list:
    with pytest.raises(ScenarioError) as e:
        load_scenario(path)
    assert all(str(path) in line for line in str(e.value).splitlines())
    return e.value.errors


@pytest.mark.parametrize("rows, key, value, message, line_text", [
    ('[[requirements]]\nname = "a"\nkind = "APX"\n', "requirements[0].kind", "APX", "must be one of", "kind ="),
    ('[[requirements]]\nname = "a"\nkind = "APE"\nbound = -3.0\nunit = "arcsec"\nconfidence = 0.9\n',
     "requirements[0].bound", -3.0, "bound must be > 0", "bound ="),
    ('[[requirements]]\nname = "a"\nkind = "APE"\nbound = 3.0\nunit = "arcsecs"\nconfidence = 0.9\n',
     "requirements[0].unit", "arcsecs", "unit must be one of", "unit ="),
    ('[[requirements]]\nname = "a"\nkind = "APE"\nbound = 3.0\nconfidence = 0.9\n',
     "requirements[0].unit", None, "required key is missing", "[[requirements]]"),
    ('[[requirements]]\nname = "a"\nkind = "APE"\nbound = 3.0\nunit = "deg"\nconfidence = 1.5\n',
     "requirements[0].confidence", 1.5, "confidence must be in (0, 1]", "confidence ="),
    ('[[requirements]]\nname = "a"\nkind = "APE"\nbound = 3.0\nunit = "deg"\nconfidence = 0.9\nwindow = 10.0\n',
     "requirements[0].window", 10.0, 'does not apply to a kind = "APE"', "window ="),
    ('[[requirements]]\nname = "a"\nkind = "RPE"\nbound = 3.0\nunit = "deg"\nconfidence = 0.9\n',
     "requirements[0].window", None, "required key is missing", "[[requirements]]"),
    ('[[requirements]]\nname = "a"\nkind = "APE"\nbound = 3.0\nunit = "deg"\nconfidence = 0.9\n'
     'interpretation = "spatial"\n', "requirements[0].interpretation", "spatial", "must be one of", "interpretation ="),
    ('[[requirements]]\nname = "a"\nkind = "APE"\nbound = 3.0\nunit = "deg"\nconfidence = 0.9\nt_from = 50.0\n'
     't_to = 40.0\n', "requirements[0].t_to", 40.0, "t_to must be > t_from = 50 s", "t_to ="),
    ('[[requirements]]\nname = "a"\nkind = "APE"\nbound = 3.0\nunit = "deg"\nconfidence = 0.9\nt_to = 400.0\n',
     "requirements[0].t_to", 400.0, "t_to must be <= run.duration = 300 s", "t_to ="),
    ('[[requirements]]\nname = "a"\nkind = "APE"\nbound = 3.0\nunit = "deg"\nconfidence = 0.9\n'
     't_from = "after_settling"\n', "requirements[0].t_from", "after_settling", "needs the settling requirement",
     "t_from ="),
    ('[[requirements]]\nname = "a"\nkind = "APE"\nbound = 3.0\nunit = "deg"\nconfidence = 0.9\nt_from = "later"\n',
     "requirements[0].t_from", "later", 't_from must be a number >= 0 [s] or "after_settling"', "t_from ="),
    ('[[requirements]]\nname = "a"\nkind = "APE"\naxis = "cone"\nbound = 3.0\nunit = "deg"\nconfidence = 0.9\n',
     "requirements[0].boresight", None, 'axis = "cone"', "[[requirements]]"),
    ('[[requirements]]\nname = "a"\nkind = "APE"\naxis = "x"\nboresight = [0.0, 0.0, 1.0]\nbound = 3.0\n'
     'unit = "deg"\nconfidence = 0.9\n', "requirements[0].boresight", [0.0, 0.0, 1.0], 'applies to axis = "cone" only',
     "boresight ="),
    ('[[requirements]]\nname = "a"\nkind = "APE"\naxis = "cone"\nboresight = [0.0, 0.0, 0.0]\nbound = 3.0\n'
     'unit = "deg"\nconfidence = 0.9\n', "requirements[0].boresight", [0.0, 0.0, 0.0], "non-zero", "boresight ="),
    ('[[requirements]]\nname = "a"\nkind = "envelope"\nbound = 1.0\n', "requirements[0].bound", 1.0,
     'does not apply to a kind = "envelope"', "bound ="),
    ('[[requirements]]\nname = "a"\nkind = "wheel_speed_margin"\nbound = 1.0\nwindw = 3.0\n',
     "requirements[0].windw", 3.0, "unknown key", "windw ="),
    ('[[requirements]]\nname = "a"\nkind = "envelope"\n[[requirements]]\nname = "a"\nkind = "max_command"\n'
     'bound = 7.0\n', "requirements[1].name", "a", "is taken by requirements[0]", 'name = "a"'),
    ('[[requirements]]\nname = "s"\nkind = "envelope"\n[[requirements]]\nname = "a"\nkind = "APE"\nbound = 3.0\n'
     'unit = "deg"\nconfidence = 0.9\nt_from = "after_settling"\nsettling = "s"\n', "requirements[1].settling", "s",
     'is a kind = "envelope" requirement', "settling ="),
    ('[requirements]\nname = "a"\n', "requirements", {"name": "a"}, "array of tables", "[requirements]"),
    ('[[requirements]]\nname = "a"\nkind = "PDE"\nbound = 3.0\nunit = "arcsec"\nconfidence = 0.9\nwindow = 10.0\n',
     "requirements[0].separation", None, "required key is missing", "[[requirements]]"),
    ('[[requirements]]\nname = "a"\nkind = "PRE"\nbound = 3.0\nunit = "arcsec"\nconfidence = 0.9\nwindow = 10.0\n'
     'separation = -5.0\n', "requirements[0].separation", -5.0, "separation must be > 0", "separation ="),
    ('[[requirements]]\nname = "a"\nkind = "RPE"\nbound = 3.0\nunit = "arcsec"\nconfidence = 0.9\nwindow = 10.0\n'
     'separation = 5.0\n', "requirements[0].separation", 5.0, 'does not apply to a kind = "RPE"', "separation ="),
    ('[[requirements]]\nname = "a"\nkind = "momentum_margin"\nbound = 1.0\nunit = "Nms"\n',
     "requirements[0].unit", "Nms", "unit must be one of", "unit ="),
    ('[[requirements]]\nname = "a"\nkind = "momentum_margin"\nbound = 1.0\nwindow = 3.0\n',
     "requirements[0].window", 3.0, 'does not apply to a kind = "momentum_margin"', "window ="),
    ('[[requirements]]\nname = "a"\nkind = "APE"\nbound = 3.0\nunit = "arcsec"\nconfidence = 0.9\nmode = "fine"\n',
     "requirements[0].mode", "fine", 'must be one of "normal", "nav_ok"', "mode ="),
    ('[[requirements]]\nname = "a"\nkind = "settling"\nbound = 3.0\nunit = "arcsec"\nsettle_by = 9.0\n'
     'mode = "normal"\n', "requirements[0].mode", "normal", 'does not apply to a kind = "settling"', "mode ="),
    ('[[requirements]]\nname = "a"\nkind = "max_torque"\nbound = 1.0\nunit = "Nm"\n',
     "requirements[0].unit", "Nm", "unit must be one of", "unit ="),
])
def test_a_bad_requirement_names_file_line_key_and_value(tmp_path, rows, key, value, message, line_text):
    p = write(tmp_path, rows)
    errs = issues(p)
    hit = [e for e in errs if e.key == key]
    assert hit, errs
    e = hit[0]
    assert e.value == value and message in e.message, e
    nth = 1 if key == "requirements[1].name" else 0
    assert e.line == line_of(p, line_text, nth) > 0, (e, line_text)


def test_the_cli_exits_2_on_a_bad_requirement(tmp_path, capsys):
    from sc_rt.cli import main

    p = write(tmp_path, '[[requirements]]\nname = "a"\nkind = "RPE"\nbound = 3.0\nunit = "arcsec"\n'
                        'confidence = 0.9973\n')
    assert main(["sim", str(p), "--engine", "cpp", "--out", str(tmp_path / "o"), "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert f"{p}:{line_of(p, '[[requirements]]')}: requirements[0].window: required key is missing" in err


def test_requirements_read_back_through_the_scenario_data(tmp_path):
    from sc_rt.scenario.keys import numeric_keys, scenario_data
    from sc_rt.scenario.reader import scenario_from_data

    scn = load_scenario("mrp_feedback_requirements")
    data = scenario_data(scn)
    assert [r["name"] for r in data["requirements"]] == [r.name for r in scn.requirements]
    assert scenario_from_data(data, scn.path).requirements == scn.requirements
    assert not any(k.startswith("requirements") for k in numeric_keys(data))  # not dispersed by [montecarlo]


def test_the_worked_example_reports_each_requirement(tmp_path, capsys):
    from sc_rt.cli import main

    out = tmp_path / "req"
    assert main(["sim", "mrp_feedback_requirements", "--engine", "cpp", "--out", str(out), "--no-plots"]) == 0
    console = capsys.readouterr().out
    m = json.loads((out / "metrics.json").read_text())
    reqs = {r["name"]: r for r in m["requirements"]}
    assert list(reqs) == ["pointing", "stability", "pointing_ensemble", "stability_mixed", "settling", "payload_cone",
                          "wheel_speed", "momentum", "command"]
    across = ("pointing_ensemble", "stability_mixed")  # statistics across runs: sc-rt montecarlo's
    for name, r in reqs.items():
        if name in across:
            assert r["passed"] is None and r["value"] is None, name
            assert re.search(rf"^\s+{name}\s.*\bacross runs$", console, re.M), (name, console)
            continue
        assert r["passed"] is True and r["margin"] == pytest.approx(r["bound"] - r["value"]), name
        assert re.search(rf"^\s+{name}\s.*\bPASS$", console, re.M), (name, console)
    assert reqs["pointing"]["unit"] == "arcsec" and reqs["pointing"]["confidence"] == 0.9973
    assert reqs["stability"]["window_s"] == pytest.approx(10.0)
    assert reqs["payload_cone"]["span_s"][0] == reqs["settling"]["value"]
    assert "7/7 requirements met, 2 across runs only (sc-rt montecarlo), worst margin" in console


def test_a_span_past_the_runs_end_is_cut_or_failed_when_the_run_diverged():
    t = grid(50.0)
    rows = [req("ape", "APE", axis="norm", bound=30.0, unit="arcsec", confidence=0.9, interpretation="temporal",
                t_from=10.0, t_to=100.0),
            req("late", "APE", axis="norm", bound=30.0, unit="arcsec", confidence=0.9, interpretation="temporal",
                t_from=60.0)]
    run = run_of(t, np.zeros((len(t), 3)), rows)  # a run of 50 s (duration_s = 50): shortened on purpose
    ape, late = result(run, "ape"), result(run, "late")
    assert ape["passed"] is True and "cut at the run's end, 50 s (asked: 100 s)" in ape["note"]
    assert late["status"] == "not evaluated" and "no row in the span" in late["note"]
    meta = dataclasses.replace(run.meta, duration_s=300.0)
    diverged = finish_run(Run(meta, {"t": t, "sigma_BD": np.zeros((len(t), 3))}, diverged=True))
    ape, late = result(diverged, "ape"), result(diverged, "late")
    assert ape["passed"] is False and late["passed"] is False and "diverged at 50 s" in ape["note"]
    assert verdict_line(diverged.metrics, "x").startswith("x: 2 of 2 requirements failed (ape, late)")


def test_compare_ranks_the_laws_by_margin_per_requirement(tmp_path, capsys):
    """Issue #27 item 5: sc-rt compare ranks the laws on each requirement by
    its margin relative to the bound (recomputed here from value and bound),
    best first, and overall by each law's worst; the rows across runs are
    left to sc-rt montecarlo."""
    from sc_rt.cli import main

    out = tmp_path / "cmp"
    assert main(["compare", "mrp_feedback_requirements", "--law", "pd", "--law", "dsc", "--out", str(out)]) == 0
    console = capsys.readouterr().out
    doc = json.loads((out / "compare.json").read_text())
    by_law = {row["law"]: {r["name"]: r for r in row["requirements"]} for row in doc["rows"]}
    names = [r.name for r in load_scenario("mrp_feedback_requirements").requirements]
    across = {"pointing_ensemble", "stability_mixed"}
    assert set(doc["ranking"]) == set(names) - across
    for name in doc["ranking"]:
        rel = {law: (r[name]["bound"] - r[name]["value"]) / r[name]["bound"] for law, r in by_law.items()}
        assert doc["ranking"][name] == sorted(rel, key=lambda law: -rel[law]), name
        best = doc["ranking"][name][0]
        assert re.search(rf"^\| {name} \| 1 \| {best} \|", console, re.M), (name, console)
    worst = {law: min((r["bound"] - r["value"]) / r["bound"] for n, r in reqs.items() if n not in across)
             for law, reqs in by_law.items()}
    assert doc["overall"] == sorted(worst, key=lambda law: -worst[law])
    assert "judged across runs only, by sc-rt montecarlo: pointing_ensemble, stability_mixed" in console
    assert "The laws ranked by margin" in (out / "compare.md").read_text()


# --------------------------------------------------------------------------------------------- #
# Mode windows and the commanded body torque (issue #27, item 1)


def test_the_mode_constants_are_the_cores():
    from sc_rt import _core
    from sc_rt.results.judge.pointing import FLAG_NAV_DEGRADED, MODE_NORMAL

    assert (MODE_NORMAL, FLAG_NAV_DEGRADED) == (_core.MODE_NORMAL, _core.FLAG_NAV_DEGRADED)


def test_a_requirement_in_the_normal_mode_leaves_the_safe_rows_out():
    """5 arcsec while the law commands, 100 arcsec during a SAFE spell from
    40 to 60 s: APE over every row sees the spell, APE in mode "normal" does
    not (the nearest-rank quantile of the NORMAL rows, computed here); RPE in
    mode "normal" keeps exactly the windows that touch no SAFE row."""
    t = grid(120.0)
    safe = (t >= 40.0) & (t < 60.0)
    theta = np.where(safe, 100.0, 5.0 + 0.5 * np.sin(t)) * ARCSEC
    mode = np.where(safe, 2, 1)
    rows = [req("all", "APE", axis="x", bound=10.0, unit="arcsec", confidence=0.99, interpretation="temporal"),
            req("normal", "APE", axis="x", bound=10.0, unit="arcsec", confidence=0.99, interpretation="temporal",
                mode="normal"),
            req("rpe", "RPE", axis="x", bound=10.0, unit="arcsec", confidence=0.9, interpretation="temporal",
                window=7.0, mode="normal")]
    run = run_of(t, about_x(theta), rows, ctrl_mode=mode)
    everything, normal, rpe = result(run, "all"), result(run, "normal"), result(run, "rpe")
    assert everything["passed"] is False and everything["value"] == pytest.approx(100.0, rel=1e-9)
    direct = nearest_rank(np.abs(theta[~safe]) / ARCSEC, 0.99)
    assert normal["value"] == pytest.approx(direct, rel=1e-9) and normal["passed"] is True
    assert f'{int(safe.sum())} rows outside mode "normal" left out' in normal["note"]
    n = int(round(7.0 * RATE))
    starts = np.arange(0, len(t) - n + 1, n)
    clean = [k for k in starts if not safe[k:k + n].any()]
    assert rpe["windows"] == len(clean) < len(starts)
    direct_rpe = np.concatenate([np.abs(theta[k:k + n] - theta[k:k + n].mean()) / ARCSEC for k in clean])
    assert rpe["value"] == pytest.approx(nearest_rank(direct_rpe, 0.9), rel=1e-9)  # every instant of them
    window_max = [np.max(np.abs(theta[k:k + n] - theta[k:k + n].mean())) / ARCSEC for k in clean]
    assert rpe["window_max_bound"] == pytest.approx(nearest_rank(np.array(window_max), 0.9), rel=1e-9)


def test_max_torque_is_the_commanded_body_torque_and_nav_ok_leaves_degraded_rows_out():
    from sc_rt.results.judge.pointing import FLAG_NAV_DEGRADED

    t = grid(30.0)
    u = np.zeros((len(t), 4))
    u[:, 0] = 2.0 * np.sin(t)
    u[:, 3] = -1.5 + 0.1 * t
    degraded = (t > 10.0) & (t < 12.0)
    u[degraded, 1] = 9.0  # a burst while the navigation is degraded
    flags = np.where(degraded, FLAG_NAV_DEGRADED, 0)
    Cbar = np.array([[1.0, 0.0, 0.0, 0.6], [0.0, 1.0, 0.0, 0.64], [0.0, 0.0, 1.0, 0.48]])
    Jw = np.array([0.1, 0.1, 0.1, 0.2])
    meta = RunMeta(scenario="c", law="pd", engine="python", control_rate_hz=RATE, duration_s=30.0, ppc=WIDE,
                   umin=(-7.0,) * 4, umax=(10.0,) * 4, Cbar=tuple(map(tuple, Cbar)), Jw=tuple(Jw),
                   requirements=(req("tau", "max_torque", bound=500.0, unit="mN m"),
                                 req("tau_nav", "max_torque", bound=500.0, unit="mN m", mode="nav_ok"),
                                 req("cmd_nav", "max_command", bound=5.0, unit="rad/s^2", mode="nav_ok")))
    run = finish_run(Run(meta, {"t": t, "sigma_BD": np.zeros((len(t), 3)), "u_cmd": u, "flags": flags}))
    tau = np.array([np.linalg.norm(Cbar @ (Jw * row)) for row in u])  # row by row [N m]
    assert result(run, "tau")["value"] == pytest.approx(1000.0 * tau.max(), rel=1e-12)
    assert result(run, "tau")["passed"] is False  # the burst: 0.9 N m and more
    assert result(run, "tau_nav")["value"] == pytest.approx(1000.0 * tau[~degraded].max(), rel=1e-12)
    assert result(run, "tau_nav")["passed"] is True
    assert result(run, "cmd_nav")["value"] == pytest.approx(np.abs(u[~degraded]).max(), rel=1e-12)
