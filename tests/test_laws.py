"""The control-law interface (issue #14 A, docs/LAWS.md): the registry, law
plugins built out of tree against the installed package (CMake package
config), their bad input, a law that fails mid-run, and the proof with a
second published law through the plugin interface only: the quaternion
feedback regulator of Wie, Weiss & Arapostathis (1989), examples/
quaternion_feedback, whose rest-to-rest slews stay about the eigenaxis."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

import sc_rt.cmake
from sc_rt import _core
from sc_rt.scenario.model import ScenarioError
from sc_rt.plan.run import plan_run
from sc_rt.scenario.reader import load_scenario, scenario_from_data
from sc_rt.sim.engines import simulate

import lcmnet
import plugbuild
from refmath import mrp_sub, mrp_to_quat
from trajcmp import compared_fields, load_traj

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent


_build = plugbuild.build
_cmake = plugbuild.cmake


def _spec(lib: Path) -> str:
    return f"plugin:{lib}"


# --------------------------------------------------------------------------- #
# The registry and the built-in laws behind it.


def test_builtin_laws_are_registered_in_order():
    assert _core.law_names()[:4] == ["dsc-ppc", "dsc", "pd", "rft"]
    for code, name in enumerate(["dsc-ppc", "dsc", "pd", "rft"]):
        info = _core.law_info(name)
        assert (info["name"], info["source"], info["code"]) == (name, "built-in", code)
        cfg = _core.ControllerConfig()
        cfg.law = name
        ctl = _core.Controller(cfg)
        assert (ctl.law_name, ctl.law_code) == (name, code)
    assert _core.ControllerConfig().law == _core.DEFAULT_LAW == "dsc-ppc"
    with pytest.raises(ValueError, match='unknown law "lqr"'):
        _core.law_info("lqr")


def test_no_law_name_outside_its_file_and_the_registry():
    """A law's name appears in the C++ only where it registers itself (and as
    the registry's default); the controller, the shell, the bindings and the
    LCM types know none ("dsc", "pd", "rft" in quotes elsewhere are the
    old layout's fields, controller_config_v1_t, kept to read old logs)."""
    names = ('"dsc-ppc"', "Law::", "LAW_DSC", "LAW_PD", "LAW_RFT", 'register_law("')
    allowed = {"cpp/src/law_dsc.cpp", "cpp/src/law_pd.cpp", "cpp/src/law_rft.cpp", "cpp/src/law_registry.cpp"}
    hits = []
    for p in list((ROOT / "cpp").rglob("*.[ch]pp")) + [
            f for f in (ROOT / "lcmtypes").glob("*.lcm")
            if f.name not in ("controller_config_v1_t.lcm", "controller_config_v2_t.lcm",
                                  "controller_config_v3_t.lcm")]:
        rel = p.relative_to(ROOT).as_posix()
        text = re.sub(r"//.*", "", p.read_text())  # comments may name a law
        for n in names:
            if n in text and rel not in allowed:
                hits.append((rel, n))
    assert hits == []


def test_config_carries_the_law_spec_and_params_through_lcm():
    c = _core.ControllerConfig()
    c.law = "plugin:/somewhere/libx.so"
    c.law_params = [("k", [0.5]), ("gains", [1.0, 2.0, 3.0]), ("empty", [])]
    back = _core.ControllerConfig.from_lcm_bytes(c.to_lcm_bytes("x"))
    assert back.law == "plugin:/somewhere/libx.so"
    assert back.law_params == [("k", [0.5]), ("gains", [1.0, 2.0, 3.0]), ("empty", [])]


def test_builtin_law_refuses_params():
    s = load_scenario("paper_fault_free")
    cfg = s.core_config()
    cfg.law_params = [("beta1", [0.1])]
    [(key, msg)] = _core.check_law(cfg)
    assert key == "params.beta1" and "unknown parameter of law dsc-ppc" in msg


# --------------------------------------------------------------------------- #
# Plugins: loading, both engines, the controller process.


def test_plugin_loads_and_registers_its_name(plugins):
    name = _core.load_law_plugin(str(plugins["qf"]))
    assert name == "quaternion-feedback"
    assert _core.load_law_plugin(str(plugins["qf"])) == name  # idempotent per file
    info = _core.law_info(_spec(plugins["qf"]))
    assert info["name"] == name and info["source"] == str(plugins["qf"].resolve())
    assert info["code"] >= 4 and name in _core.law_names()


def _qf_expected(scn, x, k=0.08, c=0.4) -> np.ndarray:
    """The regulator's command from the paper's formula, computed here in
    numpy (refmath: MRP composition and quaternion), not by the plugin."""
    p = scn.plant
    sig_BD = mrp_sub(x[0:3], scn.guidance.sigma_d0)  # omega_d = 0 at t = 0 for this check
    q = mrp_to_quat(sig_BD)
    J, W, Om = p.J0, x[3:6], x[6:10]
    # x2 = omega - R(x1) omega_d(0), omega_d(0) = bias + cos amplitude
    from refmath import R

    wd = scn.guidance.omega_bias + scn.guidance.omega_cos
    x2 = W - R(sig_BD) @ wd
    h = J @ W + p.Cbar @ (p.Jw * Om)
    tau = -k * J @ q[1:] - c * J @ x2 + np.cross(W, h)
    Bm = -np.linalg.inv(J) @ p.Cbar @ np.diag(p.Jw)
    return np.linalg.pinv(Bm) @ np.linalg.inv(J) @ tau


def test_plugin_command_is_the_papers_formula(plugins):
    scn = load_scenario("paper_fault_free")
    ctl = _core.Controller(scn.core_config(law=_spec(plugins["qf"])))
    x = np.array([0.3, -0.2, 0.1, 0.01, -0.02, 0.03, 10.0, -5.0, 3.0, 1.0])
    m = _core.Measurement(0.0, x[0:3], x[3:6], x[6:10])
    ctl.reset(m)
    cmd = ctl.step(m)
    np.testing.assert_allclose(cmd.u_cmd, _qf_expected(scn, x), rtol=1e-12, atol=1e-14)
    assert ctl.telemetry_names == ["q0", "torque_norm [N m]"]
    assert cmd.telemetry[0] == pytest.approx(mrp_to_quat(mrp_sub(x[0:3], scn.guidance.sigma_d0))[0], abs=1e-15)


@pytest.mark.parametrize("scenario", ["paper_fault_free", "paper_faults"])
def test_plugin_engines_are_bitwise_equal(plugins, scenario):
    scn = load_scenario(scenario)
    a = simulate(scn, law=_spec(plugins["qf"]), engine="python", duration=30.0)
    b = simulate(scn, law=_spec(plugins["qf"]), engine="cpp", duration=30.0)
    for k in ("sigma_BN", "omega_BN_B", "wheel_speed", "u_cmd", "u_sat", "sigma_BD", "e1", "e2"):
        assert np.array_equal(a[k], b[k]), k
    assert a.metrics["law_invalid_steps"] == 0 and np.all(np.isfinite(a["u_cmd"]))


def test_scenario_names_a_plugin_and_its_params(plugins, tmp_path):
    src = (ROOT / "scenarios" / "paper_fault_free.toml").read_text()
    lib = plugins["qf"]
    f = tmp_path / "scn" / "qf.toml"
    f.parent.mkdir()
    rel = os.path.relpath(lib, f.parent)  # a relative path is relative to the scenario file
    text = src.replace('controller = "dsc-ppc"', "") + (
        '\n[controller.params]\nk = 0.1\nc = 0.5\n')
    text = text.replace("[controller]\n", f'[controller]\nlaw = "plugin:{rel}"\n', 1)
    f.write_text(text)
    scn = plan_run(f).scenario  # the plugin is loaded where the run is planned (issue 38 item 2)
    assert scn.run.controller == f"plugin:{lib.resolve()}"
    assert scn.controller.table("quaternion-feedback") == (("k", (0.1,)), ("c", (0.5,)))
    cfg = scn.core_config()
    assert cfg.law_params == [("k", [0.1]), ("c", [0.5])]
    # the params reach the law: its command is the formula with k = 0.1, c = 0.5
    ctl = _core.Controller(cfg)
    x = np.concatenate([scn.initial.sigma_BN, scn.initial.omega_BN_B, scn.initial.wheel_speed])
    m = _core.Measurement(0.0, x[0:3], x[3:6], x[6:10])
    ctl.reset(m)
    np.testing.assert_allclose(ctl.step(m).u_cmd, _qf_expected(scn, x, 0.1, 0.5), rtol=1e-12, atol=1e-14)


def _bad_scenario(tmp_path, law: str, params: str = "") -> Path:
    src = (ROOT / "scenarios" / "paper_fault_free.toml").read_text()
    text = src.replace('controller = "dsc-ppc"', f'controller = "{law}"')
    if params:
        text += "\n[controller.params]\n" + params
    f = tmp_path / "bad.toml"
    f.write_text(text)
    return f


def _line_of(f: Path, needle: str) -> int:
    """The last line that starts with needle (the params table is at the end)."""
    return [i for i, line in enumerate(f.read_text().splitlines(), 1) if line.startswith(needle)][-1]


@pytest.mark.parametrize("which, params, key, message", [
    ("qf", "k = 0.1\nfoo = 1.0\n", "controller.params.foo", "unknown parameter of law quaternion-feedback"),
    ("qf", "k = -1.0\n", "controller.params.k", "must be > 0"),
    ("qf", "gyro = 0.5\n", "controller.params.gyro", "must be 0 or 1"),
    ("qf", "k = [1.0, 2.0]\n", "controller.params.k", "must be one number"),
    ("throws", "", "run.controller", "construction failed: no gains for this spacecraft"),
    ("nan_probe", "", "run.controller", "non-finite command (or throws) at rest (probe step"),
    ("noentry", "", "run.controller", "has no sc_rt_law_api_version(): not an sc-rt law plugin"),
    ("version99", "", "run.controller", "built against law interface version 99, this sc-rt has 3"),
    ("fingerprint", "", "run.controller", 'built with "api-1 othercc-3 cxxabi-other", this sc-rt has'),
])
def test_bad_plugin_in_a_scenario_names_file_line_key(plugins, tmp_path, which, params, key, message):
    f = _bad_scenario(tmp_path, _spec(plugins[which]), params)
    with pytest.raises(ScenarioError) as e:  # the plugin is loaded and probed where the run is planned
        plan_run(f)
    [issue] = e.value.errors
    assert issue.key == key and message in issue.message, issue
    needle = key.rpartition(".")[2] + " =" if key.startswith("controller.params") else "controller ="
    assert issue.line == _line_of(f, needle)
    assert str(f) in str(e.value)


def test_missing_plugin_and_library_errors_name_the_plugin(plugins, tmp_path):
    with pytest.raises(ValueError, match=r"law plugin:/nonexistent/libx.so: no such file /nonexistent/libx.so"):
        _core.load_law_plugin("/nonexistent/libx.so")
    with pytest.raises(ValueError, match=r"law plugin:nolaw: not found: no libnolaw.so or nolaw.so in SCRT_LAW_PATH"):
        _core.load_law_plugin("nolaw")
    junk = tmp_path / "libjunk.so"
    junk.write_bytes(b"not an ELF file")
    with pytest.raises(ValueError, match=r"law plugin:.*libjunk.so: cannot load .*libjunk.so: "):
        _core.load_law_plugin(str(junk))


def test_plugin_by_name_from_scrt_law_path(plugins, tmp_path):
    env = {"SCRT_LAW_PATH": f"/nonexistent:{plugins['badparam'].parent}"}
    code = ("from sc_rt import _core; print(_core.load_law_plugin('t_badparam'))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={**_env(), **env})
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "t-badparam"


def _env() -> dict[str, str]:
    return dict(os.environ)


@pytest.mark.parametrize("which, message", [
    ("missing", "no such file"),
    ("noentry", "not an sc-rt law plugin"),
    ("version99", "built against law interface version 99"),
    ("throws", "construction failed: no gains for this spacecraft"),
    ("nan_probe", "non-finite command"),
])
def test_cli_refuses_a_bad_plugin_in_one_line_before_running(plugins, tmp_path, which, message):
    lib = tmp_path / "none.so" if which == "missing" else plugins[which]
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", "paper_fault_free", "--law", f"plugin:{lib}",
                        "--out", str(out), "--no-plots"], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and message in lines[0] and str(lib.name) in lines[0], r.stderr
    assert not out.exists()  # nothing started


def test_controller_binary_law_plugin_option(plugins, tmp_path):
    scn = load_scenario("paper_fault_free")
    cfg = tmp_path / "cfg.bin"
    cfg.write_bytes(scn.controller_config_msg().encode())
    exe = BIN / "sc-rt-controller"
    r = subprocess.run([str(exe), "--config", str(cfg), "--check", "--law-plugin", str(plugins["qf"])],
                       capture_output=True, text=True)
    assert r.returncode == 0 and "law quaternion-feedback" in r.stdout, r.stderr
    r = subprocess.run([str(exe), "--config", str(cfg), "--check", "--law-plugin", str(plugins["version99"])],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "built against law interface version 99" in r.stderr


# --------------------------------------------------------------------------- #
# A law that fails during a run.


def test_law_returning_nan_mid_run_gives_safe_and_is_counted(plugins):
    scn = load_scenario("paper_fault_free")
    for engine in ("python", "cpp"):
        run = simulate(scn, law=_spec(plugins["nan_run"]), engine=engine, duration=10.0)
        t, flags, mode = run["t"], run["flags"], run["ctrl_mode"]
        bad = (t >= 2.0 - 1e-9) & (t < 3.0 - 1e-9)  # the law's NaN second: 10 steps at 10 Hz
        assert np.array_equal((flags & _core.FLAG_LAW_INVALID) != 0, bad), engine
        assert np.all(mode[bad] == _core.MODE_SAFE) and np.all(mode[~bad] == _core.MODE_NORMAL)
        assert np.all(run["u_cmd"][bad] == 0.0) and np.all(run["u_sat"][bad] == 0.0)
        assert run.metrics["law_invalid_steps"] == 10 and run.metrics["safe_steps"] == 10
        assert len(t) == 101 and np.all(np.isfinite(run["u_cmd"]))  # the run continued to its end
        assert "the law returned a non-finite command (or threw)" in run.metrics["safe_reasons"]


def test_law_throwing_mid_run_gives_safe_and_reengages(plugins):
    scn = load_scenario("paper_fault_free")
    c = scn.core_config(law=_spec(plugins["nan_run"]))
    c.law_params = [("t_nan", [100.0]), ("t_throw", [1.0])]
    ctl = _core.Controller(c)
    x = np.concatenate([scn.initial.sigma_BN, scn.initial.omega_BN_B, scn.initial.wheel_speed])
    ctl.reset(_core.Measurement(0.0, x[0:3], x[3:6], x[6:10]))
    modes, resets = [], []
    for k in range(15):
        cmd = ctl.step(_core.Measurement(0.1 * k, x[0:3], x[3:6], x[6:10]))
        modes.append(cmd.mode)
        resets.append(cmd.telemetry[0])
    assert modes[10] == _core.MODE_SAFE and modes.count(_core.MODE_SAFE) == 1
    assert resets[9] == 1 and resets[11] == 2  # re-engaged (reset) at the step after the failure


# --------------------------------------------------------------------------- #
# The proof: quaternion feedback's eigenaxis rotation.


def _slew_scenario(lib: Path, gyro: int = 1) -> tuple:
    """Rest to rest, 60 deg about a non-principal axis: no disturbance, the
    plant's inertia = J0, no faults, no gravity gradient (w0 = 0), limits far
    beyond the commands, a constant desired attitude (omega_d = 0), and a
    momentum bias in the wheels (so that omega x h is not zero). The desired
    attitude is the guidance's inertial hold ([guidance] kind = "hold")."""
    data = tomllib.loads((ROOT / "scenarios" / "paper_fault_free.toml").read_text())
    e = np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)
    phi = math.radians(60.0)
    data["run"].update(duration=60.0, control_rate_hz=100.0, plant_step=0.01, controller=_spec(lib))
    data["spacecraft"].update(dJ=[[0.0] * 3] * 3, umin=-1e3, umax=1e3, w0=0.0)
    data["disturbance"].update(amp=[0.0] * 3, bias=[0.0] * 3)
    data["initial"].update(sigma_BN=list(math.tan(phi / 4) * e), omega_BN_B=[0.0] * 3,
                           wheel_speed=[60.0, -40.0, 30.0, 20.0])
    data["guidance"] = {"kind": "hold", "sigma_d0": [0.0] * 3}  # C's inertial hold: omega_d = 0
    data["controller"]["params"] = {"k": 0.08, "c": 0.4, "gyro": float(gyro)}
    data.pop("faults", None)
    # [controller.params] named by the plugin's own name once it is loaded, where the run is planned
    return plan_run(scenario_from_data(data, ROOT / "scenarios" / "slew.toml")).scenario, e


def _axis_drift(scn, run) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per row: the angle [rad] between the error's rotation axis and the
    initial one, the bound on it (derived below) and |q_v|, all from the
    plant's state (sigma_DN = 0, so sigma_BD = sigma_BN)."""
    s = run["sigma_BN"]
    q = np.array([mrp_to_quat(x) for x in s])
    qv = q[:, 1:]
    n = np.linalg.norm(qv, axis=1)
    e0 = qv[0] / n[0]
    perp = np.linalg.norm(qv - np.outer(qv @ e0, e0), axis=1)
    ang = np.arcsin(np.clip(perp / n, 0.0, 1.0))
    # The bound. With K = kJ, C = cJ and omega x h cancelled at each sample,
    # J dw/dt = -kJ q_v - cJ w + J r, where r = J^-1 (w_k x h_k - w(t) x h(t))
    # is what the zero-order hold leaves of the gyroscopic term within a period
    # T (h = J w + Cbar Jw Omega: dh/dt = -w x h). The part of q_v off the
    # initial axis, p, obeys p'' + c p' + (k q0 / 2) p = (q0 / 2) r_perp (to
    # first order in p): with c^2 >= 2 k (critically damped or over-damped for
    # every q0 <= 1) its impulse response is non-negative, so its L1 gain is
    # the DC gain 1/k and |p| <= R / k, R = sup |r|. R is bounded from the
    # samples: |d/dt (w x h)| <= |dw/dt| |h| + |w|^2 |h|, times T, times
    # |J^-1|. The angle is then asin(|p| / |q_v|) <= R / (k |q_v|).
    p = scn.plant
    J, T = p.J0, scn.run.control_period
    W, Om = run["omega_BN_B"], run["wheel_speed"]
    h = W @ J.T + (Om * p.Jw) @ p.Cbar.T
    wdot = np.gradient(W, run["t"], axis=0)
    R = np.linalg.norm(np.linalg.inv(J), 2) * T * np.max(
        np.linalg.norm(wdot, axis=1) * np.linalg.norm(h, axis=1)
        + np.linalg.norm(W, axis=1) ** 2 * np.linalg.norm(h, axis=1))
    k = dict(scn.controller.table("quaternion-feedback"))["k"][0]
    bound = np.minimum(R / (k * n), math.pi / 2)
    return ang, bound, n


def test_quaternion_feedback_slews_about_the_eigenaxis(plugins):
    scn, e = _slew_scenario(plugins["qf"])
    table = dict(scn.controller.table("quaternion-feedback"))
    c = table["c"][0]
    assert c * c >= 2 * table["k"][0]  # the bound's damping condition
    run = simulate(scn, engine="cpp")
    assert not np.any(run["u_cmd"] != run["u_sat"])  # never saturated
    ang, bound, n = _axis_drift(scn, run)
    np.testing.assert_allclose(ang[0], 0.0, atol=1e-15)
    live = n > 0.02 * n[0]  # until the error is 2 % of its start (the axis is defined)
    assert live.sum() > 1000  # a large part of the slew, not a few rows
    assert np.all(ang[live] <= bound[live]), (ang[live].max(), bound[live].min())
    # in numbers (docs/LAWS.md): the bound is 0.030 rad at the start and grows as
    # 1/|q_v|; the axis holds to 0.0030 rad (0.17 deg) while |q_v| > 20 % of its start
    assert np.max(ang[n > 0.2 * n[0]]) < 0.005
    assert n[-1] < 0.01 * n[0]  # and the slew completes (rest to rest)
    assert np.linalg.norm(run["omega_BN_B"][-1]) < 1e-3


def test_without_the_gyroscopic_term_the_axis_wanders(plugins):
    """The same slew with gyro = 0: omega x h is not cancelled and the axis
    leaves the bound the cancelled law keeps (the test above can fail)."""
    scn0, _ = _slew_scenario(plugins["qf"], gyro=0)
    ang0, bound0, n0 = _axis_drift(scn0, simulate(scn0, engine="cpp"))
    live = n0 > 0.02 * n0[0]
    assert np.mean(ang0[live] > bound0[live]) > 0.5 and np.max(ang0[live]) > 0.5


# --------------------------------------------------------------------------- #
# The bus: lockstep HIL with a plugin law is bitwise the offline run.


@pytest.mark.lcm
def test_lockstep_hil_with_a_plugin_is_bit_identical_to_sim(plugins, tmp_path):
    lcmnet.require()
    duration = 10.0
    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", "scenarios/paper_faults.toml", "--law", _spec(plugins["qf"]), "--mode",
                        "lockstep", "--duration", str(duration), "--out", str(out), "--no-plots"])
    assert r.returncode == 0, r.stderr + r.stdout
    hil = load_traj(out)
    sim = simulate(load_scenario(ROOT / "scenarios" / "paper_faults.toml"), law=_spec(plugins["qf"]),
                   engine="python", duration=duration)
    assert len(hil["t"]) == len(sim["t"]) == int(duration * 10) + 1
    compared_fields(hil, sim)
    summary = json.loads((out / "controller_summary.json").read_text())
    assert summary["law"] == "quaternion-feedback"


@pytest.mark.lcm
@pytest.mark.slow
def test_realtime_hil_runs_a_plugin(plugins, tmp_path):
    lcmnet.require()
    out = tmp_path / "rt"
    r = lcmnet.run_cli(["hil", "scenarios/paper_fault_free.toml", "--law", _spec(plugins["qf"]), "--mode",
                        "realtime", "--duration", "3", "--out", str(out), "--no-plots"])
    assert r.returncode == 0, r.stderr + r.stdout
    m = json.loads((out / "metrics.json").read_text())
    summary = json.loads((out / "controller_summary.json").read_text())
    assert summary["law"] == "quaternion-feedback" and summary["mode"] == "realtime"
    assert m["finite"] and m["law_invalid_steps"] == 0


# --------------------------------------------------------------------------- #
# sc-rt new-law, compare, --cmake-dir.


def test_cmake_dir_is_printed_by_both_helpers():
    a = subprocess.run([sys.executable, "-m", "sc_rt.cli", "--cmake-dir"], capture_output=True, text=True)
    b = subprocess.run([sys.executable, "-m", "sc_rt.cmake"], capture_output=True, text=True)
    assert a.returncode == b.returncode == 0 and a.stdout == b.stdout
    d = Path(a.stdout.strip())
    assert (d / "sc_rtConfig.cmake").is_file() and (d / "sc_rtConfigVersion.cmake").is_file()
    # the headers it points at are the source tree's, unchanged
    inc = sc_rt.cmake.include_dir() / "sc_rt"
    for h in ("law.hpp", "types.hpp"):
        assert (inc / h).read_text() == (ROOT / "cpp" / "include" / "sc_rt" / h).read_text()


@pytest.mark.slow
def test_new_law_scaffold_builds_and_runs(tmp_path):
    proj = tmp_path / "mylaw"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "new-law", "my-law", "--out", str(proj)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    _build(proj, proj / "build")
    lib = proj / "build" / "libmy_law.so"
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", "paper_fault_free", "--law", f"plugin:{lib}",
                        "--duration", "30", "--out", str(out), "--no-plots"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    # the scaffold's PD with its default gains is the built-in PD: same numbers
    pd = simulate(load_scenario("paper_fault_free"), law="pd", duration=30.0)
    np.testing.assert_array_equal(load_traj(out)["u_cmd"], pd["u_cmd"])
    again = subprocess.run([sys.executable, "-m", "sc_rt.cli", "new-law", "my-law", "--out", str(proj)],
                           capture_output=True, text=True)
    assert again.returncode == 2 and "exists" in again.stderr



@pytest.mark.slow
@pytest.mark.parametrize("lang", ["cpp", "python"])
def test_the_scaffolds_own_test_passes_without_an_activated_venv(tmp_path, lang):
    """Issue #26, item 6: the generated test finds sc-rt and cmake next to
    the interpreter that runs it (PATH without the venv), and asserts a
    law-independent property (to the end, finite, never SAFE) beside the PD's
    own check. Before, it called `sc-rt` and `cmake` from PATH."""
    proj = tmp_path / "mylaw"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "new-law", "my-law", "--lang", lang, "--out", str(proj)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(proj / "test_my_law.py")],
                       capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "2 passed" in r.stdout


def test_compare_table(plugins, tmp_path):
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "compare", "paper_fault_free", "--law", "pd",
                        "--law", _spec(plugins["qf"]), "--duration", "20", "--out", str(tmp_path)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    rows = json.loads((tmp_path / "compare.json").read_text())["rows"]
    assert [x["law"] for x in rows] == ["pd", "quaternion-feedback"]
    pd = simulate(load_scenario("paper_fault_free"), law="pd", engine="cpp", duration=20.0)
    assert rows[0]["max_abs_wheel_accel"] == pd.metrics["max_abs_wheel_accel"]
    assert rows[0]["bound_violation_fraction"] == float(np.mean(~np.all(pd["bound_ok"], axis=1)))
    assert "| pd |" in r.stdout and "| quaternion-feedback |" in r.stdout


def test_montecarlo_and_check_take_a_plugin(plugins, tmp_path):
    from sc_rt.scenario.keys import scenario_data

    # a Monte Carlo draw re-reads the scenario from its data: the law and its params survive
    scn, _ = _slew_scenario(plugins["qf"])
    again = scenario_from_data(scenario_data(scn), scn.path)
    assert (again.run.controller, again.controller.laws) == (scn.run.controller, scn.controller.laws)
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "montecarlo", "paper_fault_free", "--runs", "2",
                        "--law", _spec(plugins["version99"]), "--out", str(tmp_path / "mc")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "built against law interface version 99" in r.stderr, r.stderr
    assert not (tmp_path / "mc").exists()
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "check", "paper_fault_free", "--fast", "--law",
                        _spec(plugins["qf"])], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


@pytest.mark.slow
def test_the_docs_example_builds_and_runs(tmp_path):
    """docs/LAWS.md section 3 as written: its source and CMakeLists build
    against the installed package and the law runs (its PD is the formula)."""
    doc = (ROOT / "docs" / "LAWS.md").read_text()
    section = doc.split("## 3. Writing a plugin", 1)[1].split("## 4.", 1)[0]
    cpp = re.search(r"```cpp\n(.*?)```", section, re.S).group(1)
    cmake = re.search(r"```cmake\n(.*?)```", section, re.S).group(1)
    (tmp_path / "my_pd.cpp").write_text(cpp)
    (tmp_path / "CMakeLists.txt").write_text(cmake)
    _build(tmp_path, tmp_path / "build")
    lib = tmp_path / "build" / "libmy_pd.so"
    scn = load_scenario("paper_fault_free")
    cfg = scn.core_config(law=_spec(lib))
    cfg.law_params = [("kp", [0.1]), ("kd", [0.3])]
    ctl = _core.Controller(cfg)
    assert ctl.law_name == "my-pd"
    i = scn.initial
    m = _core.Measurement(0.0, i.sigma_BN, i.omega_BN_B, i.wheel_speed)
    ctl.reset(m)
    cmd = ctl.step(m)
    sig_BD = mrp_sub(i.sigma_BN, scn.guidance.sigma_d0)
    from refmath import R

    x2 = i.omega_BN_B - R(sig_BD) @ (scn.guidance.omega_bias + scn.guidance.omega_cos)
    p = scn.plant
    Bm = -np.linalg.inv(p.J0) @ p.Cbar @ np.diag(p.Jw)
    np.testing.assert_allclose(cmd.u_cmd, -np.linalg.pinv(Bm) @ (0.1 * sig_BD + 0.3 * x2), rtol=1e-12, atol=1e-15)


# --------------------------------------------------------------------------- #
# Every engine runs the law it names or refuses it (issue #25, case 1).


def test_unsampled_engine_refuses_a_plugin_instead_of_running_rft(plugins):
    """Before: the unsampled engine ran its written-out RFT for any law it
    did not know, labelled with the plugin's name (bitwise --law rft)."""
    scn = load_scenario("paper_faults")
    with pytest.raises(ValueError, match="unsampled engine writes out the built-in laws only"):
        simulate(scn, law=_spec(plugins["qf"]), engine="unsampled", duration=1.0)


def test_sim_unsampled_with_a_plugin_exits_2_in_one_line(plugins, tmp_path):
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", "paper_faults", "--engine", "unsampled",
                        "--law", _spec(plugins["qf"]), "--duration", "1", "--out", str(out)],
                       capture_output=True, text=True, env=_env())
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "--engine unsampled" in lines[0] and "cannot run plugin:" in lines[0], r.stderr
    assert not out.exists()


# --------------------------------------------------------------------------- #
# The controller under test dying is a failed run (issue #25, case 2).


def _assert_death_reported(r, out: Path, t_crash: float, rate: float, periods: int = 1) -> None:
    """``periods``: how many control periods before the crash the last
    answered state may be (lockstep: the one before; real time: an answer
    that came after its tick is not an answer, so a loaded machine can leave
    the last few states unanswered in time)."""
    assert r.returncode == 1, r.stderr + r.stdout
    lines = [ln for ln in r.stderr.splitlines() if "died" in ln]
    assert len(lines) == 1, r.stderr
    line = lines[0]
    assert "sc-rt-controller died (signal SIGSEGV)" in line, line
    m = re.search(r"at t = ([0-9.]+) s \(the last state it answered\)", line)
    assert m, line
    assert t_crash - periods / rate - 1e-6 <= float(m.group(1)) < t_crash, line
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["valid"] is False and metrics["partial"] is True
    assert "SIGSEGV" in metrics["invalid_reason"]


@pytest.mark.lcm
@pytest.mark.parametrize("mode", ["lockstep", pytest.param("realtime", marks=pytest.mark.slow)])
def test_hil_with_a_controller_that_segfaults_is_a_failed_run(plugins, tmp_path, mode):
    """Before: the watchdog held zero commands for the rest of the run, which
    ended with exit 0, "valid": true and 0 SAFE steps."""
    lcmnet.require()
    out = tmp_path / mode
    r = lcmnet.run_cli(["hil", "scenarios/paper_fault_free.toml", "--law", _spec(plugins["crashes"]), "--mode",
                        mode, "--duration", "20" if mode == "lockstep" else "8", "--out", str(out),
                        "--no-plots", "--floor", "off"])
    _assert_death_reported(r, out, 5.0, 10.0, periods=1 if mode == "lockstep" else 5)


# --------------------------------------------------------------------------- #
# A law failure outside step() is contained, counted, named and invalidates
# the run; nothing crashes (issue #25, case 3).


@pytest.mark.parametrize("engine", ["python", "cpp"])
def test_a_reset_that_throws_at_reengagement_is_contained_offline(plugins, engine):
    """Before: the exception left Controller::step (sim, compare, montecarlo:
    'error: reset exploded', exit 2, nothing written)."""
    scn = load_scenario("paper_fault_free")
    run = simulate(scn, law=_spec(plugins["throws_in"]), engine=engine, duration=10.0)
    assert len(run) == 101  # to its end
    f = run.metrics["law_failures"]
    assert f["step"] == 1 and f["reset"] >= 1 and f["after"] == 0  # the NaN step, then every re-engagement
    assert f["last"]["call"] == "reset" and "reset exploded at re-engagement" in f["last"]["what"]
    assert 2.1 - 1e-9 <= f["last"]["t"] <= 10.0
    t, mode = run["t"], run["ctrl_mode"]
    assert np.all(mode[t < 2.0 - 1e-9] == _core.MODE_NORMAL) and np.all(mode[t >= 2.0 - 1e-9] == _core.MODE_SAFE)
    assert run.metrics["valid"] is False and "reset" in run.metrics["invalid_reason"]


def test_after_that_throws_is_contained(plugins):
    c = load_scenario("paper_fault_free").core_config(law=_spec(plugins["throws_in"]))
    c.law_params = [("t_nan", [100.0]), ("t_after", [0.5]), ("reset_throws", [0.0])]
    ctl = _core.Controller(c)
    x = np.zeros(10)
    modes = [ctl.step(_core.Measurement(0.1 * k, x[0:3], x[3:6], x[6:10])).mode for k in range(10)]
    assert modes[5] == _core.MODE_SAFE and modes.count(_core.MODE_SAFE) == 1
    f = ctl.law_failures
    assert f["after"] == 1 and f["last"]["call"] == "after" and f["last"]["t"] == pytest.approx(0.5)


def test_sim_cli_with_a_failing_law_writes_its_outputs_and_exits_1(plugins, tmp_path):
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", "paper_fault_free", "--law",
                        _spec(plugins["throws_in"]), "--duration", "5", "--out", str(out), "--no-plots"],
                       capture_output=True, text=True, env=_env())
    assert r.returncode == 1, r.stdout + r.stderr
    line = [x for x in r.stderr.splitlines() if "INVALID" in x]
    assert len(line) == 1 and "reset" in line[0] and "t = " in line[0] and "reset exploded" in line[0]
    m = json.loads((out / "metrics.json").read_text())
    assert m["valid"] is False and m["law_failures"]["reset"] >= 1
    assert "law failures (contained)" in r.stdout


@pytest.mark.lcm
@pytest.mark.parametrize("mode", ["lockstep", pytest.param("realtime", marks=pytest.mark.slow)])
def test_hil_with_a_reset_that_throws_keeps_the_controller_alive(plugins, tmp_path, mode):
    """Before: std::terminate in sc-rt-controller (the exception crossed
    LCM's C dispatch) and a run reported valid."""
    lcmnet.require()
    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", "paper_fault_free", "--law", _spec(plugins["throws_in"]), "--mode", mode,
                        "--duration", "5", "--out", str(out), "--no-plots", "--floor", "off"])
    assert r.returncode == 1, r.stderr + r.stdout
    assert "died" not in r.stderr  # contained: the process lived to the end
    m = json.loads((out / "metrics.json").read_text())
    assert m["valid"] is False and m["law_failures"]["reset"] >= 1 and m["law_failures"]["last"]["call"] == "reset"
    summary = json.loads((out / "controller_summary.json").read_text())
    # the NaN second: one step in lockstep; real time may step on that state again (stale)
    assert summary["law_failures"]["step"] == 1 if mode == "lockstep" else summary["law_failures"]["step"] >= 1
    # one number of SAFE steps everywhere (issue #25, case 5): metrics.json is the controller's count
    timing = json.loads((out / "timing.json").read_text())
    assert m["safe_steps"] == timing["controller_safe_steps"] == summary["safe_steps"] > 0
    if mode == "lockstep":
        sim = simulate(load_scenario("paper_fault_free"), law=_spec(plugins["throws_in"]), engine="python",
                       duration=5.0)
        assert np.array_equal(load_traj(out)["ctrl_mode"], sim["ctrl_mode"])


def test_montecarlo_with_a_failing_law_finishes_and_counts_the_failures(plugins, tmp_path):
    out = tmp_path / "mc"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "montecarlo", "paper_fault_free", "--runs", "3",
                        "--workers", "1", "--law", _spec(plugins["throws_in"]), "--out", str(out)],
                       capture_output=True, text=True, env=_env(), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    s = json.loads((out / "montecarlo.json").read_text())
    assert s["runs"] == 3 and s["status"]["law_failed"] == 3 and s["holds_bound"] == 0
    assert all("reset exploded" in f["message"] for f in s["failed"])
    assert "the law failed" in r.stderr and "3 of 3 runs" in r.stderr


# --------------------------------------------------------------------------- #
# A plugin that crashes its process offline: one line, and one run of a
# campaign, not the campaign (issue #25, case 2 offline).


def test_sim_with_a_segfaulting_plugin_is_one_line_not_exit_139(plugins, tmp_path):
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", "paper_fault_free", "--law",
                        _spec(plugins["crashes"]), "--duration", "10", "--out", str(out), "--no-plots"],
                       capture_output=True, text=True, env=_env())
    assert r.returncode == 1, (r.returncode, r.stderr)  # before: 139 (SIGSEGV) and nothing said
    lines = [x for x in r.stderr.splitlines() if "FAILED" in x]
    assert len(lines) == 1 and "signal SIGSEGV" in lines[0] and "libt_crashes.so" in lines[0], r.stderr


def _crash_scenario(tmp_path: Path, lib: Path, omega_x_below: float) -> Path:
    src = (ROOT / "scenarios" / "paper_faults.toml").read_text()
    text = src.replace('controller = "dsc-ppc"', "") + (
        f"\n[controller.params]\nt_crash = 1e9\nomega_x_below = {omega_x_below!r}\n")
    text = text.replace("[controller]\n", f'[controller]\nlaw = "plugin:{lib}"\n', 1)
    f = tmp_path / "crash.toml"
    f.write_text(text)
    return f


def test_montecarlo_records_a_crashed_run_and_finishes_the_rest(plugins, tmp_path):
    """The crash is drawn: the law crashes its process at once when the
    dispersed initial body rate's x component is below a threshold, so some
    runs of the campaign crash and the others run to their end."""
    import pyarrow.parquet as pq

    n = 12
    f = _crash_scenario(tmp_path, plugins["crashes"], -0.0097)  # omega_x(0) = -0.01 rad/s, dispersed
    out = tmp_path / "mc"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "montecarlo", str(f), "--runs", str(n), "--workers", "2",
                        "--seed", "3", "--out", str(out)], capture_output=True, text=True, env=_env(), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    s = json.loads((out / "montecarlo.json").read_text())
    crashed = {x["run"] for x in s["failed"] if x["status"] == "crashed"}
    assert s["runs"] == n and s["status"]["crashed"] == len(crashed)
    assert 0 < len(crashed) < n, s["status"]  # some runs crashed, the campaign ran the rest
    assert all("signal SIGSEGV" in x["message"] for x in s["failed"] if x["status"] == "crashed")
    assert s["status"]["ok"] == n - len(crashed)
    assert f"crashed its run's process in {len(crashed)} of {n} runs" in r.stderr
    rows = pq.read_table(out / "runs").to_pylist()  # the dataset: every run's drawn initial rate
    assert crashed == {x["run"] for x in rows if x["initial.omega_BN_B[0]"] < -0.0097}


def test_a_plugin_that_crashes_when_probed_is_refused_in_one_line(plugins, tmp_path):
    """The probe at rest before a run (check_law) runs a plugin in a child:
    a crash there is a refusal (exit 2), not the CLI dying with SIGSEGV."""
    f = _crash_scenario(tmp_path, plugins["crashes"], 1.0)  # at rest omega_x = 0 < 1: crashes at once
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", str(f), "--out", str(out)],
                       capture_output=True, text=True, env=_env())
    assert r.returncode == 2, (r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "crashed the process when probed" in lines[0] and "SIGSEGV" in lines[0]
    assert not out.exists()


@pytest.mark.slow
def test_montecarlo_of_100_runs_where_some_draws_make_reset_throw(plugins, tmp_path):
    """Issue #25's acceptance: a campaign of 100 runs in which the law's
    reset throws on some draws completes; those runs are law_failed with
    the reason, exactly the draws the dataset says, and the rest are ok."""
    import pyarrow.parquet as pq

    src = (ROOT / "scenarios" / "paper_faults.toml").read_text()
    text = src.replace('controller = "dsc-ppc"', "") + (
        "\n[controller.params]\nreset_throws = 0.0\nt_nan = 1e9\nomega_x_below = -0.0118\n")
    f = tmp_path / "throws.toml"
    f.write_text(text.replace("[controller]\n", f'[controller]\nlaw = "plugin:{plugins["throws_in"]}"\n', 1))
    out = tmp_path / "mc"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "montecarlo", str(f), "--runs", "100", "--seed", "1",
                        "--out", str(out)], capture_output=True, text=True, env=_env(), cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr
    s = json.loads((out / "montecarlo.json").read_text())
    rows = pq.read_table(out / "runs").to_pylist()
    want = {x["run"] for x in rows if x["initial.omega_BN_B[0]"] < -0.0118}
    failed = {x["run"] for x in rows if x["status"] == "law_failed"}
    assert s["runs"] == 100 and 1 <= len(want) < 100 and failed == want, (len(want), s["status"])
    assert all("reset exploded on this draw" in x["message"] for x in rows if x["status"] == "law_failed")
    assert s["status"]["ok"] + s["status"]["law_failed"] == 100


def test_compare_with_a_failing_law_completes_and_says_which(plugins, tmp_path):
    out = tmp_path / "cmp"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "compare", "paper_fault_free", "--law", "pd", "--law",
                        _spec(plugins["throws_in"]), "--duration", "5", "--out", str(out)],
                       capture_output=True, text=True, env=_env())
    assert r.returncode == 1, r.stderr  # a law failed: the comparison is done, and says so
    rows = json.loads((out / "compare.json").read_text())["rows"]
    assert [x["law"] for x in rows] == ["pd", "t-throws-in"] and [x["valid"] for x in rows] == [True, False]
    assert "reset exploded" in rows[1]["invalid_reason"]
    assert "t-throws-in INVALID" in r.stderr and "| no |" in r.stdout
