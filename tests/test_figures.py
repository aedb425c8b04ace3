"""The run figures by content: the axes, the series, the bound lines and the
event markers each figure must show (not file sizes)."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest

from sc_rt.results.present import figures
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate


@pytest.fixture(scope="module")
def faults_run():
    return simulate(load_scenario("paper_faults"), law="dsc-ppc", engine="cpp", duration=60.0)


@pytest.fixture
def captured(monkeypatch):
    """Every figure the module saves, by file name, still open for inspection."""
    figs: dict[str, matplotlib.figure.Figure] = {}

    def keep(fig, path, dpi=110):
        figs[path.name] = fig
        return path

    monkeypatch.setattr(figures, "save_figure", keep)
    yield figs
    for f in figs.values():
        matplotlib.pyplot.close(f)


def _labels(ax) -> list[str]:
    return [ln.get_label() for ln in ax.get_lines()] + [p.get_label() for p in ax.patches]


def test_tracking_figures_show_the_envelope_events_and_one_axis_per_wheel(faults_run, captured, tmp_path):
    paths = figures.tracking_figures(faults_run, tmp_path)
    names = {p.name for p in paths}
    assert names == set(captured) == {"attitude_error.png", "attitude_error_log.png", "pointing_error.png",
                                      "rate_error.png", "wheel_commands.png", "disturbance_observer.png",
                                      "faults.png"}
    att = captured["attitude_error.png"].axes
    assert len(att) == 3
    for i, ax in enumerate(att):
        labels = _labels(ax)
        assert {f"sigma_BD,{'xyz'[i]} (true)", "dmax chi(t)", "-dmin chi(t)"} <= set(labels)
        # the bound line is the scenario's envelope, recomputed here independently
        bound = next(ln for ln in ax.get_lines() if ln.get_label() == "dmax chi(t)")
        p = faults_run.meta.ppc
        t = faults_run.t
        chi = (p["chi0"][i] - p["chiinf"][i]) * np.exp(-p["gamma"][i] * t) + p["chiinf"][i]
        np.testing.assert_allclose(bound.get_ydata(), p["dmax"][i] * chi, rtol=1e-12)
    # titles on their own lines: what, then which run
    title = att[0].get_title()
    assert title.split("\n")[1] == "paper_faults, dsc-ppc, offline (C++ loop)"
    # the events: three scheduled fault onsets (5, 10, 5 s -> two distinct times)
    # and the first violation (4.1 s, docs/REPRODUCTION.md) as vertical lines
    xs = sorted({float(ln.get_xdata()[0]) for ln in att[0].get_lines()
                 if ln.get_label() in ("fault onset", "first bound violation")
                 or (ln.get_linestyle() == "--" and ln.get_color() == "r" and len(set(ln.get_xdata())) == 1)})
    assert xs == [pytest.approx(4.1), 5.0, 10.0]
    wheels = captured["wheel_commands.png"].axes
    assert len(wheels) == 4 and all("limits" in _labels(a) or len(a.get_lines()) >= 3 for a in wheels)
    # the legend sits outside the data (right of the axes)
    leg = wheels[0].get_legend()
    assert leg is not None and leg.get_bbox_to_anchor().x0 > wheels[0].get_window_extent().x1 - 1
    ptg = captured["pointing_error.png"].axes[0]
    assert ptg.get_yscale() == "log" and "arcsec" in ptg.get_ylabel()
    series = {ln.get_label(): ln for ln in ptg.get_lines()}
    ang = series["true pointing error 4 atan|sigma_BD|"].get_ydata()  # no sensors: the law's own, the truth's
    np.testing.assert_allclose(ang, np.degrees(4 * np.arctan(np.linalg.norm(faults_run["sigma_BD"], axis=1)))
                               * 3600 + 1e-300, rtol=1e-12)
    assert len(captured["faults.png"].axes) == 8  # four wheels, each with its fault-state twin axis


def test_safe_spans_are_shaded(captured, tmp_path):
    # the paper's law tumbles past the 10 rad/s safety limit near 240 s: the
    # controller is in SAFE from there (docs/REPRODUCTION.md), shaded grey
    run = simulate(load_scenario("paper_faults"), law="dsc-ppc", engine="python")
    assert run.metrics["safe_steps"] > 0
    figures.tracking_figures(run, tmp_path)
    ax = captured["attitude_error.png"].axes[0]
    safe = [p for p in ax.patches if p.get_label() == "SAFE"]
    assert safe, _labels(ax)
    x0 = safe[0].get_x() if hasattr(safe[0], "get_x") else safe[0].get_xy()[0][0]
    assert x0 == pytest.approx(run.metrics["safe_from_s"])


def test_lockstep_timing_figure_has_no_empty_wake_panel(captured, tmp_path):
    from sc_rt.results.record.run import Run, RunMeta

    scn = load_scenario("paper_faults")
    n = 50
    run = Run(RunMeta.of_scenario(scn, "hil-lockstep", mode="lockstep"),
              {"t": np.arange(n) / 10.0, "latency_us": np.full(n, 80.0), "compute_us": np.full(n, 1.0)})
    figures.timing_figures(run, tmp_path, floor={"latency_us": 150.0})
    axs = captured["timing.png"].axes
    ylabels = [a.get_ylabel() for a in axs[::2]]
    assert ylabels == ["state-to-command latency [us]", "controller compute [us]"]
    labels = _labels(axs[0])
    assert "period 100000 us" in labels and "bench floor p99 150 us" in labels
    assert axs[0].get_xlabel() == "t [s]"


@pytest.fixture(scope="module")
def requirements_run():
    return simulate(load_scenario("mrp_feedback_requirements"), engine="cpp")


def test_requirement_figures_draw_each_bound_over_its_span(requirements_run, captured, tmp_path):
    """Issue #27 item 5 (write_run adds these two to the tracking figures):
    requirements.png has a panel per pointing or
    settling requirement with its bound over its span and the values judged
    (recomputed here from sigma_BD); wheel_speeds.png draws the wheels and
    their total momentum against the bounds; wheel_commands.png follows the
    commands, not the saturation limits."""
    run = requirements_run
    from sc_rt.results.present.requirement_figures import requirement_figures

    names = {p.name for p in requirement_figures(run, tmp_path)}
    assert names == {"requirements.png", "wheel_speeds.png"}
    figures.tracking_figures(run, tmp_path)
    reqs = {q["name"]: q for q in run.meta.requirements}
    results = {r["name"]: r for r in run.metrics["requirements"]}
    panels = [q for q in run.meta.requirements if q["kind"] in ("APE", "RPE", "settling")]
    axs = captured["requirements.png"].axes
    assert len(axs) == len(panels)
    ax = axs[[q["name"] for q in panels].index("pointing")]
    assert ax.get_title(loc="left").startswith("pointing: APE norm p0.9973 temporal -> PASS")
    bound = next(c for c in ax.collections if c.get_label() == "bound 30")
    (seg,) = bound.get_segments()
    np.testing.assert_allclose(seg, [[60.0, 30.0], [300.0, 30.0]])  # the bound over the span
    values = next(ln for ln in ax.get_lines() if ln.get_label() == "APE values")
    t = run.t
    angle = np.degrees(4 * np.arctan(np.linalg.norm(run["sigma_BD"], axis=1))) * 3600
    np.testing.assert_allclose(values.get_xdata(), t[t >= 60.0 - 1e-9])
    np.testing.assert_allclose(values.get_ydata(), angle[t >= 60.0 - 1e-9], rtol=1e-9)
    measured = next(c for c in ax.collections if c.get_label().startswith("p0.9973 value"))
    assert measured.get_segments()[0][0][1] == pytest.approx(results["pointing"]["value"])
    stab = axs[[q["name"] for q in panels].index("stability")]
    rpe = next(ln for ln in stab.get_lines() if ln.get_label() == "RPE values")  # one value per instant
    assert len(rpe.get_xdata()) == results["stability"]["samples"]
    wmax = next(c for c in stab.collections if c.get_label().startswith("window-max bound"))
    assert wmax.get_segments()[0][0][1] == pytest.approx(results["stability"]["window_max_bound"])
    ens = axs[[q["name"] for q in panels].index("pointing_ensemble")]
    assert "ACROSS RUNS" in ens.get_title(loc="left")
    # the wheels: speeds as simulated, the 150 rad/s bound in view, the 600 rad/s actuator limit named off scale
    top, bottom = captured["wheel_speeds.png"].axes
    lines = {ln.get_label(): ln for ln in top.get_lines()}
    for w in range(4):
        np.testing.assert_allclose(lines[f"wheel {w + 1}"].get_ydata(), run["wheel_speed"][:, w])
    labels = [ln.get_label() for ln in top.get_lines()] + [c.get_label() for c in top.collections]
    assert "wheel_speed bound" in labels and "actuator speed limit (off scale: 600)" in labels
    lo, hi = top.get_ylim()
    assert hi >= reqs["wheel_speed"]["bound"] and hi < 600.0 and lo <= -reqs["wheel_speed"]["bound"]
    scn = load_scenario("mrp_feedback_requirements")
    h = np.linalg.norm((run["wheel_speed"] * scn.plant.Jw) @ scn.plant.Cbar.T, axis=1)
    mom = next(ln for ln in bottom.get_lines() if ln.get_label().startswith("|h_w|"))
    np.testing.assert_allclose(mom.get_ydata(), h, rtol=1e-12)
    assert results["momentum"]["value"] == pytest.approx(h.max(), rel=1e-12)
    # the commands' axes follow the commands (|u| < 0.6 rad/s^2), not the limits (-7, 10)
    for w, ax in enumerate(captured["wheel_commands.png"].axes):
        lo, hi = ax.get_ylim()
        u = run["u_sat"][:, w]
        assert lo <= u.min() and hi >= u.max() and hi - lo < 2.0
        assert any("limits (off scale" in (ln.get_label() or "") for ln in ax.get_lines())
