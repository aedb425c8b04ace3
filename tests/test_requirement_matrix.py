"""Every documented requirement kind, in each axis form, through the commands
that judge a run (issue 41, item 1; docs/REQUIREMENTS.md): ``sc-rt sim``
(both engines), ``sc-rt hil --mode lockstep``, ``sc-rt report LOG`` of that
run, ``sc-rt compare`` and ``sc-rt montecarlo --rerun``. Each value in
metrics.json is checked against a numpy computation of the recorded
trajectory written here from the definitions (the errors with
tests/refmath.py, the rotation vectors with scipy, the quantiles with numpy's
``inverted_cdf``), never with sc_rt's own helpers.

On main before this test, ``kind = "max_torque"`` crashed the console table
(a TypeError: an unsupported format string passed to None's __format__),
``sc-rt sim`` and ``hil`` exited 1 without report.html.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from refmath import chi, mrp_dcm, mrp_sub
from sc_rt.scenario.reader import load_scenario
from sc_rt.scenario.tables.requirements import KINDS
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
LIB = ROOT / "python" / "sc_rt" / "scenario" / "library"
ARCSEC = math.pi / 648000.0
DURATION = 60.0  # [s] at the file's 10 Hz
EPS = 1e-9  # [s] time comparisons on the control grid

#: name -> the row's keys: every kind of docs/REQUIREMENTS.md, each axis form (x, y, z, norm, cone),
#: a span from a time, to a time and from a settling, an ensemble row; bounds chosen so that some pass
#: and some fail. The performance kinds are judged on the truth, the knowledge kinds on the estimate.
ROWS: dict[str, dict] = {
    "ape_x": dict(kind="APE", axis="x", bound=30.0, unit="arcsec", confidence=0.9973, t_from=20.0),
    "ape_y": dict(kind="APE", axis="y", bound=0.5, unit="arcsec", confidence=0.9),
    "ape_z": dict(kind="APE", axis="z", bound=30.0, unit="arcsec", confidence=0.5, t_from=10.0, t_to=50.0),
    "ape_norm": dict(kind="APE", axis="norm", bound=0.01, unit="deg", confidence=0.95, t_from=30.0),
    "ape_cone": dict(kind="APE", axis="cone", boresight=[0.0, 0.6, 0.8], bound=20.0, unit="arcsec",
                     confidence=0.95, t_from="after_settling", settling="settle_norm"),
    "ape_ensemble": dict(kind="APE", axis="norm", bound=30.0, unit="arcsec", confidence=0.95,
                         interpretation="ensemble", t_from=30.0),
    "mpe_y": dict(kind="MPE", axis="y", bound=2.0, unit="arcsec", confidence=0.9, window=5.0, t_from=20.0),
    "rpe_x": dict(kind="RPE", axis="x", bound=5.0, unit="arcsec", confidence=0.9973, window=4.0, t_from=15.0),
    "rpe_norm": dict(kind="RPE", axis="norm", bound=1.0, unit="urad", confidence=0.5, window=3.0),
    "pde_z": dict(kind="PDE", axis="z", bound=3.0, unit="arcsec", confidence=0.9, window=5.0, separation=10.0,
                  t_from=10.0, t_to=55.0),
    "pre_norm": dict(kind="PRE", axis="norm", bound=3.0, unit="arcsec", confidence=0.95, window=2.0,
                     separation=15.0, t_from=20.0, t_to=40.0),
    "ake_norm": dict(kind="AKE", axis="norm", bound=30.0, unit="arcsec", confidence=0.9973),
    "ake_cone": dict(kind="AKE", axis="cone", boresight=[0.0, 0.0, 1.0], bound=2.0, unit="arcsec",
                     confidence=0.9),
    "mke_x": dict(kind="MKE", axis="x", bound=10.0, unit="arcsec", confidence=0.9, window=10.0),
    "rke_y": dict(kind="RKE", axis="y", bound=2.0, unit="arcsec", confidence=0.95, window=5.0, t_from=5.0),
    "kde_norm": dict(kind="KDE", axis="norm", bound=5.0, unit="arcsec", confidence=0.9, window=5.0,
                     separation=20.0),
    "kre_z": dict(kind="KRE", axis="z", bound=5.0, unit="arcsec", confidence=0.9, window=4.0, separation=12.0,
                  t_to=30.0),
    "settle_norm": dict(kind="settling", axis="norm", bound=100.0, unit="arcsec", settle_by=30.0),
    "settle_cone": dict(kind="settling", axis="cone", boresight=[1.0, 0.0, 0.0], bound=5.0, unit="arcsec",
                        settle_by=8.0),
    "settle_x": dict(kind="settling", axis="x", bound=30.0, unit="arcsec", settle_by=20.0, t_from=2.0),
    "wheels": dict(kind="wheel_speed_margin", bound=900.0, unit="rpm"),
    "momentum": dict(kind="momentum_margin", bound=50.0, unit="mN m s", t_from=20.0),
    "command": dict(kind="max_command", bound=0.1, unit="rad/s^2"),
    "torque": dict(kind="max_torque", bound=20.0, unit="mN m", t_from=5.0),
    "torque_si": dict(kind="max_torque", bound=1.0),
    "envelope": dict(kind="envelope"),
}

SENSORS = """
[controller]
measurement = "estimate"

[controller.estimator]
initial_attitude_sigma = 30.0
initial_bias_sigma = 0.3
degraded_after = 2.0

[sensors]
seed = 3

[sensors.gyro]
rate_hz = 10.0
arw = 0.07
bias_sigma = 0.1
bias_tau = 3600.0
bias0 = [0.1, -0.1, 0.05]

[sensors.star_tracker]
rate_hz = 5.0
sigma_cross = 2.0
sigma_boresight = 20.0
boresight = [0.0, 0.0, 1.0]
latency = 0.1
"""


def _toml(v) -> str:
    return json.dumps(v)  # numbers, strings and lists of numbers read the same in TOML


def scenario_text() -> str:
    """The shipped PD hold (mrp_feedback_requirements) for 60 s, with sensors, and ROWS as its requirements."""
    src = (LIB / "mrp_feedback_requirements.toml").read_text()
    head, rest = src.split("\n[run]", 1)
    head = head[:head.index("\n[[requirements]]")]
    rows = "".join(f'\n[[requirements]]\nname = "{name}"\n' + "".join(f"{k} = {_toml(v)}\n" for k, v in row.items())
                   for name, row in ROWS.items())
    rest = re.sub(r"(?m)^duration = 300\.0", f"duration = {DURATION}", rest)
    assert f"duration = {DURATION}" in rest
    return head + rows + "\n[run]" + rest + SENSORS


@pytest.fixture
def scenario(tmp_path) -> Path:
    p = tmp_path / "every_requirement.toml"
    p.write_text(scenario_text())
    return p


def test_the_matrix_has_every_kind_and_axis():
    assert {r["kind"] for r in ROWS.values()} == set(KINDS)
    pointing = [r for r in ROWS.values() if "axis" in r]
    assert {r["axis"] for r in pointing} == {"x", "y", "z", "norm", "cone"}
    assert {r["axis"] for r in pointing if r["kind"] == "settling"} == {"x", "norm", "cone"}


# --------------------------------------------------------------------------------------------- #
# The reference: the definitions of docs/REQUIREMENTS.md section 2, on the recorded rows


def rotvec(sigma: np.ndarray) -> np.ndarray:
    """Axis times angle of each MRP (scipy's MRPs are e tan(theta/4), as ours)."""
    return Rotation.from_mrp(sigma).as_rotvec()


def signal(sigma: np.ndarray, row: dict) -> np.ndarray:
    """The row's error as vectors (N, 3): a body component, the rotation vector, or the cone vector
    (the smallest rotation taking the boresight b to C(sigma) b, its length the angle between them)."""
    axis = row["axis"]
    if axis == "cone":
        b = np.asarray(row["boresight"], float)
        b = b / np.linalg.norm(b)
        out = np.zeros((len(sigma), 3))
        for i, s in enumerate(sigma):
            d = mrp_dcm(s) @ b
            c = np.cross(b, d)
            n = np.linalg.norm(c)
            out[i] = 0.0 if n == 0 else c / n * math.atan2(n, float(b @ d))
        return out
    phi = rotvec(sigma)
    if axis == "norm":
        return phi
    k = "xyz".index(axis)
    out = np.zeros_like(phi)
    out[:, k] = phi[:, k]
    return out


def span_rows(t: np.ndarray, row: dict, settled: dict) -> np.ndarray:
    t_from = row.get("t_from", 0.0)
    start = settled[row["settling"]] if t_from == "after_settling" else float(t_from)
    stop = float(row.get("t_to", t[-1]))
    return np.flatnonzero((t >= start - EPS) & (t <= stop + EPS))


def q(values, p: float) -> float:
    return float(np.quantile(np.asarray(values, float), p, method="inverted_cdf"))


#: each knowledge index is the same statistic as its performance index, on the other error
AS_PERFORMANCE = {"AKE": "APE", "MKE": "MPE", "RKE": "RPE", "KDE": "PDE", "KRE": "PRE"}
ANGLE = {"arcsec": ARCSEC, "deg": math.pi / 180.0, "urad": 1e-6}
PEAK_UNITS = {"rpm": 2.0 * math.pi / 60.0, "mN m s": 1e-3, "mN m": 1e-3, "N m": 1.0, "rad/s^2": 1.0}


def outside(t0, t1, out) -> tuple[float | None, float | None]:
    """(first, last) instant of the values outside the bound: the first value's first instant, the last
    one's last instant (a sample: its time; a window: its first and last sample; a pair: its first window)."""
    out = np.asarray(out, bool)
    if not out.any():
        return (None, None)
    return (float(np.asarray(t0)[out].min()), float(np.asarray(t1)[out].max()))


def pointing_values(row: dict, t: np.ndarray, sigma: np.ndarray, idx: np.ndarray):
    """(values [rad], first instant, last instant of each): APE: |e| per sample of the span; MPE:
    |window mean| over non-overlapping windows tiling the span from its first sample; RPE: |e - the mean
    of its window| at every instant of those windows (ECSS-E-ST-60-10C 3.2.12); PDE, PRE: |mean of the
    window `separation` later - the window's mean|, the later window inside the span (PDE) or inside
    the run (PRE)."""
    kind = AS_PERFORMANCE.get(row["kind"], row["kind"])
    e = signal(sigma, row)
    if kind == "APE":
        return np.linalg.norm(e[idx], axis=1), t[idx], t[idx]
    n = int(round(row["window"] * 10.0))
    starts = list(range(int(idx[0]), int(idx[-1]) - n + 2, n))
    if kind == "RPE":
        at = np.concatenate([np.arange(k, k + n) for k in starts])
        per = np.concatenate([np.linalg.norm(e[k:k + n] - e[k:k + n].mean(axis=0), axis=1) for k in starts])
        return per, t[at], t[at]
    if kind == "MPE":
        per = [np.linalg.norm(e[k:k + n].mean(axis=0)) for k in starts]
    else:
        shift = int(round(row["separation"] * 10.0))
        end = int(idx[-1]) if kind == "PDE" else len(t) - 1
        starts = [k for k in starts if k + shift + n - 1 <= end]
        per = [np.linalg.norm(e[k + shift:k + shift + n].mean(axis=0) - e[k:k + n].mean(axis=0)) for k in starts]
    starts = np.asarray(starts)
    return np.asarray(per), t[starts], t[starts + n - 1]


def reference(traj, scn, bounds: dict | None = None) -> dict[str, tuple]:
    """name -> (value in the row's unit, passed, (first, last) instant outside its bound) from the rows;
    into ``bounds``, name -> the window-max bound of each RPE and RKE row (the p-quantile over its
    windows of each window's largest |e - window mean|)."""
    t = traj["t"]
    perf = np.array([mrp_sub(s, d) for s, d in zip(traj["sigma_BN"], traj["sigma_DN"])])
    know = np.array([mrp_sub(s, e) for s, e in zip(traj["sigma_BN"], traj["sigma_BN_est"])])
    Cbar, Jw = np.asarray(scn.plant.Cbar, float), np.asarray(scn.plant.Jw, float)
    out: dict[str, tuple] = {}
    settled: dict[str, float | None] = {}
    for name, row in sorted(ROWS.items(), key=lambda kv: kv[1]["kind"] != "settling"):
        kind = row["kind"]
        if kind == "settling":
            idx = span_rows(t, row, settled)
            mag = np.linalg.norm(signal(perf, row)[idx], axis=1)
            out_of_band = mag > row["bound"] * ANGLE[row["unit"]]
            last_out = np.flatnonzero(out_of_band)
            ts = float(t[idx][0]) if last_out.size == 0 else (
                None if last_out[-1] == idx.size - 1 else float(t[idx][last_out[-1] + 1]))
            settled[name] = ts
            late = out_of_band & (t[idx] >= row["settle_by"] - EPS)  # outside the band once it had to be in
            out[name] = (ts, ts is not None and ts <= row["settle_by"] + EPS, outside(t[idx], t[idx], late))
        elif kind == "envelope":
            p = scn.controller.ppc
            ppc = {k: np.asarray(getattr(p, k), float) for k in ("chi0", "chiinf", "gamma", "dmin", "dmax")}
            c = np.array([chi(ppc, tt) for tt in t])
            inside = (-ppc["dmin"] * c < perf) & (perf < ppc["dmax"] * c)
            ratio = np.where(perf >= 0, perf / (ppc["dmax"] * c), -perf / (ppc["dmin"] * c))
            rows_out = ~inside.all(axis=1)
            out[name] = (float(ratio.max()), bool(inside.all()), outside(t, t, rows_out))
        elif row.get("interpretation") == "ensemble":
            out[name] = (None, None, (None, None))  # a campaign's statistic
        elif kind in ("wheel_speed_margin", "momentum_margin", "max_command", "max_torque"):
            idx = span_rows(t, row, settled)
            if kind == "wheel_speed_margin":
                per = np.abs(traj["wheel_speed"][idx]).max(axis=1)
            elif kind == "max_command":
                per = np.abs(traj["u_cmd"][idx]).max(axis=1)
            else:
                col = traj["wheel_speed"] if kind == "momentum_margin" else traj["u_cmd"]
                per = np.array([np.linalg.norm(Cbar @ (Jw * r)) for r in col[idx]])
            per = per / PEAK_UNITS[row.get("unit", "N m")]
            v = float(per.max())
            out[name] = (v, bool(v <= row["bound"]), outside(t[idx], t[idx], per > row["bound"]))
        else:
            idx = span_rows(t, row, settled)
            sigma = know if kind in AS_PERFORMANCE else perf
            per, t0, t1 = pointing_values(row, t, sigma, idx)
            per = per / ANGLE[row["unit"]]
            v = q(per, row["confidence"])
            if kind in ("RPE", "RKE") and bounds is not None:  # the instants of each window, n at a time
                n = int(round(row["window"] * 10.0))
                bounds[name] = q(per.reshape(-1, n).max(axis=1), row["confidence"])
            out[name] = (v, bool(v <= row["bound"]), outside(t0, t1, per > row["bound"]))
    return out


def assert_matches_reference(metrics: dict, traj, scn, who: str) -> None:
    bounds: dict[str, float] = {}
    ref = reference(traj, scn, bounds)
    got = {r["name"]: r for r in metrics["requirements"]}
    assert list(got) == list(ROWS), who
    for name, b in bounds.items():  # RPE, RKE: the window-max statistic beside the index, never below it
        if got[name]["value"] is not None:
            assert got[name]["window_max_bound"] == pytest.approx(b, rel=1e-7, abs=1e-12), (who, name)
            assert got[name]["window_max_bound"] >= got[name]["value"], (who, name)
    for name, (value, passed, (first, last)) in ref.items():
        r = got[name]
        # when it was outside its bound (issue 41 item 6): the first and last instant
        assert (r["first_outside_s"], r["last_outside_s"]) == (first, last), (who, name, r)
        if value is None:
            assert r["value"] is None and r["passed"] is passed, (who, name, r)
            continue
        assert r["value"] == pytest.approx(value, rel=1e-7, abs=1e-12), (who, name, r["value"], value, r["note"])
        assert r["passed"] is passed, (who, name, r)
    # both outcomes are exercised, and the verdict counts them
    assert {True, False} <= {p for _, p, _ in ref.values()}, ref
    assert any(f is not None for _, p, (f, _) in ref.values() if p is False), ref
    failed = [n for n, (_, p, _) in ref.items() if p is False]
    assert f"{len(failed)} of {sum(p is not None for _, p, _ in ref.values())} requirements failed" in \
        metrics_verdict(metrics), who


def metrics_verdict(metrics: dict) -> str:
    from sc_rt.results.judge.verdict import verdict_line

    return verdict_line(metrics, "x")


def assert_console_rows(console: str) -> None:
    """The console's requirement table names every row with when it was outside its bound and its result."""
    for name in ROWS:
        assert re.search(rf"^\s+{name}\s.*\s(-|at [0-9.]+ s|[0-9.]+-[0-9.]+ s)\s+(PASS|FAIL|across runs)$",
                         console, re.M), (name, console)


# --------------------------------------------------------------------------------------------- #
# The commands


@pytest.mark.parametrize("engine", ["cpp", "python"])
def test_every_kind_through_sim(scenario, tmp_path, capsys, engine):
    from sc_rt.cli import main

    out = tmp_path / "sim"
    assert main(["sim", str(scenario), "--engine", engine, "--out", str(out), "--no-plots"]) == 0
    console = capsys.readouterr().out
    assert_console_rows(console)
    assert (out / "report.html").is_file()
    metrics = json.loads((out / "metrics.json").read_text())
    assert_matches_reference(metrics, load_traj(out), load_scenario(scenario), f"sim {engine}")


@pytest.mark.lcm
def test_every_kind_through_hil_lockstep_and_its_report(scenario, tmp_path):
    import lcmnet

    lcmnet.require()
    scn = load_scenario(scenario)
    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", str(scenario), "--mode", "lockstep", "--out", str(out), "--no-plots"])
    assert r.returncode == 0, r.stderr[-3000:] + r.stdout[-3000:]
    assert_console_rows(r.stdout)
    assert (out / "report.html").is_file()
    metrics = json.loads((out / "metrics.json").read_text())
    assert_matches_reference(metrics, load_traj(out), scn, "hil lockstep")
    rep = tmp_path / "report"
    r = lcmnet.run_cli(["report", str(out / "run.lcmlog"), "--out", str(rep), "--no-plots"], netns=False)
    assert r.returncode == 0, r.stderr[-3000:]
    assert_console_rows(r.stdout)
    assert_matches_reference(json.loads((rep / "metrics.json").read_text()), load_traj(rep), scn,
                             "report LOG")


def test_every_kind_through_compare_and_a_campaigns_rerun(scenario, tmp_path, capsys):
    from sc_rt.cli import main

    scn = load_scenario(scenario)
    out = tmp_path / "mc"
    assert main(["montecarlo", str(scenario), "--runs", "2", "--rerun", "1", "--out", str(out)]) == 0
    rerun = out / "rerun-1"
    metrics = json.loads((rerun / "metrics.json").read_text())
    assert_matches_reference(metrics, load_traj(rerun), scn, "montecarlo --rerun")
    # compare: the values of the same run offline (sim --engine cpp, checked above against the reference)
    sim = tmp_path / "sim"
    assert main(["sim", str(scenario), "--engine", "cpp", "--out", str(sim), "--no-plots"]) == 0
    want = {r["name"]: r for r in json.loads((sim / "metrics.json").read_text())["requirements"]}
    capsys.readouterr()
    # one seed: the same run as the sim (a sensed scenario runs 5 seeds by default, their mean)
    assert main(["compare", str(scenario), "--law", "pd", "--seeds", "1", "--out", str(tmp_path / "cmp")]) == 0
    console = capsys.readouterr().out
    doc = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    got = {r["name"]: r for r in doc["rows"][0]["requirements"]}
    assert list(got) == list(ROWS)
    for name, r in got.items():
        assert (r["value"], r["passed"]) == (want[name]["value"], want[name]["passed"]), name
        if r["passed"] is not None:
            assert re.search(rf"^\| {name} \| ", console, re.M), (name, console)


def test_every_kind_through_a_campaign_and_its_ensemble_row(scenario, tmp_path):
    """The campaign itself, not only a rerun: each run's value of every
    per-run row in the dataset equals the reference on that run's trajectory
    (replayed with --rerun, bitwise the campaign's run), and the ensemble
    row's per-bin statistics equal a numpy evaluation across the runs: each
    run's largest value in each bin of the common time grid, then per bin the
    runs within the bound and the nearest-rank p-quantile across the runs
    (docs/REQUIREMENTS.md section 4)."""
    import pyarrow.dataset as pads

    from sc_rt.cli import main

    scn = load_scenario(scenario)
    out = tmp_path / "mc"
    n = 3
    assert main(["montecarlo", str(scenario), "--runs", str(n), "--workers", "1", "--out", str(out)]) == 0
    table = pads.dataset(out / "runs", format="parquet").to_table().to_pylist()
    rows = {r["run"]: r for r in table}
    assert sorted(rows) == list(range(n))
    summary = {r["name"]: r for r in json.loads((out / "montecarlo.json").read_text())["requirements"]}
    ens_row = ROWS["ape_ensemble"]
    ens = summary["ape_ensemble"]
    bin_s = ens["bin_s"]
    per_run_bins = []
    for k in range(n):
        assert main(["montecarlo", str(scenario), "--runs", str(n), "--rerun", str(k), "--out", str(out)]) == 0
        traj = load_traj(out / f"rerun-{k}")
        ref = reference(traj, scn)
        for name, (value, passed, _) in ref.items():
            if value is None:  # the ensemble row: below
                continue
            assert rows[k][f"req.{name}.value"] == pytest.approx(value, rel=1e-7, abs=1e-12), (k, name)
            assert bool(rows[k][f"req.{name}.passed"]) is passed, (k, name)
        t = traj["t"]
        perf = np.array([mrp_sub(s, d) for s, d in zip(traj["sigma_BN"], traj["sigma_DN"])])
        idx = span_rows(t, ens_row, {})
        per, t0, _ = pointing_values(ens_row, t, perf, idx)
        b = np.floor(t0 / bin_s + 1e-9).astype(int)
        per_run_bins.append({int(j): float(per[b == j].max() / ANGLE[ens_row["unit"]]) for j in np.unique(b)})
    grid = sorted(per_run_bins[0])
    assert all(sorted(p) == grid for p in per_run_bins)
    assert ens["per_bin"]["t_s"] == pytest.approx([j * bin_s for j in grid])
    vals = np.array([[p[j] for p in per_run_bins] for j in grid])  # bins x runs
    within = (vals <= ens_row["bound"]).sum(axis=1)
    p = ens_row["confidence"]
    rank = int(math.ceil(p * n))  # nearest rank
    quant = np.sort(vals, axis=1)[:, rank - 1]
    assert ens["per_bin"]["within"] == within.tolist()
    assert ens["per_bin"]["quantile"] == pytest.approx(quant.tolist(), rel=1e-7, abs=1e-12)
    assert ens["quantile_max"] == pytest.approx(float(quant.max()), rel=1e-7)
    assert ens["worst_t_s"] == pytest.approx(grid[int(np.argmin(within))] * bin_s)
