"""Scenario files: the paper's two scenarios, the LCM config path, and the validator.

Expected values are typed in from docs/MODEL.md section 8 (the paper's section 4),
not read from the code, so a drift in the files or in the C++ defaults fails.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
from sc_rt_lcm import controller_config_t

from sc_rt import _core
from sc_rt.model.actuators import WheelFault
from sc_rt.scenario.model import LAWS, ControllerParams, Scenario, ScenarioError
from sc_rt.scenario.reader import load_scenario, with_run
from sc_rt.scenario.schema import key_lines

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
FAULT_FREE = SCENARIOS / "paper_fault_free.toml"
FAULTS = SCENARIOS / "paper_faults.toml"

CBAR = [
    [-0.9992, -0.0300, -0.0256, -0.6086],
    [-0.0394, 0.7455, 0.6653, 0.7913],
    [0.0009, -0.6658, 0.7461, 0.0469],
]
# Every field of controller_config_t for the paper's fault-free file
# (docs/MODEL.md section 8; pd, rft, safety, substeps: this project's values).
EXPECTED_MSG = {
    "scenario": "paper_fault_free",
    "law": "dsc-ppc",
    "law_api_version": 3,
    # [laws.dsc-ppc] of the file, in its order: the observer's, then the DSC gains (paper s4)
    "n_law_params": 13,
    "law_param_keys": ("neso_k1", "neso_k2", "neso_k3", "neso_k4", "neso_alpha", "neso_substeps",
                       "neso_init_from_measurement", "k1", "k2", "k3", "k4", "k6", "tau"),
    "law_param_len": [1.0] * 13,
    "n_law_param_values": 13,
    "law_param_values": [0.2, 0.03, 0.08, 0.06, 0.7, 1.0, 0.0, 0.1, 4.0, 0.01, 22.0, 1.0, 0.1],
    "control_rate_hz": 10.0,
    "J0": [[10, 0, 0], [0, 15, 0], [0, 0, 20]],
    "Cbar": CBAR,
    "Jw": [0.338] * 4,
    "umin": [-7.0] * 4,
    "umax": [10.0] * 4,
    "wheel_torque_command": False,  # the paper's wheels take an acceleration
    "wheel_speed_max": [0.0] * 4,   # no speed limit (0 on the wire)
    "w0": 0.0011,
    "guidance_kind": 0,  # GUIDANCE_PAPER: no kind key in the paper's files
    "sigma_d0": [0.217, -0.109, -0.163],
    "omega_d_bias": [0.0, 0.0, 0.0],
    "omega_d_cos": [0.02, 0.0, -0.03],
    "omega_d_sin": [0.0, -0.01, 0.0],
    "omega_d_freq": 0.01,
    "slew_target": [0.0, 0.0, 0.0],  # the slew's and the table's fields: unused, zero
    "slew_start": 0.0,
    "slew_duration": 0.0,
    "ref_n": 0,
    "ref_t": [],
    "ref_sigma": [],
    "ref_omega": [],
    "ppc_chi0": [0.11, 0.14, 0.2],
    "ppc_chiinf": [4e-6, 2e-6, 1.4e-6],
    "ppc_gamma": [0.12, 0.12, 0.08],
    "ppc_dmin": [0.7, 1.0, 1.0],
    "ppc_dmax": [1.0, 0.7, 0.3],
    "pinv_damping": 0.0,
    "max_rate": 10.0,
    "max_wheel_speed": 1e4,
    "stale_periods": 5.0,
    # no [sensors]: the estimator is off and its fields zero
    "nav_enabled": False, "nav_use_estimate": False, "nav_arw": 0.0, "nav_rrw": 0.0,
    "nav_bias_sigma": 0.0, "nav_bias_tau": 0.0, "nav_quantization": 0.0, "nav_sigma_cross": 0.0,
    "nav_sigma_boresight": 0.0, "nav_boresight": [0.0, 0.0, 0.0], "nav_initial_attitude_sigma": 0.0,
    "nav_initial_bias_sigma": 0.0, "nav_degraded_after": 0.0, "nav_history": 0, "nav_sigma0": [0.0, 0.0, 0.0],
    "nav_calibrate": False, "nav_initial_scale_factor_sigma": 0.0, "nav_initial_misalignment_sigma": 0.0,
    # magnetic control: none in this file, every field off and zero
    "mag_rods_enabled": False, "mag_n_rods": 0, "mag_G_B": [[0.0] * 6] * 3, "mag_dipole_max": [0.0] * 6,
    "mag_momentum_enabled": False, "mag_unload_kind": 0, "mag_gain": 0.0, "mag_hysteresis": False,
    "mag_on_fraction": 0.0, "mag_off_fraction": 0.0, "mag_capacity": 0.0, "mag_null_gain": 0.0,
    "mag_null_bias": 0.0, "bdot_enabled": False, "bdot_gain": 0.0, "bdot_normalized": False,
    "bdot_derivative": 0, "bdot_filter_tau": 0.0, "bdot_rate_on": 0.0, "bdot_rate_off": 0.0,
    # no magnetometer (no [sensors]): off and zero
    "nav_mag_enabled": False, "nav_mag_R_SB": [[0.0] * 3] * 3,
}


def assert_msg_equals(msg: controller_config_t, expected: dict) -> None:
    for name, value in expected.items():
        got = getattr(msg, name)
        if isinstance(value, tuple):  # strings
            assert list(got) == list(value), name
        elif isinstance(value, (list, float)):
            np.testing.assert_array_equal(np.array(got, dtype=float), np.array(value, dtype=float),
                                          err_msg=name)  # fmt: skip
        else:
            assert got == value, name


def assert_same(a, b, path: str = "") -> None:
    """Field-by-field equality of nested dataclasses holding numpy arrays."""
    if dataclasses.is_dataclass(a):
        assert type(a) is type(b), path
        for f in dataclasses.fields(a):
            assert_same(getattr(a, f.name), getattr(b, f.name), f"{path}.{f.name}")
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b, err_msg=path)
    elif isinstance(a, tuple):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{path}[{i}]")
    else:
        assert a == b, path


# --------------------------------------------------------------------------- #
# The paper's scenarios


@pytest.mark.parametrize("path", [FAULT_FREE, FAULTS], ids=["fault_free", "faults"])
def test_paper_scenarios_hold_model_md_values(path):
    s = load_scenario(path)
    assert s.name == path.stem and s.path == path and "Huang & Duan" in s.description
    assert (s.run.duration, s.run.control_rate_hz, s.run.plant_step, s.run.controller) == (
        300.0, 10.0, 0.1, "dsc-ppc")  # fmt: skip
    assert s.run.plant_substeps == 1
    p = s.plant
    np.testing.assert_array_equal(p.J0, np.diag([10.0, 15.0, 20.0]))
    np.testing.assert_array_equal(p.dJ, np.diag([2.0, -1.0, 2.0]))
    np.testing.assert_array_equal(p.J, np.diag([12.0, 14.0, 22.0]))
    np.testing.assert_array_equal(p.Cbar, CBAR)
    np.testing.assert_array_equal(p.Jw, [0.338] * 4)
    assert p.w0 == 0.0011
    np.testing.assert_array_equal(p.disturbance.amp, [5e-3, -5e-3, 6e-3])
    np.testing.assert_array_equal(p.disturbance.freq, [0.02, 0.025, 0.04])
    np.testing.assert_array_equal(p.disturbance.bias, [0.0, 0.0, 0.0])
    a = s.actuators
    np.testing.assert_array_equal(a.umin, [-7.0] * 4)
    np.testing.assert_array_equal(a.umax, [10.0] * 4)
    assert np.all(np.isinf(a.max_wheel_speed))
    np.testing.assert_array_equal(s.initial.sigma_BN, [0.323, -0.194, -0.388])
    np.testing.assert_array_equal(s.initial.omega_BN_B, [-0.01, 0.02, -0.03])
    np.testing.assert_array_equal(s.initial.wheel_speed, [0.0] * 4)
    g = s.guidance
    np.testing.assert_array_equal(g.sigma_d0, [0.217, -0.109, -0.163])
    # omega_d(t) = [0.02 cos(t/100), -0.01 sin(t/100), -0.03 cos(t/100)]
    t = 123.4
    w = g.omega_freq * t
    omega_d = g.omega_bias + g.omega_cos * np.cos(w) + g.omega_sin * np.sin(w)
    np.testing.assert_allclose(omega_d, [0.02 * np.cos(t / 100), -0.01 * np.sin(t / 100),
                                         -0.03 * np.cos(t / 100)], rtol=0, atol=1e-15)  # fmt: skip
    c = s.controller
    np.testing.assert_array_equal(c.ppc.chi0, [0.11, 0.14, 0.2])
    np.testing.assert_array_equal(c.ppc.chiinf, [4e-6, 2e-6, 1.4e-6])
    np.testing.assert_array_equal(c.ppc.gamma, [0.12, 0.12, 0.08])
    np.testing.assert_array_equal(c.ppc.dmin, [0.7, 1.0, 1.0])
    np.testing.assert_array_equal(c.ppc.dmax, [1.0, 0.7, 0.3])
    assert [law for law, _ in c.laws] == ["dsc-ppc"]  # the table of the law the file runs, only
    d = c.resolved("dsc-ppc")
    for k, v in (("neso_k1", 0.2), ("neso_k2", 0.03), ("neso_k3", 0.08), ("neso_k4", 0.06)):
        np.testing.assert_array_equal(np.broadcast_to(d[k], 3), [v] * 3)
    assert (d["neso_alpha"], d["neso_substeps"], d["neso_init_from_measurement"]) == (0.7, 1.0, 0.0)
    assert tuple(d[k] for k in ("k1", "k2", "k3", "k4", "k6", "tau")) == (0.1, 4.0, 0.01, 22.0, 1.0, 0.1)
    # the other laws run their own defaults: the PD's design (docs/DESIGN.md), this project's RFT
    assert (c.resolved("pd")["beta1"], c.resolved("pd")["beta2"]) == (0.05693, 0.2386)
    assert tuple(c.resolved("rft")[k] for k in ("c", "k", "gain", "leak", "phi", "rho0")) == (
        0.2, 0.4, 0.5, 0.01, 1e-2, 0.0)
    assert dataclasses.astuple(c.safety) == (10.0, 1e4, 5.0)
    assert c.pinv_damping == 0.0


def test_paper_faults_follow_section_4_2_with_erratum_2():
    assert load_scenario(FAULT_FREE).actuators.faults == ()
    assert load_scenario(FAULTS).actuators.faults == (
        WheelFault(wheel=0, effectiveness=0.5, bias=0.3, onset=5.0, end=None, rate=1.0),
        WheelFault(wheel=1, effectiveness=0.5, bias=0.0, onset=10.0, end=None, rate=1.0),
        WheelFault(wheel=2, effectiveness=1.0, bias=-0.3, onset=5.0, end=15.0, rate=1.0),
    )  # RW4 healthy


def test_the_two_paper_files_differ_only_in_faults():
    a, b = load_scenario(FAULT_FREE), load_scenario(FAULTS)
    assert b.actuators.faults
    b = dataclasses.replace(b, name=a.name, description=a.description, path=a.path,
                            actuators=dataclasses.replace(b.actuators, faults=()))  # fmt: skip
    assert_same(a, b)


def test_every_value_of_the_paper_files_carries_a_comment():
    # On its own line, or on the comment line just above it (the matrices).
    for path in (FAULT_FREE, FAULTS):
        lines = path.read_text().splitlines()
        for n, line in enumerate(lines, 1):
            if re.match(r"\s*\w+\s*=", line) and not line.startswith(("name", "description")):
                assert "#" in line or lines[n - 2].startswith("#"), f"{path.name}:{n}: {line}"


def test_defaults_are_the_paper_controller(write):
    # A file without any [controller] table gets the paper's controller.
    # The paper's file gives its law's table with the paper's values: the law's own defaults.
    text = FAULT_FREE.read_text()
    bare, full = load_scenario(write(text[: text.index("[controller]")], "bare")), load_scenario(FAULT_FREE)
    assert bare.controller.laws == ()
    for law in LAWS:  # a number for all three axes is the same as three equal ones
        a, b = bare.controller.resolved(law), full.controller.resolved(law)
        assert a.keys() == b.keys()
        for k in a:
            shape = np.broadcast_shapes(np.shape(a[k]), np.shape(b[k]))
            np.testing.assert_array_equal(np.broadcast_to(a[k], shape), np.broadcast_to(b[k], shape), err_msg=k)
    assert_same(ControllerParams().ppc, full.controller.ppc)
    assert_same(ControllerParams().safety, full.controller.safety)


def test_controller_config_msg_fills_every_field():
    msg = load_scenario(FAULT_FREE).controller_config_msg()
    assert set(EXPECTED_MSG) | {"utime"} == set(controller_config_t.__slots__)
    assert msg.utime > 1_600_000_000_000_000  # [us] wall clock at encoding
    assert_msg_equals(msg, EXPECTED_MSG)


def test_controller_config_round_trips_through_the_cpp_decoder():
    s = load_scenario(FAULT_FREE)
    msg = s.controller_config_msg()
    cfg = _core.ControllerConfig.from_lcm_bytes(msg.encode())
    assert _core.validate(cfg) == []
    # Back out through the C++ encoder: every field as the scenario gave it.
    back = controller_config_t.decode(cfg.to_lcm_bytes(s.name))
    assert_msg_equals(back, EXPECTED_MSG)
    # And a few fields read directly from the C++ structs.
    np.testing.assert_array_equal(cfg.spacecraft.Cbar, CBAR)
    np.testing.assert_array_equal(cfg.ppc.chiinf, [4e-6, 2e-6, 1.4e-6])
    assert (dict(cfg.law_params)["k4"], dict(cfg.law_params)["neso_alpha"], cfg.guidance.omega_freq) == (
        [22.0], [0.7], 0.01)
    assert cfg.law == "dsc-ppc"


@pytest.mark.parametrize("law", list(LAWS))
def test_core_config_builds_a_working_controller(law):
    s = load_scenario(FAULTS)
    cfg = s.core_config(law, 20.0)
    assert cfg.law == law and cfg.control_rate_hz == 20.0
    ctl = _core.Controller(cfg)
    i = s.initial
    for k in range(3):
        cmd = ctl.step(_core.Measurement(0.05 * k, i.sigma_BN, i.omega_BN_B, i.wheel_speed))
        assert cmd.mode == _core.MODE_NORMAL
        assert np.all(np.isfinite(cmd.u_cmd))
        assert np.all(cmd.u_sat >= -7.0) and np.all(cmd.u_sat <= 10.0)
    np.testing.assert_allclose(
        cmd.sigma_BD, _core.mrp_subtract(i.sigma_BN, cmd.sigma_DN), rtol=0, atol=1e-15
    )


def test_law_table_matches_the_wire_and_the_core():
    # The table is the core's registry: the four built-ins in their order
    # (their codes are controller_status_t.law).
    assert LAWS == {"dsc-ppc": 0, "dsc": 1, "pd": 2, "rft": 3}
    assert _core.law_names()[:4] == list(LAWS)
    for name, code in LAWS.items():
        info = _core.law_info(name)
        assert {k: info[k] for k in ("name", "source", "code")} == {"name": name, "source": "built-in",
                                                                   "code": code}
        assert info["defaults"]  # each built-in declares its parameters and their defaults


def test_msg_overrides_and_their_errors():
    s = load_scenario(FAULT_FREE)
    msg = s.controller_config_msg(law="rft", control_rate_hz=50.0)
    assert (msg.law, msg.control_rate_hz) == ("rft", 50.0)
    with pytest.raises(ValueError, match='controller must be one of "dsc-ppc"'):
        s.controller_config_msg(law="lqr")
    with pytest.raises(ValueError, match="control_rate_hz must be > 0"):
        s.core_config(control_rate_hz=0.0)


def test_with_run_overrides():
    s = load_scenario(FAULTS)
    r = with_run(s, controller="pd", control_rate_hz=5, duration=None)
    assert (r.run.controller, r.run.control_rate_hz, r.run.duration) == ("pd", 5.0, 300.0)
    assert r.run.plant_substeps == 2
    assert r.core_config().law == "pd"
    assert s.run.controller == "dsc-ppc"  # the original is unchanged
    assert r.actuators is s.actuators and r.controller is s.controller
    with pytest.raises(ScenarioError) as e:
        with_run(s, control_rate_hz=3.0, duration=-1.0, dt=0.2)  # three problems
    assert {(x.key, x.line) for x in e.value.errors} == {
        ("run.duration", 0), ("run.plant_step", 0), ("run.dt", 0)}  # fmt: skip
    text = str(e.value)
    assert "paper_faults.toml (override): run.duration = -1.0: duration must be > 0" in text
    assert "integer multiple of plant_step (it is 3.33333 steps)" in text


def test_scenario_is_frozen():
    s = load_scenario(FAULT_FREE)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.run = None
    with pytest.raises(ValueError, match="read-only"):
        s.controller.ppc.chi0[0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        s.initial.sigma_BN[0] = 1.0


# --------------------------------------------------------------------------- #
# Optional forms


@pytest.fixture
def write(tmp_path):
    """write(text, name="x") -> path of a scenario file holding text."""

    def _write(text: str, name: str = "x") -> Path:
        path = tmp_path / f"{name}.toml"
        path.write_text(text)
        return path

    return _write


def edit(text: str, old: str, new: str) -> str:
    assert text.count(old) == 1, f"{old!r} occurs {text.count(old)} times"
    return text.replace(old, new)


def test_scalars_broadcast_and_optional_keys_default(write):
    text = FAULTS.read_text()
    text = edit(text, "neso_k1 = 0.2 ", "neso_k1 = [0.1, 0.2, 0.3] ")
    text = edit(text, "Jw = 0.338", "Jw = [0.3, 0.31, 0.32, 0.33]")
    text = edit(text, "bias = [0.0, 0.0, 0.0]      # [N m] none in the paper\n", "")
    text = edit(text, "w0 = 0.0011", "max_wheel_speed = 600.0\nw0 = 0.0011")
    text = edit(text, "effectiveness = 1.0  # [-] \"without power off\"; paper s4.2\n", "")
    text = edit(text, "rate = 1.0           # [1/s] a_3 = 1; paper s4.2\n", "")
    text += "\n[[faults]]\nwheel = 4\nonset = 20.0\nstuck = true\n"
    s = load_scenario(write(text))
    np.testing.assert_array_equal(s.controller.resolved("dsc-ppc")["neso_k1"], [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(s.plant.Jw, [0.3, 0.31, 0.32, 0.33])
    np.testing.assert_array_equal(s.plant.disturbance.bias, [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(s.actuators.max_wheel_speed, [600.0] * 4)
    assert s.actuators.faults[2] == WheelFault(wheel=2, effectiveness=1.0, bias=-0.3, onset=5.0,
                                               end=15.0, rate=1.0)  # fmt: skip
    assert s.actuators.faults[3] == WheelFault(wheel=3, onset=20.0, stuck=True)
    cfg = s.core_config()
    assert dict(cfg.law_params)["neso_k1"] == [0.1, 0.2, 0.3]
    np.testing.assert_array_equal(cfg.spacecraft.Jw, [0.3, 0.31, 0.32, 0.33])


CAPTURE = """
[spacecraft.capture]
frame = "service"              # axes of the combined frame: the service's

[spacecraft.capture.service]
mass = 400.0                   # [kg]
inertia = [[8.0, 0.0, 0.0], [0.0, 9.0, 0.0], [0.0, 0.0, 10.0]]   # [kg m^2] about O_s, in S
C = [[1.0, 0.0, 0.0, 0.5773502691896258],
     [0.0, 1.0, 0.0, 0.5773502691896258],
     [0.0, 0.0, 1.0, 0.5773502691896258]]

[spacecraft.capture.target]
mass = 100.0                   # [kg]
inertia = [[2.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 4.0]]   # [kg m^2] about O_t, in T
position = [0.5, 0.0, 0.0]     # [m] O_t from O_s, in S
attitude = [0.0, 0.0, 0.41421356237309503]   # [-] MRP sigma_TS: +90 deg about z
"""


def capture_text(extra: str = CAPTURE) -> str:
    text = FAULT_FREE.read_text()
    text = edit(text, "J0 = [[10.0, 0.0, 0.0], [0.0, 15.0, 0.0], [0.0, 0.0, 20.0]]\n", "")
    start = text.index("Cbar = [")
    text = text[:start] + text[text.index("\n]\n", start) + 3 :]
    return edit(text, "\n[disturbance]", extra + "\n[disturbance]")


def test_capture_table_builds_j0_and_cbar(write):
    s = load_scenario(write(capture_text()))
    # r_c = 100 * 0.5 / 500 = 0.1 m on x. Service: diag(8, 9, 10) + 400 * 0.1^2 on y, z.
    # Target, turned 90 deg about z: diag(3, 2, 4) in S, + 100 * 0.4^2 on y, z.
    np.testing.assert_allclose(s.plant.J0, np.diag([8 + 3, 13 + 18, 14 + 20]), rtol=0, atol=1e-12)
    s3 = 1 / np.sqrt(3)
    C = [[1, 0, 0, s3], [0, 1, 0, s3], [0, 0, 1, s3]]
    np.testing.assert_allclose(s.plant.Cbar, C, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(s.core_config().spacecraft.J0, s.plant.J0)
    principal = load_scenario(write(capture_text(edit(CAPTURE, '"service"', '"principal"'))))
    np.testing.assert_allclose(principal.plant.J0, np.diag([11.0, 31.0, 34.0]), atol=1e-12)


# --------------------------------------------------------------------------- #
# Broken files: one edit of the paper file each; the expected line is the
# first line of the edited file that contains `anchor`.

BROKEN = [
    # id, old, new, key, message fragment, anchor, number of errors
    ("unknown key", "duration = 300.0", "durration = 300.0",
     "run.durration", "unknown key (did you mean 'duration'?)", "durration", 2),
    ("missing key", "Jw = 0.338    # [kg m^2] spin inertia of each wheel; paper s4\n", "",
     "spacecraft.Jw", "required key is missing", "[spacecraft]", 1),
    ("missing J0", "J0 = [[10.0, 0.0, 0.0], [0.0, 15.0, 0.0], [0.0, 0.0, 20.0]]\n", "",
     "spacecraft.J0", "missing (or give a [spacecraft.capture] table)", "[spacecraft]", 1),
    ("unknown table", "[controller.safety]", "[controller.safty]",
     "controller.safty", "unknown table (did you mean 'safety'?)", "[controller.safty]", 1),
    ("string for number", "w0 = 0.0011", 'w0 = "0.0011"',
     "spacecraft.w0", "w0 must be a number", "w0 =", 1),
    ("float for int", "neso_substeps = 1 ", "neso_substeps = 2.5 ",
     "laws.dsc-ppc.neso_substeps", "must be an integer in [1, 10000], got 2.5", "neso_substeps =", 1),
    ("int for bool", "neso_init_from_measurement = false", "neso_init_from_measurement = 2",
     "laws.dsc-ppc.neso_init_from_measurement", "must be 0 or 1 (false or true), got 2",
     "neso_init_from_measurement", 1),
    ("unknown law parameter", "tau = 0.1 ", "taux = 0.1 ",
     "laws.dsc-ppc.taux", "unknown parameter", "taux =", 1),
    ("vector length", "sigma_BN = [0.323, -0.194, -0.388]", "sigma_BN = [0.323, -0.194]",
     "initial.sigma_BN", "sigma_BN must be a list of 3 numbers", "sigma_BN", 1),
    ("matrix shape", "  [ 0.0009, -0.6658,  0.7461,  0.0469],\n", "",
     "spacecraft.Cbar", "Cbar must be a 3x4 array", "Cbar = [", 1),
    ("nan", "w0 = 0.0011", "w0 = nan",
     "spacecraft.w0", "w0 must be finite", "w0 =", 1),
    ("inf in a vector", "omega_BN_B = [-0.01, 0.02, -0.03]", "omega_BN_B = [-0.01, inf, -0.03]",
     "initial.omega_BN_B", "omega_BN_B must be finite", "omega_BN_B", 1),
    ("J0 not positive definite", "J0 = [[10.0, 0.0, 0.0]", "J0 = [[-10.0, 0.0, 0.0]",
     "spacecraft.J0", "J0 must be positive definite (eigenvalues [-10.0, 15.0, 20.0])", "J0 =", 1),
    ("J0 + dJ not positive definite", "[0.0, -1.0, 0.0]", "[0.0, -16.0, 0.0]",
     "spacecraft.dJ", "the true inertia J0 + dJ", "dJ = [[", 1),
    ("asymmetric J0", "J0 = [[10.0, 0.0, 0.0]", "J0 = [[10.0, 0.5, 0.0]",
     "spacecraft.J0", "J0 must be symmetric", "J0 =", 1),
    ("asymmetric dJ", "dJ = [[2.0, 0.0, 0.0]", "dJ = [[2.0, 0.5, 0.0]",
     "spacecraft.dJ", "dJ must be symmetric", "dJ = [[", 1),
    ("not a rigid body", "[0.0, 0.0, 20.0]]", "[0.0, 0.0, 30.0]]",
     "spacecraft.J0", "triangle inequality I1 + I2 >= I3", "J0 =", 1),
    ("umin >= umax", "umin = -7.0 ", "umin = [10, 10, 10, 10] ",
     "spacecraft.umin", "umin must be < umax = 10.0 for every wheel (not for wheel 1, 2, 3, 4)",
     "umin =", 1),
    ("Jw not positive", "Jw = 0.338 ", "Jw = [0.338, 0.338, 0.0, 0.338] ",
     "spacecraft.Jw", "Jw must have every element > 0", "Jw =", 1),
    ("Cbar column not unit", "[-0.0394,  0.7455,", "[-0.5394,  0.7455,",
     "spacecraft.Cbar", "columns must be unit spin axes", "Cbar = [", 1),
    ("sigma in degrees", "sigma_BN = [0.323, -0.194, -0.388]", "sigma_BN = [30.0, -20.0, 10.0]",
     "initial.sigma_BN", "must be an MRP with norm <= 1, got norm 37.42 (MRP, not degrees?)",
     "sigma_BN", 1),
    ("sigma_d0 > 1", "sigma_d0 = [0.217, -0.109, -0.163]", "sigma_d0 = [1.0, 0.5, 0.0]",
     "guidance.sigma_d0", "got norm 1.118", "sigma_d0", 1),
    ("negative duration", "duration = 300.0", "duration = -300.0",
     "run.duration", "duration must be > 0", "duration =", 1),
    ("plant step", "plant_step = 0.1 ", "plant_step = 0.03 ",
     "run.plant_step", "must be an integer multiple of plant_step (it is 3.33333 steps)",
     "plant_step =", 1),
    ("plant step longer than the period", "plant_step = 0.1 ", "plant_step = 0.2 ",
     "run.plant_step", "integer multiple of plant_step (it is 0.5 steps)", "plant_step =", 1),
    ("unknown law", 'controller = "dsc-ppc"', 'controller = "DSC+PPC"',
     "run.controller", 'controller must be one of "dsc-ppc", "dsc", "pd", "rft"',
     "controller =", 1),
    ("chi0 < chiinf", "chi0 = [0.11, 0.14, 0.2]", "chi0 = [0.11, 1e-6, 0.2]",
     "controller.ppc.chi0", "chi0 must be >= chiinf = [4e-06, 2e-06, 1.4e-06]", "chi0 =", 1),
    ("alpha", "neso_alpha = 0.7", "neso_alpha = 0.4",
     "laws.dsc-ppc.neso_alpha", "must be in [0.5, 1], got 0.4", "neso_alpha =", 1),
    ("neso gain", "neso_k3 = 0.08", "neso_k3 = -0.08",
     "laws.dsc-ppc.neso_k3", "must be > 0 on every axis", "neso_k3 = -0.08", 1),
    ("dsc tau", "tau = 0.1 ", "tau = 0.0 ",
     "laws.dsc-ppc.tau", "must be > 0, got 0", "tau =", 1),
    ("fault wheel", "wheel = 3 ", "wheel = 0 ",
     "faults[2].wheel", "wheel must be in [1, 4]", "wheel = 0", 1),
    ("duplicate wheel", "wheel = 3 ", "wheel = 1 ",
     "faults[2].wheel", "wheel 1 already has a fault (faults[0]): one fault per wheel",
     "wheel = 1            # RW3", 1),
    ("effectiveness", 'effectiveness = 0.5  # [-] "50%', 'effectiveness = 1.5  # [-] "50%',
     "faults[1].effectiveness", "effectiveness must be in [0, 1]", "effectiveness = 1.5", 1),
    ("fault end before onset", "end = 15.0", "end = 5.0",
     "faults[2].end", "end must be > onset (5 s)", "end = 5.0", 1),
    ("fault without onset", "onset = 10.0 ", "",
     "faults[1].onset", "required key is missing", "[[faults]]\nwheel = 2", 1),
    ("stuck with a bias", "end = 15.0", "end = 15.0\nstuck = true",
     "faults[2].stuck", "a stuck wheel ignores effectiveness, bias", "stuck =", 1),
    ("initial wheel speed over the limit", "wheel_speed = [0.0, 0.0, 0.0, 0.0]",
     "wheel_speed = [0.0, 700.0, 0.0, 0.0]",
     "initial.wheel_speed", "must be <= spacecraft.max_wheel_speed = [600.0, 600.0, 600.0, 600.0]",
     "wheel_speed = [0.0, 700.0", 1),
]  # fmt: skip


def line_of(text: str, anchor: str) -> int:
    return text.count("\n", 0, text.index(anchor)) + 1


@pytest.mark.parametrize("case", BROKEN, ids=[c[0] for c in BROKEN])
def test_broken_file_is_reported_with_file_line_key_and_value(case, write):
    _, old, new, key, fragment, anchor, count = case
    base = FAULTS.read_text()
    if "max_wheel_speed" in fragment:
        base = edit(base, "w0 = 0.0011", "max_wheel_speed = 600.0\nw0 = 0.0011")
    text = edit(base, old, new)
    path = write(text)
    with pytest.raises(ScenarioError) as e:
        load_scenario(path)
    err = e.value
    assert isinstance(err, ValueError) and err.path == str(path)
    assert len(err.errors) == count, str(err)
    [hit] = [x for x in err.errors if x.key == key]
    assert fragment in hit.message, str(err)
    assert hit.line == line_of(text, anchor), str(err)
    # The message names the file, the line, the key and the value as read
    # from the file (none for a missing key).
    value = value_at(tomllib.loads(text), key)
    assert hit.value == value or (math.isnan(value) and math.isnan(hit.value))
    shown = f"{path}:{hit.line}: {key}" + ("" if value is None else " = ")
    assert shown in str(err)


def value_at(data: dict, key: str):
    """The value at a dotted key such as faults[2].wheel, None if absent."""
    for part in key.split("."):
        name, _, index = part.partition("[")
        data = data.get(name) if isinstance(data, dict) else None
        if index and data is not None:
            data = data[int(index[:-1])]
    return data


def test_umin_message_reads_as_documented(write):
    text = edit(FAULTS.read_text(), "umin = -7.0 ", "umin = [10, 10, 10, 10] ")
    path = write(text)
    with pytest.raises(ScenarioError) as e:
        load_scenario(path)
    line = line_of(text, "umin =")
    assert str(e.value) == (
        f"{path}:{line}: spacecraft.umin = [10, 10, 10, 10]: "
        "umin must be < umax = 10.0 for every wheel (not for wheel 1, 2, 3, 4)"
    )
    [issue] = e.value.errors
    assert issue[:3] == (line, "spacecraft.umin", [10, 10, 10, 10])


def test_toml_syntax_error_names_the_line(write):
    text = edit(FAULTS.read_text(), "k4 = 22.0", "k4 = 22.0.0")
    path = write(text)
    with pytest.raises(ScenarioError, match="TOML syntax error") as e:
        load_scenario(path)
    [issue] = e.value.errors
    assert issue.line == line_of(text, "k4 = 22.0.0")
    assert str(e.value).startswith(f"{path}:{issue.line}: TOML syntax error: ")


def test_all_errors_of_a_file_are_reported_together(write):
    text = FAULTS.read_text()
    text = edit(text, "neso_alpha = 0.7", "neso_alpha = 2.0")
    text = edit(text, "umax = 10.0", "umax = -10.0")
    text = edit(text, "onset = 10.0 ", "onset = -1.0 ")
    path = write(text)
    with pytest.raises(ScenarioError) as e:
        load_scenario(path)
    lines = str(e.value).splitlines()
    assert len(lines) == len(e.value.errors) == 3
    expected = [("spacecraft.umin", "umin ="), ("laws.dsc-ppc.neso_alpha", "neso_alpha = 2.0"),
                ("faults[1].onset", "onset = -1.0")]  # in line order  # fmt: skip
    for line, err, (key, anchor) in zip(lines, e.value.errors, expected):
        assert err.key == key and err.line == line_of(text, anchor)
        assert line.startswith(f"{path}:{err.line}: {key} = ")


def test_missing_table_and_unreadable_file(write, tmp_path):
    text = edit(FAULTS.read_text(), "[initial]", "[initial_state]")
    with pytest.raises(ScenarioError) as e:
        load_scenario(write(text))
    assert [(x.key, x.message) for x in e.value.errors] == [
        ("initial", "required table is missing"),
        ("initial_state", "unknown table (did you mean 'initial'?)"),
    ]
    assert e.value.errors[0].line == 0
    assert e.value.errors[1].line == line_of(text, "[initial_state]")
    with pytest.raises(ScenarioError, match="cannot read the file"):
        load_scenario(tmp_path / "nope.toml")


def test_a_scenario_error_pickles_whole(write):
    """A pool worker's or a child's ScenarioError reaches the parent as it
    was (it did not unpickle: a worker's broke the process pool)."""
    import pickle

    with pytest.raises(ScenarioError) as e:
        load_scenario(write(edit(FAULTS.read_text(), "[initial]", "[initial_state]")))
    back = pickle.loads(pickle.dumps(e.value))
    assert type(back) is ScenarioError and str(back) == str(e.value)
    assert (back.path, back.errors) == (e.value.path, e.value.errors)


def test_capture_errors_are_located(write):
    capture = edit(CAPTURE, "mass = 100.0", "mass = -1.0")
    capture = edit(capture, "attitude = [0.0, 0.0, 0.414", "attitude = [0.0, 0.0, 3.0]  # 0.414")
    text = capture_text(capture)
    text = edit(text, "[spacecraft]\n", "[spacecraft]\nCbar = 1.0\n")
    with pytest.raises(ScenarioError) as e:
        load_scenario(write(text))
    got = {(x.key, x.line) for x in e.value.errors}
    assert got == {
        ("spacecraft.Cbar", line_of(text, "Cbar = 1.0")),
        ("spacecraft.capture.target.mass", line_of(text, "mass = -1.0")),
        ("spacecraft.capture.target.attitude", line_of(text, "attitude = [0.0, 0.0, 3.0]")),
    }
    assert "give either Cbar or [spacecraft.capture], not both" in str(e.value)


def test_key_locator():
    text = """\
# [not.a.table] in a comment
top = 1
[a]
x = [1,   # a [bracket] in a comment
  2]
"q.z" = "]"
b.c = 2
[a.sub]
y = '''
z = 3
'''
w = 4
[[f]]
k = 1
[[f]]
k = 2
"""
    assert key_lines(text) == {
        "top": 2, "a": 3, "a.x": 4, "a.q.z": 6, "a.b.c": 7, "a.sub": 8, "a.sub.y": 9,
        "a.sub.w": 12, "f[0]": 13, "f[0].k": 14, "f[1]": 15, "f[1].k": 16,
    }  # fmt: skip


def test_scenario_type_has_the_documented_fields():
    assert [f.name for f in dataclasses.fields(Scenario)] == [
        "name", "description", "path", "run", "plant", "actuators", "initial", "guidance",
        "controller", "montecarlo", "sensors", "expect", "requirements", "record", "deprecations", "overrides",
        "field_model", "magnetic_control",
        "law_key", "law_keys",
    ]  # fmt: skip
