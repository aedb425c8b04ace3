"""The references besides the paper's (issue #14 item 7): inertial hold,
rest-to-rest eigenaxis slew and a reference read from a file, checked
against closed forms computed here (axis-angle rotations by Rodrigues'
formula, quaternions from rotation matrices), never against the core's own
output; and the same reference in the C++ controller process (lockstep HIL
bitwise equal to the offline simulation)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.results.judge.metrics import fill_tracking_errors
from sc_rt.results.record.run import Run
from sc_rt.scenario.model import ScenarioError
from sc_rt.scenario.reader import load_scenario, with_run
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
SLEW = ROOT / "scenarios" / "slew_rest_to_rest.toml"


# --------------------------------------------------------------------------- #
# Independent rotation math: DCM [DN] maps N components to D components.

def skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rot(axis, angle):
    """DCM of a frame rotated by ``angle`` about ``axis`` (Rodrigues)."""
    e = np.asarray(axis, float) / np.linalg.norm(axis)
    return math.cos(angle) * np.eye(3) + (1 - math.cos(angle)) * np.outer(e, e) - math.sin(angle) * skew(e)


def quat_of_dcm(C):
    """Unit quaternion [w, x, y, z] of a DCM (Shepperd), w >= 0."""
    tr = np.trace(C)
    cand = [1 + tr, 1 + 2 * C[0, 0] - tr, 1 + 2 * C[1, 1] - tr, 1 + 2 * C[2, 2] - tr]
    i = int(np.argmax(cand))
    q = np.empty(4)
    q[i] = 0.5 * math.sqrt(cand[i])
    d = 4 * q[i]
    if i == 0:
        q[1:] = [(C[1, 2] - C[2, 1]) / d, (C[2, 0] - C[0, 2]) / d, (C[0, 1] - C[1, 0]) / d]
    elif i == 1:
        q[0], q[2], q[3] = (C[1, 2] - C[2, 1]) / d, (C[0, 1] + C[1, 0]) / d, (C[2, 0] + C[0, 2]) / d
    elif i == 2:
        q[0], q[1], q[3] = (C[2, 0] - C[0, 2]) / d, (C[0, 1] + C[1, 0]) / d, (C[1, 2] + C[2, 1]) / d
    else:
        q[0], q[1], q[2] = (C[0, 1] - C[1, 0]) / d, (C[2, 0] + C[0, 2]) / d, (C[1, 2] + C[2, 1]) / d
    return -q if q[0] < 0 else q


def mrp_of_dcm(C):
    q = quat_of_dcm(C)
    return q[1:] / (1 + q[0])


def dcm_of_mrp(s):
    """(10) written out once more from the quaternion: R = (w^2 - v'v) I + 2 v v' - 2 w v^."""
    s = np.asarray(s, float)
    ss = s @ s
    w, v = (1 - ss) / (1 + ss), 2 * s / (1 + ss)
    return (w * w - v @ v) * np.eye(3) + 2 * np.outer(v, v) - 2 * w * skew(v)


def cycloid(phi, T, s):
    """theta, theta_dot, theta_ddot of the documented profile at s = (t - start)/T in [0, 1]."""
    w = 2 * math.pi * s
    return (phi * (s - math.sin(w) / (2 * math.pi)), phi / T * (1 - math.cos(w)),
            2 * math.pi * phi / T**2 * math.sin(w))


def slew_params(sigma0, target, start, duration):
    p = _core.GuidanceParams()
    p.kind = _core.GuidanceKind.Slew
    p.sigma_d0, p.slew_target, p.slew_start, p.slew_duration = sigma0, target, start, duration
    return p


def table_params(t, sigma, omega):
    p = _core.GuidanceParams()
    p.kind = _core.GuidanceKind.Table
    p.table_t, p.table_sigma, p.table_omega = np.asarray(t, float), np.asarray(sigma, float), np.asarray(omega, float)
    return p


AXIS = np.array([0.3, -0.8, 0.52])
E = AXIS / np.linalg.norm(AXIS)
PHI = math.radians(130.0)
C0 = rot([1.0, 0.4, -0.2], math.radians(35.0))  # the attitude before the slew
SIGMA0 = mrp_of_dcm(C0)
TARGET = mrp_of_dcm(rot(E, PHI) @ C0)


# --------------------------------------------------------------------------- #
# Hold


def test_hold_is_a_constant_attitude_at_rest():
    p = _core.GuidanceParams()
    p.kind = _core.GuidanceKind.Hold
    p.sigma_d0 = [0.1, -0.25, 0.4]
    assert _core.validate(p) == []
    g = _core.Guidance(p, 0.1)
    g.reset(0.0)
    for t in (0.0, 0.05, 1.0, 17.3, 300.0, 1e5):
        g.advance(t)
        np.testing.assert_array_equal(g.sigma_DN, [0.1, -0.25, 0.4])
        np.testing.assert_array_equal(_core.sigma_d(p, t), [0.1, -0.25, 0.4])
        np.testing.assert_array_equal(_core.omega_d(p, t), np.zeros(3))
        np.testing.assert_array_equal(_core.omega_d_dot(p, t), np.zeros(3))


def test_hold_from_a_scenario_reaches_the_core(tmp_path):
    path = _scenario(tmp_path, 'kind = "hold"\nsigma_d0 = [0.05, 0.1, -0.2]\n')
    s = load_scenario(path)
    assert s.guidance.kind == "hold"
    cfg = s.core_config().guidance
    assert cfg.kind == _core.GuidanceKind.Hold
    np.testing.assert_array_equal(cfg.sigma_d0, [0.05, 0.1, -0.2])
    np.testing.assert_array_equal(_core.omega_d(cfg, 12.0), np.zeros(3))


# --------------------------------------------------------------------------- #
# Slew


def test_slew_axis_and_angle_are_the_short_rotation_between_the_ends():
    p = slew_params(SIGMA0, TARGET, 5.0, 40.0)
    np.testing.assert_allclose(_core.slew_axis(p), E, atol=1e-12)
    assert abs(_core.slew_angle(p) - PHI) < 1e-12


@pytest.mark.parametrize("t", [5.0 + 40.0 * s for s in (0.0, 1e-3, 0.1, 0.25, 0.37, 0.5, 0.81, 0.999, 1.0)]
                         + [0.0, 2.0, 45.5, 200.0])
def test_slew_attitude_is_the_axis_angle_rotation(t):
    start, T = 5.0, 40.0
    p = slew_params(SIGMA0, TARGET, start, T)
    s = min(max((t - start) / T, 0.0), 1.0)
    theta, rate, accel = cycloid(PHI, T, s)
    expected = mrp_of_dcm(rot(E, theta) @ C0)
    np.testing.assert_allclose(_core.sigma_d(p, t), expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(_core.omega_d(p, t), rate * E, rtol=0, atol=1e-15)
    np.testing.assert_allclose(_core.omega_d_dot(p, t), accel * E, rtol=0, atol=1e-15)
    # and the controller's Guidance gives the same (closed form, any step)
    g = _core.Guidance(p, 0.1)
    g.reset(t)
    np.testing.assert_allclose(g.sigma_DN, expected, rtol=0, atol=1e-12)


def test_slew_rests_at_both_ends_and_peaks_as_documented():
    start, T = 5.0, 40.0
    p = slew_params(SIGMA0, TARGET, start, T)
    for t in (0.0, 4.0, start):
        np.testing.assert_array_equal(_core.sigma_d(p, t), SIGMA0)
        np.testing.assert_array_equal(_core.omega_d(p, t), np.zeros(3))
        np.testing.assert_array_equal(_core.omega_d_dot(p, t), np.zeros(3))
    for t in (start + T, 50.0, 1e4):
        np.testing.assert_allclose(_core.sigma_d(p, t), TARGET, atol=1e-15)
        np.testing.assert_array_equal(_core.omega_d(p, t), np.zeros(3))
        np.testing.assert_array_equal(_core.omega_d_dot(p, t), np.zeros(3))
    # continuous at the ends: rate O(eps^2), acceleration O(eps)
    for t in (start + 1e-4, start + T - 1e-4):
        assert np.linalg.norm(_core.omega_d(p, t)) < 1e-9
        assert np.linalg.norm(_core.omega_d_dot(p, t)) < 1e-6
    # peaks: rate 2 Phi / T at mid-slew, acceleration 2 pi Phi / T^2 at a quarter
    assert abs(np.linalg.norm(_core.omega_d(p, start + T / 2)) - 2 * PHI / T) < 1e-15
    assert abs(np.linalg.norm(_core.omega_d_dot(p, start + T / 4)) - 2 * math.pi * PHI / T**2) < 1e-15
    ts = np.linspace(0, 60, 6001)
    assert max(np.linalg.norm(_core.omega_d(p, t)) for t in ts) <= 2 * PHI / T * (1 + 1e-15)


def test_slew_rate_integrates_to_the_attitude():
    """sigma_dot = G(sigma) omega_d: RK4 with the core's G from sigma_d0 reproduces sigma_DN(t)."""
    start, T = 2.0, 30.0
    p = slew_params(SIGMA0, TARGET, start, T)
    h, sigma, t = 0.01, SIGMA0.copy(), 0.0
    f = lambda tt, ss: np.asarray(_core.mrp_G(ss)) @ np.asarray(_core.omega_d(p, tt))  # noqa: E731
    worst = 0.0
    for k in range(1, 3601):  # to 36 s, past the end
        k1 = f(t, sigma)
        k2 = f(t + h / 2, sigma + h / 2 * k1)
        k3 = f(t + h / 2, sigma + h / 2 * k2)
        k4 = f(t + h, sigma + h * k3)
        sigma = sigma + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        t = k * h
        if k % 100 == 0:
            worst = max(worst, np.linalg.norm(sigma - np.asarray(_core.sigma_d(p, t))))
    assert worst < 1e-9, worst


def test_slew_acceleration_is_the_rate_derivative():
    p = slew_params(SIGMA0, TARGET, 3.0, 25.0)
    h = 1e-5
    for t in np.linspace(3.1, 27.9, 17):
        fd = (np.asarray(_core.omega_d(p, t + h)) - np.asarray(_core.omega_d(p, t - h))) / (2 * h)
        np.testing.assert_allclose(_core.omega_d_dot(p, t), fd, rtol=0, atol=1e-10)


def test_slew_of_no_rotation_is_a_hold():
    p = slew_params([0.1, 0.2, 0.3], [0.1, 0.2, 0.3], 1.0, 10.0)
    np.testing.assert_array_equal(_core.slew_axis(p), np.zeros(3))
    for t in (0.0, 3.0, 6.0, 20.0):
        np.testing.assert_allclose(_core.sigma_d(p, t), [0.1, 0.2, 0.3], atol=1e-16)
        np.testing.assert_array_equal(_core.omega_d(p, t), np.zeros(3))


def test_shipped_slew_scenario():
    s = load_scenario("slew_rest_to_rest")
    g = s.guidance
    assert g.kind == "slew" and (g.start, g.duration) == (10.0, 100.0)
    np.testing.assert_allclose(g.target, mrp_of_dcm(rot([1, 2, 2], math.pi / 2)), atol=1e-16)
    assert abs(g.angle - math.pi / 2) < 1e-14
    assert abs(g.max_rate - math.pi / 100) < 1e-15 and abs(g.max_accel - math.pi**2 / 1e4) < 1e-15
    np.testing.assert_array_equal(s.plant.disturbance.amp, np.zeros(3))
    assert s.actuators.faults == () and s.plant.w0 == 0.0
    cfg = s.core_config().guidance
    assert cfg.kind == _core.GuidanceKind.Slew and (cfg.slew_start, cfg.slew_duration) == (10.0, 100.0)


def test_fill_tracking_errors_uses_the_slew():
    s = load_scenario("slew_rest_to_rest")
    from sc_rt.results.record.run import RunMeta

    t = np.arange(0, 1501) / 10.0
    run = Run.allocate(len(t), RunMeta.of_scenario(s, "test"))  # no controller telemetry
    run["t"][:] = t
    run["sigma_BN"][:] = 0.0
    run["omega_BN_B"][:] = 0.0
    assert fill_tracking_errors(run, s.core_config().guidance) == len(t)
    for k in (0, 100, 350, 600, 1100, 1500):
        theta, rate, _ = cycloid(math.pi / 2, 100.0, min(max((t[k] - 10) / 100, 0), 1))
        e = np.array([1, 2, 2]) / 3
        np.testing.assert_allclose(run["sigma_DN"][k], mrp_of_dcm(rot(e, theta)), atol=1e-12)
        # the body at rest at N: omega_BD_B = -R(sigma_BD) omega_d
        np.testing.assert_allclose(run["omega_BD_B"][k], -dcm_of_mrp(run["sigma_BD"][k]) @ (rate * e),
                                   atol=1e-15)


# --------------------------------------------------------------------------- #
# Table (a reference file)


def spin(t, w=0.05):
    """A constant-rate rotation about E from C0: attitude, rate (the SLERP's exact case)."""
    return mrp_of_dcm(rot(E, w * t) @ C0), w * E


def test_table_is_exact_at_the_samples():
    rng = np.random.default_rng(7)
    t = np.cumsum(rng.uniform(0.1, 2.0, 12)) - 1.0
    sigma = np.array([mrp_of_dcm(rot(rng.normal(size=3), rng.uniform(0, 2.5))) for _ in t])
    omega = rng.normal(scale=0.02, size=(len(t), 3))
    p = table_params(t, sigma, omega)
    assert _core.validate(p) == []
    for k in range(len(t)):
        np.testing.assert_allclose(_core.sigma_d(p, t[k]), sigma[k], rtol=0, atol=1e-15)
        np.testing.assert_array_equal(_core.omega_d(p, t[k]), omega[k])


def test_table_slerp_reproduces_a_constant_rate_rotation_between_samples():
    t = np.array([-0.5, 0.0, 0.7, 2.0, 2.1, 5.0, 9.5, 12.0])  # uneven on purpose
    samples = [spin(x) for x in t]
    p = table_params(t, [s for s, _ in samples], [w for _, w in samples])
    for x in np.linspace(-0.5, 12.0, 251):
        s, w = spin(x)
        np.testing.assert_allclose(_core.sigma_d(p, x), s, rtol=0, atol=1e-12)
        np.testing.assert_allclose(_core.omega_d(p, x), w, rtol=0, atol=1e-15)
        np.testing.assert_allclose(_core.omega_d_dot(p, x), np.zeros(3), rtol=0, atol=1e-15)


def test_table_rate_is_linear_and_its_slope_is_omega_dot():
    t = np.array([0.0, 1.0, 3.0, 3.5, 10.0])
    a, b = np.array([0.01, -0.02, 0.005]), np.array([1e-3, 2e-3, -5e-4])
    omega = np.array([a + b * x for x in t])  # omega linear in t: interpolation is exact
    sigma = np.array([spin(x)[0] for x in t])
    p = table_params(t, sigma, omega)
    for x in np.linspace(0.0, 10.0, 97):
        np.testing.assert_allclose(_core.omega_d(p, x), a + b * x, rtol=0, atol=1e-16)
        np.testing.assert_allclose(_core.omega_d_dot(p, x), b, rtol=0, atol=1e-16)
    # piecewise linear: the slope of each segment
    omega2 = omega.copy()
    omega2[2] += [0.01, 0.0, 0.0]
    p2 = table_params(t, sigma, omega2)
    np.testing.assert_allclose(_core.omega_d_dot(p2, 2.0), b + [0.01 / 2.0, 0, 0], atol=1e-16)
    np.testing.assert_allclose(_core.omega_d_dot(p2, 3.2), b - [0.01 / 0.5, 0, 0], atol=1e-16)
    # outside the samples: at rest at the end sample
    np.testing.assert_array_equal(_core.omega_d(p, 10.5), np.zeros(3))
    np.testing.assert_array_equal(_core.sigma_d(p, 11.0), sigma[-1])


def _write_csv(path: Path, t, attitude, omega, names, header_extra: str = "") -> Path:
    lines = ["# a reference file", header_extra + ",".join(["t", *names, "omega_x", "omega_y", "omega_z"])]
    for x, q, w in zip(t, attitude, omega):
        lines.append(",".join(repr(float(v)) for v in (x, *q, *w)))
    path.write_text("\n".join(lines) + "\n")
    return path


def _scenario(tmp_path: Path, guidance: str, duration: float = 10.0) -> Path:
    """The shipped slew scenario with another [guidance] table and run length."""
    text = SLEW.read_text()
    text = (text[: text.index("\n[guidance]\n")] + "\n[guidance]\n" + guidance + "\n\n"
            + text[text.index("\n[controller.ppc]\n"):])
    text = re.sub(r"(?m)^duration = 150\.0.*$", f"duration = {duration}", text)
    path = tmp_path / "scn.toml"
    path.write_text(text)
    return path


def _quats(t):
    return [quat_of_dcm(dcm_of_mrp(spin(x)[0])) for x in t]


def test_file_reference_csv_quaternions_and_npz_mrps(tmp_path):
    t = np.linspace(-1.0, 12.0, 27)
    omega = [spin(x)[1] for x in t]
    _write_csv(tmp_path / "ref.csv", t, _quats(t), omega, ["q_w", "q_x", "q_y", "q_z"])
    np.savez(tmp_path / "ref.npz", t=t, sigma=np.array([spin(x)[0] for x in t]), omega=np.array(omega))
    np.savez(tmp_path / "ref_q.npz", t=t, q=-np.array(_quats(t)), omega=np.array(omega))  # the other sign
    _write_csv(tmp_path / "ref_s.csv", t, [spin(x)[0] for x in t], omega, ["sigma_x", "sigma_y", "sigma_z"])
    for name in ("ref.csv", "ref.npz", "ref_q.npz", "ref_s.csv"):
        s = load_scenario(_scenario(tmp_path, f'kind = "file"\nfile = "{name}"\n'))
        assert s.guidance.kind == "file" and s.guidance.t.size == t.size
        np.testing.assert_allclose(s.guidance.sigma_d0, spin(0.0)[0], atol=1e-12)
        cfg = s.core_config().guidance  # through controller_config_t's arrays
        assert cfg.kind == _core.GuidanceKind.Table
        g = _core.Guidance(cfg, 0.1)
        g.reset(0.0)
        for x in np.linspace(0.0, 10.0, 41):
            g.advance(x)
            np.testing.assert_allclose(g.sigma_DN, spin(x)[0], rtol=0, atol=1e-12)
            np.testing.assert_allclose(_core.omega_d(cfg, x), spin(x)[1], rtol=0, atol=1e-15)
        # the scenario as data (Monte Carlo) keeps the file, not its numbers
        from sc_rt.scenario.keys import scenario_data

        assert scenario_data(s)["guidance"] == {"kind": "file", "file": name}


def _issue(path: Path, guidance: str, csv_text: str | None = None, duration: float = 10.0):
    if csv_text is not None:
        (path.parent / "ref.csv").write_text(csv_text)
    scn = _scenario(path.parent, guidance, duration)
    with pytest.raises(ScenarioError) as exc:
        load_scenario(scn)
    err = exc.value
    assert err.path == str(scn)
    line = next(n for n, ln in enumerate(scn.read_text().splitlines(), 1) if ln.startswith("file =")) \
        if "file =" in guidance else None
    return err, line


GOOD = "t,sigma_x,sigma_y,sigma_z,omega_x,omega_y,omega_z\n"


@pytest.mark.parametrize("rows, expected", [
    ("0,0,0,0,0,0,0\n5,0,0,0,0,0,0\n5,0,0,0,0,0,0\n10,0,0,0,0,0,0\n",
     r"ref\.csv: line 5: t = 5 must be greater than the previous time 5 \(line 4\)"),
    ("0,0,0,0,0,0,0\n4,0,0,0,0,0,0\n3,0,0,0,0,0,0\n10,0,0,0,0,0,0\n",
     r"ref\.csv: line 5: t = 3 must be greater than the previous time 4 \(line 4\)"),
    ("0,0,0,0,0,0,0\n5,0,nan,0,0,0,0\n10,0,0,0,0,0,0\n", r"ref\.csv: line 4: sigma_y = nan must be finite"),
    ("0,0,0,0,0,0,0\n5,0,0,0,0,inf,0\n10,0,0,0,0,0,0\n", r"ref\.csv: line 4: omega_y = inf must be finite"),
    ("0,0,0,0,0,0,0\n5,30,0,0,0,0,0\n10,0,0,0,0,0,0\n",
     r"ref\.csv: line 4: the MRP \[30, 0, 0\] has norm 30: must be <= 1"),
    ("1,0,0,0,0,0,0\n10,0,0,0,0,0,0\n", r"its times 1 \.\. 10 s must cover the run, 0 \.\. 10 s"),
    ("0,0,0,0,0,0,0\n9.5,0,0,0,0,0,0\n", r"its times 0 \.\. 9\.5 s must cover the run, 0 \.\. 10 s"),
    ("0,0,0,0,0,0,0\n", r"1 samples: a reference file needs 2"),
    ("0,0,0,0,0,0\n10,0,0,0,0,0,0\n", r"ref\.csv: line 3: 6 values for 7 columns"),
    ("0,0,0,x,0,0,0\n10,0,0,0,0,0,0\n", r"ref\.csv: line 3: 'x' is not a number"),
])
def test_file_reference_errors_name_the_file_line_and_key(tmp_path, rows, expected):
    err, line = _issue(tmp_path / "x", 'kind = "file"\nfile = "ref.csv"', "# header next\n" + GOOD + rows)
    assert len(err.errors) == 1, err
    issue = err.errors[0]
    assert (issue.key, issue.value, issue.line) == ("guidance.file", "ref.csv", line)
    assert re.search(expected, issue.message), issue.message
    assert f"{err.path}:{line}: guidance.file = \"ref.csv\": " in str(err)


def test_file_reference_non_unit_quaternion(tmp_path):
    text = ("t,q_w,q_x,q_y,q_z,omega_x,omega_y,omega_z\n0,1,0,0,0,0,0,0\n"
            "5,0.9,0.1,0,0,0,0,0\n10,1,0,0,0,0,0,0\n")
    err, line = _issue(tmp_path / "x", 'kind = "file"\nfile = "ref.csv"', text)
    (issue,) = err.errors
    assert (issue.key, issue.line) == ("guidance.file", line)
    assert re.search(r"line 3: the quaternion \[0\.9, 0\.1, 0, 0\] has norm 0\.905538514: must be unit",
                     issue.message), issue.message


@pytest.mark.parametrize("text, expected", [
    ("t,q_w,q_x,q_y,q_z,sigma_x,sigma_y,sigma_z,omega_x,omega_y,omega_z\n", "give the attitude once"),
    ("t,sigma_x,sigma_y,omega_x,omega_y,omega_z\n", "missing columns: sigma_z"),
    ("t,sigma_x,sigma_y,sigma_z,omega_x,omega_y,omega_zz\n", "unknown column 'omega_zz'"),
    ("# only a comment\n", "no header row"),
])
def test_file_reference_header_errors(tmp_path, text, expected):
    err, line = _issue(tmp_path / "x", 'kind = "file"\nfile = "ref.csv"', text)
    (issue,) = err.errors
    assert issue.key == "guidance.file" and issue.line == line and expected in issue.message


def test_file_reference_missing_file_npz_shape_and_suffix(tmp_path):
    err, _ = _issue(tmp_path / "x", 'kind = "file"\nfile = "nope.csv"')
    assert "cannot read the reference file" in err.errors[0].message
    np.savez(tmp_path / "bad.npz", t=np.arange(3.0), sigma=np.zeros((3, 2)), omega=np.zeros((3, 3)))
    err, _ = _issue(tmp_path / "x", 'kind = "file"\nfile = "bad.npz"')
    assert "array 'sigma' must be numbers of shape (n, 3)" in err.errors[0].message
    (tmp_path / "ref.txt").write_text("t\n")
    err, _ = _issue(tmp_path / "x", 'kind = "file"\nfile = "ref.txt"')
    assert "must be .csv or .npz" in err.errors[0].message


def test_file_reference_size_limit(tmp_path):
    n = _core.GUIDANCE_TABLE_MAX + 1  # what controller_config_t may carry, plus one
    np.savez(tmp_path / "big.npz", t=np.linspace(0.0, 10.0, n), sigma=np.zeros((n, 3)), omega=np.zeros((n, 3)))
    err, _ = _issue(tmp_path / "x", 'kind = "file"\nfile = "big.npz"')
    assert f"{n} samples: a reference file needs 2 .. {n - 1}" in err.errors[0].message
    p = table_params(np.linspace(0.0, 1.0, n), np.zeros((n, 3)), np.zeros((n, 3)))
    assert any("2..2000 samples" in e for e in _core.validate(p))


def test_a_longer_run_than_the_file_is_refused_on_override(tmp_path):
    t = np.array([0.0, 10.0])
    _write_csv(tmp_path / "ref.csv", t, [spin(x)[0] for x in t], [spin(x)[1] for x in t],
               ["sigma_x", "sigma_y", "sigma_z"])
    s = load_scenario(_scenario(tmp_path, 'kind = "file"\nfile = "ref.csv"'))
    with pytest.raises(ScenarioError) as exc:
        with_run(s, duration=20.0)
    (issue,) = exc.value.errors
    assert issue.key == "run.duration" and "must cover the run, 0 .. 20 s" in issue.message


@pytest.mark.parametrize("guidance, key, expected", [
    ('kind = "hold"\nsigma_d0 = [0, 0, 0]\nomega_cos = [0, 0, 0]', "guidance.omega_cos",
     "omega_cos is a key of kind 'paper', not of kind 'hold' (its keys: sigma_d0)"),
    ('kind = "slew"\nsigma_d0 = [0, 0, 0]\ntarget = [0, 0, 0.1]', "guidance.duration", "required key is missing"),
    ('kind = "slew"\nsigma_d0 = [0, 0, 0]\ntarget = [0, 0, 0.1]\nduration = 0', "guidance.duration", "must be > 0"),
    ('kind = "slew"\nsigma_d0 = [0, 0, 0]\ntarget = [0, 0, 2]\nduration = 5', "guidance.target",
     "must be an MRP with norm <= 1"),
    ('kind = "spin"', "guidance.kind", 'must be one of "paper", "hold", "slew", "file"'),
])
def test_guidance_table_errors(tmp_path, guidance, key, expected):
    scn = _scenario(tmp_path, guidance)
    with pytest.raises(ScenarioError) as exc:
        load_scenario(scn)
    (issue,) = exc.value.errors
    lines = scn.read_text().splitlines()
    table = lines.index("[guidance]") + 1
    line = table if "missing" in expected else next(
        n for n, ln in enumerate(lines, 1) if n > table and ln.startswith(key.split(".")[1] + " ="))
    assert (issue.key, issue.line) == (key, line) and expected in issue.message, issue


def test_the_paper_reference_is_read_as_before():
    s = load_scenario("paper_fault_free")
    assert s.guidance.kind == "paper" and "kind" not in s.guidance.data()
    cfg = s.core_config().guidance
    assert cfg.kind == _core.GuidanceKind.Paper and _core.guidance_integrated(cfg)
    with pytest.raises(ValueError, match="integrated"):
        _core.sigma_d(cfg, 1.0)


# --------------------------------------------------------------------------- #
# The C++ controller process uses the same reference.


@pytest.mark.lcm
def test_lockstep_hil_of_a_slew_is_bit_identical_to_sim(tmp_path):
    import lcmnet
    from trajcmp import compared_fields

    from sc_rt.sim.engines import simulate

    lcmnet.require()
    duration = 40.0  # at rest, then the first 30 s of the slew (its fastest part included)
    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", "slew_rest_to_rest", "--mode", "lockstep", "--duration", str(duration),
                        "--out", str(out), "--no-plots"])
    assert r.returncode == 0, r.stderr + r.stdout
    hil = load_traj(out)
    sim = simulate(load_scenario("slew_rest_to_rest"), engine="python", duration=duration)
    assert len(hil["t"]) == len(sim["t"]) == 401
    compared_fields(hil, sim)
    # the controller's desired attitude is the slew's closed form
    for k in (0, 100, 250, 400):
        theta, _, _ = cycloid(math.pi / 2, 100.0, max((hil["t"][k] - 10.0) / 100.0, 0.0))
        np.testing.assert_allclose(hil["sigma_DN"][k], mrp_of_dcm(rot([1, 2, 2], theta)), atol=1e-12)
    assert json.loads((out / "metrics.json").read_text())["finite"]


@pytest.mark.lcm
def test_a_file_reference_reaches_the_controller_process_and_the_log(tmp_path):
    """The table travels in controller_config_t: the controller's sigma_DN is
    the spin's closed form, the run is bitwise the offline one, and the
    logged config carries the samples (what sc-rt report rebuilds from)."""
    import lcm
    import lcmnet
    from trajcmp import compared_fields

    from sc_rt.sim.engines import simulate

    lcmnet.require()
    w = 0.02  # [rad/s] about E from N: SLERP between the samples is exact
    t = np.linspace(-1.0, 21.0, 45)
    sigma = [mrp_of_dcm(rot(E, w * x)) for x in t]
    _write_csv(tmp_path / "ref.csv", t, [quat_of_dcm(dcm_of_mrp(s)) for s in sigma],
               [w * E] * len(t), ["q_w", "q_x", "q_y", "q_z"])
    scn_path = _scenario(tmp_path, 'kind = "file"\nfile = "ref.csv"', duration=20.0)
    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", str(scn_path), "--law", "pd", "--mode", "lockstep", "--out", str(out),
                        "--no-plots"])
    assert r.returncode == 0, r.stderr + r.stdout
    hil = load_traj(out)
    sim = simulate(load_scenario(scn_path), law="pd", engine="python")
    assert len(hil["t"]) == len(sim["t"]) == 201
    compared_fields(hil, sim)
    for k in range(0, 201, 20):
        np.testing.assert_allclose(hil["sigma_DN"][k], mrp_of_dcm(rot(E, w * hil["t"][k])), atol=1e-12)
    # external processes get it on the bus: the emulator's guidance_t (from _core.Guidance)
    from sc_rt_lcm import guidance_t

    refs = [guidance_t.decode(e.data) for e in lcm.EventLog(str(out / "run.lcmlog"), "r")
            if e.channel == "SCRT_GUIDANCE"]
    assert len(refs) > 100  # the logger may miss a few on a loaded machine
    for m in refs:
        np.testing.assert_allclose(m.sigma_DN, mrp_of_dcm(rot(E, w * m.t)), rtol=0, atol=1e-12)
        np.testing.assert_allclose(m.omega_DN_D, w * E, rtol=0, atol=1e-15)
        np.testing.assert_array_equal(m.omega_dot_DN_D, np.zeros(3))
    configs = [e.data for e in lcm.EventLog(str(out / "run.lcmlog"), "r") if e.channel == "SCRT_CONFIG"]
    assert len(configs) == 1
    logged = _core.ControllerConfig.from_lcm_bytes(configs[0]).guidance
    assert logged.kind == _core.GuidanceKind.Table
    np.testing.assert_array_equal(logged.table_t, t)
    np.testing.assert_allclose(logged.table_sigma, sigma, atol=1e-15)
    rep = tmp_path / "report"
    r = lcmnet.run_cli(["report", str(out / "run.lcmlog"), "--out", str(rep), "--no-plots"], netns=False)
    assert r.returncode == 0, r.stderr + r.stdout
    rt = load_traj(rep)  # the rows whose messages the logger kept
    rows = np.searchsorted(hil["t"], rt["t"])
    np.testing.assert_array_equal(hil["t"][rows], rt["t"])
    np.testing.assert_array_equal(rt["sigma_DN"], hil["sigma_DN"][rows])
    # rows without controller telemetry (a real-time run's unused states) are
    # filled from the logged reference exactly as the controller had them
    run = Run.load(out).in_memory()  # (its columns written into below)
    gone = np.arange(3, 201, 7)
    for name in ("sigma_DN", "sigma_BD", "omega_BD_B"):
        run[name][gone] = np.nan
    assert fill_tracking_errors(run, logged) == gone.size
    for name in ("sigma_DN", "sigma_BD"):
        np.testing.assert_array_equal(run[name], hil[name], err_msg=name)
    # numpy's R @ omega_d rounds in another order than the core's: the last bit
    np.testing.assert_allclose(run["omega_BD_B"], hil["omega_BD_B"], rtol=0, atol=1e-17)


def test_every_offline_engine_follows_the_slew():
    """The C++ loop, the Python loop and the unsampled reference (whose paper
    guidance is an ODE state) all take the slew's closed form."""
    from sc_rt.sim.engines import simulate

    s = load_scenario("slew_rest_to_rest")
    e = np.array([1.0, 2.0, 2.0]) / 3
    for engine in ("cpp", "python", "unsampled"):
        r = simulate(s, engine=engine, duration=30.0)
        for k in (0, 120, 200, 300):
            s_ = max((r["t"][k] - 10.0) / 100.0, 0.0)
            theta = math.pi / 2 * (s_ - math.sin(2 * math.pi * s_) / (2 * math.pi))
            np.testing.assert_allclose(r["sigma_DN"][k], mrp_of_dcm(rot(e, theta)), atol=1e-12, err_msg=engine)
        assert np.abs(r["sigma_BD"]).max() < 1e-6, engine  # it tracks (feedforward of omega_d, omega_d_dot)


def test_an_unvalidated_table_is_refused_not_read_out_of_bounds():
    p = _core.GuidanceParams()
    p.kind = _core.GuidanceKind.Table
    for f in (_core.sigma_d, _core.omega_d, _core.omega_d_dot):
        with pytest.raises(ValueError, match="table reference needs"):
            f(p, 0.0)
    p = table_params([0.0, 1.0], np.zeros((3, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="table reference needs"):
        _core.omega_d(p, 0.5)
    with pytest.raises(ValueError, match="one row per time"):
        _core.Guidance(p, 0.1)


def test_the_core_validates_what_it_is_sent():
    """A controller_config_t not made by the scenario reader is checked by the core."""
    p = table_params([0.0, 1.0, 1.0], np.zeros((3, 3)), np.zeros((3, 3)))
    assert any("strictly increasing" in e and "sample 2" in e for e in _core.validate(p))
    p = table_params([0.0, 1.0], [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]], np.zeros((2, 3)))
    assert any("table_sigma sample 1" in e for e in _core.validate(p))
    p = table_params([0.0, 1.0], np.zeros((2, 3)), [[0.0, np.nan, 0.0], [0.0, 0.0, 0.0]])
    assert any("table_omega sample 0" in e for e in _core.validate(p))
    p = slew_params([0.0, 0.0, 0.0], [0.0, 0.0, 0.5], 0.0, 0.0)
    assert any("slew_duration must be > 0" in e for e in _core.validate(p))
    p = slew_params([0.0, 0.0, 0.0], [0.0, 0.0, 1.5], 0.0, 10.0)
    assert any("slew_target must be finite with |slew_target| <= 1" in e for e in _core.validate(p))
    # and the wire's kind must be one of GUIDANCE_*
    s = load_scenario("slew_rest_to_rest")
    m = s.controller_config_msg()
    m.guidance_kind = 7
    with pytest.raises(ValueError, match="guidance_kind must be 0..3"):
        _core.ControllerConfig.from_lcm_bytes(m.encode())
