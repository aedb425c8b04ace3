"""When each requirement was outside its bound (issue 41, item 6): every
result carries ``first_outside_s``, ``last_outside_s`` (the first instant of
the first value outside the bound, the last instant of the last one) and
``outside`` (how many values), shown in the console's requirement table and
report.html's. Checked on constructed signals against a numpy computation of
the values outside (tests/test_requirement_matrix.py checks them on recorded
runs of every kind). Before this change the results had no time at all:
flight_wheels' "lost at 2762 s" had to be computed by hand."""

from __future__ import annotations

import dataclasses
import re

import numpy as np

from sc_rt.results.judge.metrics import finish_run
from sc_rt.results.record.run import Run

from test_requirements import ARCSEC, RATE, about_x, grid, req, result, run_of


def outside(t0, t1, out) -> tuple:
    out = np.asarray(out, bool)
    if not out.any():
        return (None, None, 0)
    return (float(np.asarray(t0)[out].min()), float(np.asarray(t1)[out].max()), int(out.sum()))


def got(r: dict) -> tuple:
    return (r["first_outside_s"], r["last_outside_s"], r["outside"])


def signal() -> tuple[np.ndarray, np.ndarray]:
    """2 arcsec about x, 40 arcsec from 30 to 33 s and at 70.5 s, a 20 arcsec wobble from 41 to 44 s."""
    t = grid(100.0)
    theta = np.full(t.shape, 2.0)
    theta[(t >= 30.0 - 1e-9) & (t <= 33.0 + 1e-9)] = 40.0
    theta[np.isclose(t, 70.5)] = 40.0
    wobble = (t > 41.0) & (t < 44.0)
    theta[wobble] += 20.0 * np.sin(2.0 * np.pi * t[wobble])
    return t, theta * ARCSEC


def test_ape_and_rpe_name_their_first_and_last_instants_outside():
    t, theta = signal()
    rows = [req("ape", "APE", axis="x", bound=30.0, unit="arcsec", confidence=0.9, interpretation="temporal"),
            req("ape_fails", "APE", axis="x", bound=30.0, unit="arcsec", confidence=0.99,
                interpretation="temporal", t_from=31.0),
            req("rpe", "RPE", axis="x", bound=10.0, unit="arcsec", confidence=0.99, interpretation="temporal",
                window=5.0)]
    run = run_of(t, about_x(theta), rows)
    mag = np.abs(theta) / ARCSEC
    ape, ape_fails, rpe = result(run, "ape"), result(run, "ape_fails"), result(run, "rpe")
    # passed at p = 0.9 (32 samples of 1001 outside), yet it was outside: from 30 to 70.5 s
    assert ape["passed"] is True and got(ape) == outside(t, t, mag > 30.0) == (30.0, 70.5, 32)
    span = t >= 31.0 - 1e-9
    assert ape_fails["passed"] is False and got(ape_fails) == outside(t[span], t[span], mag[span] > 30.0)
    # RPE: windows of 5 s from 0 s; every instant's |e - its window's mean| (ECSS-E-ST-60-10C 3.2.12),
    # written out: the instants outside, not whole windows
    n = int(5.0 * RATE)
    starts = np.arange(0, len(t) - n + 1, n)
    at = np.concatenate([np.arange(k, k + n) for k in starts])
    x = theta / ARCSEC  # axis "x": the rotation vector's component, signed (the wobble crosses zero)
    per = np.concatenate([np.abs(x[k:k + n] - x[k:k + n].mean()) for k in starts])
    want = outside(t[at], t[at], per > 10.0)
    assert got(rpe) == want and want[:2] == (30.0, 70.5), want  # the step at 30-33 s, the wobble, the spike


def test_settling_peaks_and_the_envelope_name_their_instants_outside():
    t = grid(100.0)
    theta = 3600.0 * ARCSEC * np.exp(-t / 5.0)
    late = (t >= 80.0 - 1e-9) & (t <= 81.0 + 1e-9)
    theta[late] = 50.0 * ARCSEC  # out of the 30 arcsec band after it had to be settled (by 60 s)
    ws = np.zeros((len(t), 4))
    ws[:, 2] = np.where((t >= 10.0 - 1e-9) & (t <= 12.0 + 1e-9), 200.0, 90.0)
    rows = [req("s", "settling", axis="norm", bound=30.0, unit="arcsec", settle_by=60.0),
            req("w", "wheel_speed_margin", bound=150.0, unit="rad/s"),
            req("env", "envelope")]
    run = run_of(t, about_x(theta), rows, wheel_speed=ws)
    band = theta / ARCSEC > 30.0
    s, w = result(run, "s"), result(run, "w")
    assert s["passed"] is False  # settled only at 81.1 s
    assert got(s) == outside(t, t, band & (t >= 60.0 - 1e-9)) == (80.0, 81.0, 11)
    assert got(w) == outside(t, t, np.abs(ws).max(axis=1) > 150.0) == (10.0, 12.0, 21)
    assert got(result(run, "env")) == (None, None, 0)  # the constructed runs' envelope is wide
    # a narrow envelope: |sigma| < 0.001 on every axis (chi constant 0.001, dmin = dmax = 1)
    narrow = {k: (v,) * 3 for k, v in dict(chi0=1e-3, chiinf=1e-3, gamma=0.0, dmin=1.0, dmax=1.0).items()}
    meta = dataclasses.replace(run.meta, ppc=narrow)
    env = finish_run(Run(meta, {"t": t, "sigma_BD": about_x(theta), "wheel_speed": ws}))
    sigma = np.tan(theta / 4.0)
    r = result(env, "env")
    assert r["passed"] is False and got(r) == outside(t, t, sigma >= 1e-3)
    assert r["first_outside_s"] == r["first_violation_s"]


def test_the_console_and_the_report_show_them():
    from sc_rt.cli.common import requirement_table
    from sc_rt.results.present.html_requirements import requirements_table

    t, theta = signal()
    run = run_of(t, about_x(theta), [
        req("ape", "APE", axis="x", bound=30.0, unit="arcsec", confidence=0.9, interpretation="temporal"),
        req("clean", "APE", axis="x", bound=100.0, unit="arcsec", confidence=0.9, interpretation="temporal"),
        req("spike", "APE", axis="x", bound=30.0, unit="arcsec", confidence=0.9, interpretation="temporal",
            t_from=50.0)])
    reqs = run.metrics["requirements"]
    lines = "\n".join(requirement_table(reqs))
    assert lines.splitlines()[1].split()[-3:] == ["outside", "bound", "result"]
    for name, text in (("ape", "30-70.5 s"), ("clean", "-"), ("spike", "at 70.5 s")):
        row = next(line for line in lines.splitlines() if line.split()[0] == name)
        assert re.search(rf"\s{re.escape(text)}\s+PASS$", row), row
    html = requirements_table(reqs)
    assert "<th title=\"the first and last time its values were outside the bound\">outside bound</th>" in html
    assert "<td class=num>30-70.5 s</td>" in html and "<td class=num>at 70.5 s</td>" in html


def test_rows_outside_a_mode_are_not_outside_the_bound():
    """A SAFE spell the requirement leaves out (mode = "normal") is not a time it was outside."""
    t, theta = signal()
    ctrl_mode = np.where((t >= 29.0) & (t < 34.0), 2, 1)  # SAFE over the 40 arcsec step
    run = run_of(t, about_x(theta), [req("n", "APE", axis="x", bound=30.0, unit="arcsec", confidence=0.9,
                                         interpretation="temporal", mode="normal")], ctrl_mode=ctrl_mode)
    mag = np.abs(theta) / ARCSEC
    assert got(result(run, "n")) == outside(t, t, (mag > 30.0) & (ctrl_mode == 1)) == (70.5, 70.5, 1)
