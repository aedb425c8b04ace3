"""The requirements across the runs of a campaign (issue #27, items 3 and 6;
sc_rt.studies.campaign.requirements, sc_rt.studies.campaign.stats,
sc_rt.results.judge.ensemble, docs/REQUIREMENTS.md section 4).

Every statistic is checked against something computed independently here:

1. the one-sided Clopper-Pearson bound against scipy's exact binomial test
   and against its definition in the binomial distribution (59 of 59 at 95 %:
   0.05^(1/59));
2. the runs a statement needs (Wilks / binomial minimum) by counting up n
   with scipy.stats.binom;
3. the upper confidence bound of a quantile by its coverage over many
   simulated campaigns of known quantile, and its duality with (1);
4. Hoeffding's bound by its definition and its coverage;
5. a campaign's ensemble statistics of constructed series against numpy's
   quantile and direct counts; a run's series against a direct binning of a
   constructed signal;
6. the command: montecarlo on the worked example (59 runs: the 95 % bound
   0.9505), its options.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binom, binomtest

from sc_rt.results.judge.ensemble import bin_width, campaign_series, n_bins
from sc_rt.results.judge.metrics import finish_run
from sc_rt.results.record.run import Run, RunMeta
from sc_rt.scenario.tables.requirements import Requirement
from sc_rt.studies.campaign.requirements import campaign_requirements, row_columns
from sc_rt.studies.campaign.stats import (clopper_pearson_lower, hoeffding_lower, quantile_upper_rank,
                                          runs_needed)

ARCSEC = math.pi / 648000.0
RATE = 10.0
WIDE = {k: (v,) * 3 for k, v in dict(chi0=1.0, chiinf=1.0, gamma=0.0, dmin=1.0, dmax=1.0).items()}


# --------------------------------------------------------------------------------------------- #
# 1.-4. The statistics


@pytest.mark.parametrize("k, n", [(59, 59), (58, 59), (0, 10), (1, 10), (97, 100), (299, 299), (5, 7)])
@pytest.mark.parametrize("confidence", [0.9, 0.95, 0.99])
def test_one_sided_clopper_pearson_is_the_exact_binomial_bound(k, n, confidence):
    lb = clopper_pearson_lower(k, n, confidence)
    exact = binomtest(k, n, alternative="greater").proportion_ci(confidence_level=confidence, method="exact").low
    assert lb == pytest.approx(exact, abs=1e-10)
    if 0 < k:  # the definition: at p = lb, k or more successes have probability exactly 1 - confidence
        assert binom.sf(k - 1, n, lb) == pytest.approx(1.0 - confidence, rel=1e-6)
    if k == n:  # zero failures: p^n = 1 - confidence
        assert lb == pytest.approx((1.0 - confidence) ** (1.0 / n), rel=1e-12)


def test_59_of_59_supports_095_at_95_percent_and_58_does_not():
    assert clopper_pearson_lower(59, 59, 0.95) == pytest.approx(1.0 - (1.0 - 0.05 ** (1.0 / 59)), rel=1e-12)
    assert clopper_pearson_lower(59, 59, 0.95) >= 0.95 > clopper_pearson_lower(58, 58, 0.95)


def _brute_runs(p: float, confidence: float, failures: int) -> int:
    """The fewest n for which n - failures successes show P >= p at the confidence: P(X >= n - f | p) <= 1 - C."""
    n = failures + 1
    while binom.sf(n - failures - 1, n, p) > 1.0 - confidence:
        n += 1
    return n


@pytest.mark.parametrize("p, confidence, failures", [(0.95, 0.95, 0), (0.9973, 0.95, 0), (0.99, 0.9, 0),
                                                     (0.95, 0.95, 1), (0.95, 0.95, 3), (0.9, 0.99, 2)])
def test_runs_needed_is_the_binomial_minimum(p, confidence, failures):
    n = runs_needed(p, confidence, failures)
    assert n == _brute_runs(p, confidence, failures)
    if failures == 0:  # Wilks first order: p^n <= 1 - C < p^(n - 1)
        assert p**n <= 1.0 - confidence < p ** (n - 1)


@pytest.mark.parametrize("n, p", [(59, 0.95), (100, 0.95), (30, 0.9), (400, 0.9973), (58, 0.95)])
def test_the_quantile_upper_bound_covers_the_true_quantile(n, p):
    """Simulated campaigns of n exponential samples (quantile -ln(1 - p)):
    the order statistic the code picks is above the true quantile in at
    least 95 % of them (less only by the simulation's noise), the one below
    it is not."""
    conf, trials = 0.95, 4000
    r = quantile_upper_rank(n, p, conf)
    if n < math.log(1 - conf) / math.log(p):  # too few runs even for the maximum
        assert r == 0
        return
    x = np.sort(np.random.default_rng(n).standard_exponential((trials, n)), axis=1)
    q = -math.log(1.0 - p)
    covered = np.mean(x[:, r - 1] >= q)
    assert covered >= conf - 3.0 * math.sqrt(conf * (1 - conf) / trials)
    if r > 1:  # minimal: the next lower order statistic is below the confidence (in exact terms)
        assert binom.cdf(r - 2, n, p) < conf <= binom.cdf(r - 1, n, p)


def test_the_quantile_bound_and_the_fraction_bound_say_the_same():
    """The r-th smallest sample is within b exactly when the lower bound of
    the fraction within b reaches p (the duality the ensemble verdict uses)."""
    rng = np.random.default_rng(3)
    for _ in range(300):
        n = int(rng.integers(20, 400))
        p = float(rng.choice([0.9, 0.95, 0.99]))
        x = np.sort(rng.standard_exponential(n))
        b = float(rng.uniform(0.5, 8.0))
        k = int(np.sum(x <= b))
        r = quantile_upper_rank(n, p, 0.95)
        assert (r > 0 and x[r - 1] <= b) == (clopper_pearson_lower(k, n, 0.95) >= p), (n, p, b, k, r)


def test_hoeffding_lower_bound_definition_and_coverage():
    assert hoeffding_lower(0.9, 100, 0.95) == pytest.approx(0.9 - math.sqrt(math.log(20.0) / 200.0))
    assert hoeffding_lower(0.1, 10, 0.95) == 0.0
    rng = np.random.default_rng(1)
    f = rng.beta(20.0, 1.0, (5000, 30))  # values in [0, 1], mean 20/21
    lb = np.array([hoeffding_lower(m, 30, 0.95) for m in f.mean(axis=1)])
    assert np.mean(lb <= 20.0 / 21.0) >= 0.95


# --------------------------------------------------------------------------------------------- #
# 5. A campaign's statistics on constructed rows


def _row(name: str, passed, value=None, status=None, **extra) -> dict:
    r = {f"req.{name}.passed": passed, f"req.{name}.value": value,
         f"req.{name}.status": status or ("pass" if passed else "fail" if passed is False else "not evaluated")}
    r.update({f"req.{name}.{k}": v for k, v in extra.items()})
    return r


APE = Requirement("ape", "APE", axis="norm", bound=30.0, unit="arcsec", confidence=0.9973, interpretation="temporal")


@pytest.mark.parametrize("met, n", [(59, 59), (58, 58), (57, 59), (95, 100)])
def test_a_per_run_requirement_across_runs(met, n):
    rng = np.random.default_rng(met)
    values = rng.uniform(5.0, 25.0, n)
    rows = [_row("ape", i < met, float(values[i]) if i < met else 40.0) for i in range(n)]
    (s,) = campaign_requirements((APE,), rows, 300.0, 10.0, confidence=0.95, coverage=0.95)
    exact = binomtest(met, n).proportion_ci(confidence_level=0.95, method="exact")
    assert s["runs_met"] == met and s["runs"] == n and s["fraction"] == met / n
    assert s["interval"] == [pytest.approx(exact.low, abs=1e-12), pytest.approx(exact.high, abs=1e-12)]
    lb = binomtest(met, n, alternative="greater").proportion_ci(confidence_level=0.95, method="exact").low
    assert s["lower_bound"] == pytest.approx(lb, abs=1e-10)
    assert s["met_at_confidence"] is (lb >= 0.95)
    assert s["runs_needed_without_failure"] == _brute_runs(0.95, 0.95, 0) == 59
    if met < n and met / n >= 0.95:
        assert s["runs_needed_with_these_failures"] == _brute_runs(0.95, 0.95, n - met)
    elif met < n:
        assert s["runs_needed_with_these_failures"] is None  # the fraction seen is below the one required
    allv = np.sort(np.array([float(values[i]) if i < met else 40.0 for i in range(n)]))
    assert s["across_runs"]["value"] == np.quantile(allv, 0.95, method="inverted_cdf")


def test_a_run_without_a_result_counts_as_not_meeting():
    rows = [_row("ape", True, 10.0)] * 58 + [{"run": 58, "status": "invalid"}]
    (s,) = campaign_requirements((APE,), rows, 300.0, 10.0)
    assert s["runs_met"] == 58 and s["runs"] == 59 and s["met_at_confidence"] is False


def test_ensemble_statistics_of_constructed_series_against_numpy():
    req = Requirement("ens", "APE", axis="norm", bound=20.0, unit="arcsec", confidence=0.9,
                      interpretation="ensemble", t_from=10.0)
    width = bin_width(100.0, RATE)
    nb = n_bins(100.0, width)
    rng = np.random.default_rng(4)
    n = 40
    m = np.full((n, nb), np.nan)
    m[:, 10:] = rng.uniform(0.0, 25.0, (n, nb - 10))  # the span from 10 s
    m[:, 50:] = np.minimum(m[:, 50:], 19.0)            # within after 50 s, in every run
    rows = [{**_row("ens", None, bins=list(m[i]), within=0.5)} for i in range(n)]
    (s,) = campaign_requirements((req,), rows, 100.0, RATE, confidence=0.95)
    per = s["per_bin"]
    assert per["t_s"] == [pytest.approx(j * width) for j in range(10, nb)]
    for j, tj in enumerate(range(10, nb)):
        col = m[:, tj]
        assert per["runs"][j] == n and per["within"][j] == int(np.sum(col <= 20.0))
        assert per["quantile"][j] == np.quantile(col, 0.9, method="inverted_cdf")
        k = int(np.sum(col <= 20.0))
        assert per["lower_bound"][j] == pytest.approx(
            binomtest(k, n, alternative="greater").proportion_ci(0.95, method="exact").low, abs=1e-10)
    worst = int(np.argmin(per["lower_bound"]))
    assert s["worst_t_s"] == per["t_s"][worst] and s["met_at_confidence"] is False
    # within the bound in every run from 50 s: judged on those bins alone, 40/40 at p = 0.9 is shown
    rows = [{**_row("ens", None, bins=list(np.where(np.arange(nb) < 50, np.nan, m[i])), within=1.0)}
            for i in range(n)]
    (s,) = campaign_requirements((req,), rows, 100.0, RATE, confidence=0.95)
    assert s["worst"]["lower_bound"] == pytest.approx(0.05 ** (1 / 40)) and s["met_at_confidence"] is True
    assert s["upper_bound_max"] == max(np.max(m[:, j]) for j in range(50, nb))  # p0.9 of 40 at 95 %: the maximum
    # a run with no series (an invalid draw) fails in every bin of the span
    (s,) = campaign_requirements((req,), rows + [{"run": 99}], 100.0, RATE, confidence=0.95)
    assert s["worst"]["runs"] == 41 and s["worst"]["runs_met"] == 40


def test_mixed_statistics_against_their_definitions():
    req = Requirement("mix", "RPE", axis="norm", bound=5.0, unit="arcsec", confidence=0.99,
                      interpretation="mixed", window=10.0)
    f = np.r_[np.ones(50), np.full(10, 0.995)]
    rows = [_row("mix", None, bins=[1.0, 2.0], within=float(x)) for x in f]
    (s,) = campaign_requirements((req,), rows, 100.0, RATE, confidence=0.95)
    hoeff = f.mean() - math.sqrt(math.log(1.0 / 0.025) / (2 * 60))
    cp = binomtest(50, 60, alternative="greater").proportion_ci(0.975, method="exact").low
    assert s["mean_within"] == pytest.approx(f.mean()) and s["runs_never_outside"] == 50
    assert s["lower_bound"] == pytest.approx(max(hoeff, cp), abs=1e-10)
    assert s["met_at_confidence"] is False and s["runs_needed_without_failure"] == _brute_runs(0.99, 0.975, 0)
    assert s["pooled_quantile"] == 2.0


# --------------------------------------------------------------------------------------------- #
# 5. A run's series


def _run(t, sigma, reqs, diverged=False, duration=None):
    meta = RunMeta(scenario="c", law="pd", engine="python", control_rate_hz=RATE,
                   duration_s=float(duration or t[-1]), ppc=WIDE, umin=(-7.0,) * 4, umax=(10.0,) * 4,
                   requirements=tuple(dataclasses.asdict(r) for r in reqs))
    return finish_run(Run(meta, {"t": t, "sigma_BD": sigma}, diverged=diverged))


def _about_x(theta):
    s = np.zeros((len(theta), 3))
    s[:, 0] = np.tan(theta / 4.0)
    return s


def test_a_runs_series_is_the_binned_maximum_of_its_values():
    t = np.arange(1001) / RATE  # 100 s
    theta = 20.0 * ARCSEC * (1.0 + np.sin(2 * np.pi * t / 7.0))
    reqs = (Requirement("ens", "APE", axis="x", bound=30.0, unit="arcsec", confidence=0.95,
                        interpretation="ensemble", t_from=20.0),
            Requirement("mix", "RPE", axis="x", bound=1.0, unit="arcsec", confidence=0.95,
                        interpretation="mixed", window=4.0, t_from=20.0))
    run = _run(t, _about_x(theta), reqs)
    series = campaign_series(run, run.metrics["requirements"])
    width = bin_width(100.0, RATE)
    assert width == pytest.approx(0.4) and len(series["ens"]["bins"]) == n_bins(100.0, width) == 251
    bins = np.array(series["ens"]["bins"])
    for j in range(len(bins)):
        sel = (t >= max(20.0, j * width) - 1e-9) & (t < (j + 1) * width - 1e-9)
        want = np.max(np.abs(theta[sel])) / ARCSEC if np.any(sel) else np.nan
        np.testing.assert_allclose(bins[j], want, rtol=1e-9, equal_nan=True)
    span = t >= 20.0 - 1e-9
    assert series["ens"]["within"] == pytest.approx(np.mean(np.abs(theta[span]) / ARCSEC <= 30.0))
    assert 0.5 < series["ens"]["within"] < 0.8  # the sine reaches 40 arcsec: some of it is outside
    # RPE over 4 s windows from 20 s: every instant's |e - its window's mean| (ECSS-E-ST-60-10C 3.2.12) in
    # its bin; within: the instants <= 1 arcsec
    e = theta[t >= 20.0 - 1e-9] / ARCSEC
    tt = t[t >= 20.0 - 1e-9]
    ks = range(0, len(e) - 39, 40)
    per = np.concatenate([np.abs(e[k:k + 40] - e[k:k + 40].mean()) for k in ks])
    at = np.concatenate([tt[k:k + 40] for k in ks])
    assert series["mix"]["within"] == pytest.approx(np.mean(per <= 1.0))
    mb = np.array(series["mix"]["bins"])
    assert np.nanmax(mb) == pytest.approx(per.max()) and np.all(np.isnan(mb[:50]))
    for j in range(50, len(mb)):  # each bin: the largest relative error of its instants
        sel = (at >= j * width - 1e-9) & (at < (j + 1) * width - 1e-9)
        np.testing.assert_allclose(mb[j], per[sel].max() if sel.any() else np.nan, rtol=1e-9, equal_nan=True)
    # columns of the dataset row
    row = row_columns(run.metrics["requirements"], series)
    assert row["req.ens.passed"] is None and row["req.ens.bins"] == series["ens"]["bins"]
    assert row["meets_requirements"] is None  # nothing judged within the run


def test_a_diverged_run_fails_the_rest_of_its_span():
    t = np.arange(401) / RATE  # stopped at 40 s of 100
    req = Requirement("ens", "APE", axis="x", bound=30.0, unit="arcsec", confidence=0.95,
                      interpretation="ensemble", t_from=20.0)
    run = _run(t, _about_x(np.full(len(t), 10.0 * ARCSEC)), (req,), diverged=True, duration=100.0)
    s = campaign_series(run, run.metrics["requirements"])["ens"]
    b = np.array(s["bins"])
    width = bin_width(100.0, RATE)
    last = int(math.floor(40.0 / width + 1e-9))
    assert np.all(b[int(20.0 / width):last + 1] == pytest.approx(10.0)) and np.all(np.isinf(b[last + 1:]))
    assert s["within"] == pytest.approx(20.0 / 80.0)  # within for 20 of its 80 s


def test_a_run_that_never_settles_fails_an_ensemble_row_from_its_settle_by():
    t = np.arange(1001) / RATE
    theta = np.full(len(t), 40.0 * ARCSEC)  # never within the 30 arcsec band
    reqs = (Requirement("s", "settling", axis="x", bound=30.0, unit="arcsec", settle_by=25.0),
            Requirement("ens", "APE", axis="x", bound=30.0, unit="arcsec", confidence=0.95,
                        interpretation="ensemble", t_from="after_settling", settling="s"))
    run = _run(t, _about_x(theta), reqs)
    s = campaign_series(run, run.metrics["requirements"])["ens"]
    b = np.array(s["bins"])
    first = int(math.floor(25.0 / bin_width(100.0, RATE) + 1e-9))
    assert np.all(np.isnan(b[:first])) and np.all(np.isinf(b[first:])) and s["within"] == 0.0


# --------------------------------------------------------------------------------------------- #
# 6. The command


def test_montecarlo_on_the_worked_example_reports_each_requirement(tmp_path):
    from sc_rt.scenario.reader import load_scenario
    from sc_rt.studies.montecarlo import run_montecarlo

    res = run_montecarlo(load_scenario("mrp_feedback_requirements"), 4, workers=1, backend="serial",
                         progress=False, out=tmp_path / "mc")
    reqs = {r["name"]: r for r in res["requirements"]}
    assert res["judged_by"] == "requirements" and res["meets_requirements"] == 4
    assert reqs["pointing"]["statistic"] == "runs" and reqs["pointing"]["runs_met"] == 4
    assert reqs["pointing"]["lower_bound"] == pytest.approx(0.05 ** 0.25) and not reqs["pointing"]["met_at_confidence"]
    assert reqs["pointing"]["runs_needed_without_failure"] == 59
    ens = reqs["pointing_ensemble"]
    assert ens["statistic"] == "ensemble" and ens["per_bin"]["t_s"][0] == 60.0 and ens["bins"] == 241
    assert ens["upper_bound_max"] is None and ens["runs_needed_without_failure"] == 59  # 4 runs: no bound yet
    per = res["per_run"]
    q = [np.quantile([r["req.pointing_ensemble.bins"][60 + j] for r in per], 0.95, method="inverted_cdf")
         for j in range(241)]
    assert ens["per_bin"]["quantile"] == q
    mix = reqs["stability_mixed"]
    assert mix["statistic"] == "mixed" and mix["runs_needed_without_failure"] == _brute_runs(0.9973, 0.975, 0)
    assert reqs["settling"]["unit"] == "s" and reqs["settling"]["bound"] == 60.0


@pytest.mark.slow
def test_59_runs_state_the_95_percent_bound_they_support(tmp_path):
    """The acceptance case: every requirement met in 59 of 59 runs supports
    P >= 0.05^(1/59) = 0.9505 at 95 %, which meets 0.95 (the ensemble row's
    probability and the default coverage); the mixed 3-sigma row is not shown
    and says how many runs it needs."""
    import subprocess
    import sys

    root = Path(__file__).resolve().parent.parent
    out = tmp_path / "mc"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "montecarlo", "mrp_feedback_requirements", "--runs", "59",
                        "--workers", "2", "--out", str(out)], capture_output=True, text=True, cwd=root)
    assert r.returncode == 0, r.stderr
    m = json.loads((out / "montecarlo.json").read_text())
    reqs = {x["name"]: x for x in m["requirements"]}
    bound = 0.05 ** (1.0 / 59.0)
    for name in ("pointing", "stability", "settling", "payload_cone", "wheel_speed", "momentum", "command"):
        assert reqs[name]["runs_met"] == 59 and reqs[name]["lower_bound"] == pytest.approx(bound), name
        assert reqs[name]["met_at_confidence"] is True, name
    assert reqs["pointing_ensemble"]["worst"]["lower_bound"] == pytest.approx(bound)
    assert reqs["pointing_ensemble"]["met_at_confidence"] is True
    assert reqs["stability_mixed"]["met_at_confidence"] is False
    assert "59/59 runs met it: fraction 1 (95 % CI 0.9394-1), at least 0.9505 with 95 % confidence" in r.stdout
    assert "pointing_ensemble" in r.stdout and "MET at 95 %" in r.stdout
    assert f"{_brute_runs(0.9973, 0.975, 0)} runs needed" in r.stdout
    assert (out / "montecarlo_requirements.png").exists()


def test_a_coverage_or_confidence_of_one_is_stated_not_a_crash():
    """Every run must meet it (coverage 1, or an ensemble row at confidence
    1): no finite campaign shows that, which the summary says instead of
    dividing by log(1) (it used to raise ZeroDivisionError after the runs)."""
    assert runs_needed(1.0, 0.95) is None and runs_needed(0.999, 0.95) is not None
    rows = [_row("ape", True, 10.0) for _ in range(20)]
    (s,) = campaign_requirements((APE,), rows, 300.0, 10.0, confidence=0.95, coverage=1.0)
    assert s["met_at_confidence"] is False and s["runs_needed_without_failure"] is None
    from sc_rt.studies.campaign.text import requirement_lines

    assert any("no finite number of runs" in line for line in requirement_lines([s], 0.95, 1.0))
