"""What a law commands (issue 39, item 3): a law declares wheel accelerations
[rad/s^2] (the default) or motor torques [N m]; on wheels that take the other
the controller converts exactly as the drive does (torque = Jw a, a = torque
/ Jw) before saturation, on every engine and on the bus; ``sc-rt check`` says
which.

Each law below puts its own u_cmd in its telemetry, so the test reads the
law's output from the record and computes the wheels' command from it and the
scenario's Jw independently of the controller.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.pylaw import register
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate

import lcmnet
from trajcmp import compared_fields, load_traj

ROOT = Path(__file__).resolve().parent.parent
FLIGHT = ROOT / "scenarios" / "flight_wheels.toml"
JW = 0.0796  # [kg m^2] flight_wheels' HR16 (its [spacecraft] Jw)
U_MAX = 0.2  # [N m] the HR16's torque limit: the torque copy's umax


def torque_flight(tmp_path: Path, law: str = "dsc") -> Path:
    """flight_wheels on wheels that take motor torques, its command limits in N m,
    run by ``law`` (the file's own law, a built-in, by default)."""
    text = FLIGHT.read_text()
    for old, new in (('controller = "dsc"', f"controller = {json.dumps(law)}"),
                     ('command = "acceleration"', 'command = "torque"'),
                     ("umin = -2.51  # [rad/s^2]", f"umin = -{U_MAX}  # [N m]"),
                     ("umax = 2.51   # [rad/s^2]", f"umax = {U_MAX}   # [N m]")):
        assert old in text, old
        text = text.replace(old, new, 1)
    path = tmp_path / "flight_torque.toml"
    path.write_text(text)
    return path


class AccelPD:
    """A PD commanding wheel accelerations (declares nothing)."""

    telemetry_names = ("u1", "u2", "u3", "u4")

    def __init__(self, setup):
        self.model = setup.model

    def reset(self, inp):
        pass

    def accel(self, inp):
        # tau = -kp sigma_BD - kd omega_BD_B [N m]; a = B+ J0^-1 tau [rad/s^2]
        return np.asarray(self.model.wheels_for_torque(-0.5 * inp.e.sigma_BD - 5.0 * inp.e.omega_BD_B))

    def step(self, inp):
        u = self.accel(inp)
        return u, dict(zip(self.telemetry_names, u))


class TorquePD(AccelPD):
    """The same PD commanding motor torques Jw a [N m]."""

    command = "torque"

    def step(self, inp):
        u = np.asarray(self.model.Jw) * self.accel(inp)
        return u, dict(zip(self.telemetry_names, u))


def _law_output(run) -> np.ndarray:
    """The law's own u_cmd, row by row (its telemetry's first four columns)."""
    return np.asarray(run["telemetry"], float)[:, :4]


def _assert_converted(run, to_wheels) -> None:
    law = _law_output(run)
    normal = np.asarray(run["ctrl_mode"]) == _core.MODE_NORMAL
    assert normal.mean() > 0.9 and np.abs(law[normal]).max() > 0
    u_cmd, u_sat = np.asarray(run["u_cmd"], float), np.asarray(run["u_sat"], float)
    assert np.array_equal(u_cmd, to_wheels(law))  # the wheels' command, exactly the drive's arithmetic
    lo, hi = np.asarray(run.meta.umin), np.asarray(run.meta.umax)
    assert np.array_equal(u_sat[normal], np.clip(u_cmd[normal], lo, hi))  # saturated in the wheels' unit


@pytest.mark.parametrize("engine", ["python", "cpp"])
def test_a_python_law_of_accelerations_on_torque_wheels_is_converted(tmp_path, engine):
    scn = load_scenario(torque_flight(tmp_path, f"python:{Path(__file__).resolve()}:AccelPD"))
    assert scn.plant.Jw[0] == JW and scn.actuators.wheels.command == "torque"
    run = simulate(scn, engine=engine, duration=60.0)
    _assert_converted(run, lambda a: JW * a)  # torque = Jw a [N m]


@pytest.mark.parametrize("engine", ["python", "cpp"])
def test_a_plugin_of_accelerations_on_torque_wheels_is_converted(plugins, tmp_path, engine):
    scn = load_scenario(torque_flight(tmp_path, f"plugin:{plugins['accel_pd']}"))
    run = simulate(scn, engine=engine, duration=60.0)
    _assert_converted(run, lambda a: JW * a)


@pytest.mark.parametrize("law", ["python", "plugin"])
def test_a_law_of_torques_on_acceleration_wheels_is_converted(plugins, law):
    scn = load_scenario(FLIGHT)
    assert scn.actuators.wheels.command == "acceleration"
    spec = register(TorquePD) if law == "python" else f"plugin:{plugins['torque_pd']}"
    run = simulate(scn, law=spec, engine="cpp", duration=60.0)
    _assert_converted(run, lambda tau: tau / JW)  # a = torque / Jw [rad/s^2]


def test_a_law_of_the_wheels_own_unit_is_not_touched(plugins, tmp_path):
    acc = simulate(load_scenario(FLIGHT), law=register(AccelPD), engine="cpp", duration=20.0)
    _assert_converted(acc, lambda a: a)
    tq = simulate(load_scenario(torque_flight(tmp_path)), law=f"plugin:{plugins['torque_pd']}", engine="cpp",
                  duration=20.0)
    _assert_converted(tq, lambda tau: tau)


def test_the_law_declares_its_command_in_the_registry(plugins):
    assert _core.law_info("dsc-ppc")["command"] == "acceleration"  # the built-ins
    assert _core.law_info(f"plugin:{plugins['accel_pd']}")["command"] == "acceleration"  # declares nothing
    assert _core.law_info(f"plugin:{plugins['torque_pd']}")["command"] == "torque"
    assert _core.law_info(register(TorquePD))["command"] == "torque"
    with pytest.raises(ValueError, match=r"sc_rt_law_command\(\) returned 7, not a LawCommand"):
        _core.load_law_plugin(str(plugins["badcommand"]))


def test_a_python_law_with_an_unknown_command_is_refused_naming_it():
    class Current(AccelPD):
        command = "current"

    with pytest.raises(ValueError, match=r"law Current: command = 'current': must be one of 'acceleration', "
                                         r"'torque'"):
        register(Current)


def _check(path: Path, law: str) -> str:
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "check", str(path), "--law", law, "--fast", "-v"],
                       capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert r.returncode in (0, 1), r.stdout + r.stderr
    return r.stdout


def test_check_names_what_the_law_commands_and_the_conversion(plugins, tmp_path):
    torque = torque_flight(tmp_path)
    out = _check(torque, f"plugin:{plugins['accel_pd']}")
    assert ("NOTE    wheels.command = torque: law plugin:" in out
            and "commands wheel accelerations [rad/s^2]; the wheels take motor torques [N m]: converted by the "
                "controller (torque = Jw a" in out), out
    out = _check(FLIGHT, f"plugin:{plugins['torque_pd']}")
    assert "commands motor torques [N m]; the wheels take wheel accelerations [rad/s^2]: converted by the " \
           "controller (a = torque / Jw" in out, out
    out = _check(FLIGHT, "dsc")
    assert ("OK      wheels.command = acceleration: law dsc commands wheel accelerations [rad/s^2]; the wheels "
            "take wheel accelerations [rad/s^2]: no conversion") in out, out
    # a built-in law on torque wheels (refused before: its rad/s^2 were N m) is converted
    out = _check(torque, "dsc")
    assert "law dsc commands wheel accelerations [rad/s^2]; the wheels take motor torques [N m]: converted" in out


@pytest.mark.lcm
def test_lockstep_converts_as_sim_does_bitwise(plugins, tmp_path):
    lcmnet.require()
    law = f"plugin:{plugins['accel_pd']}"
    path, duration = torque_flight(tmp_path, law), 20.0
    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", str(path), "--law", law, "--mode", "lockstep", "--duration", str(duration),
                        "--out", str(out), "--no-plots"])
    assert r.returncode == 0, r.stderr + r.stdout
    hil = load_traj(out)
    sim = simulate(load_scenario(path), law=law, engine="python", duration=duration)
    assert len(hil["t"]) == len(sim["t"]) == int(duration * 10) + 1
    compared_fields(hil, sim)
    assert np.array_equal(hil["u_cmd"], JW * hil["telemetry"][:, :4])
    # the run's log exported: the wheel command's schema says N m, its values are the record's
    from mcap.reader import make_reader

    from sc_rt.export.mcap_export import export_mcap

    export_mcap(out / "run.lcmlog", tmp_path / "run.mcap")
    with open(tmp_path / "run.mcap", "rb") as f:
        cmds = [(schema, json.loads(m.data)) for schema, ch, m in make_reader(f).iter_messages()
                if ch.topic == "SCRT_CMD"]
    props = json.loads(cmds[0][0].data)["properties"]
    assert "[N m]" in props["u_cmd"]["description"] and "rad/s^2" not in props["u_sat"]["description"]
    assert np.array_equal(np.array([c["u_cmd"] for _, c in cmds])[:len(hil["t"])], hil["u_cmd"])


def _feedforward_use(path: Path) -> float:
    """The percentage of the wheel limits the desired trajectory's feed-forward uses (sc-rt check)."""
    from sc_rt.studies.check import check_scenario

    found = [f for f in check_scenario(path, run_estimate=False) if f.key == "spacecraft.umax"]
    assert len(found) == 1 and found[0].level == "ok", found
    return float(found[0].message.split("uses at most ")[1].split(" %")[0])


def test_check_compares_the_feed_forward_with_the_limits_in_the_wheels_unit(tmp_path):
    # the same trajectory on the same wheels: limits 2.51 rad/s^2 against 0.2 N m = Jw x 2.5126 rad/s^2,
    # so the torque copy uses 2.51 Jw / 0.2 of what the acceleration file uses (not 1/Jw = 12.6 x that)
    accel = _feedforward_use(FLIGHT)
    torque = _feedforward_use(torque_flight(tmp_path))
    assert accel > 0 and torque == pytest.approx(accel * 2.51 * JW / U_MAX, rel=5e-3)  # the message has 3 digits


class HeldPD(AccelPD):
    """AccelPD that reports the held command it is handed (u_sat_prev) as its telemetry."""

    def step(self, inp):
        return self.accel(inp), dict(zip(self.telemetry_names, np.asarray(inp.u_sat_prev)))


def test_a_converted_law_gets_its_held_command_back_in_its_own_unit(tmp_path):
    scn = load_scenario(torque_flight(tmp_path, f"python:{Path(__file__).resolve()}:HeldPD"))
    run = simulate(scn, engine="cpp", duration=30.0)
    held = _law_output(run)[1:]  # step k's u_sat_prev: the saturated command of step k - 1
    u_sat = np.asarray(run["u_sat"], float)[:-1]  # the wheels' [N m]
    normal = (np.asarray(run["ctrl_mode"]) == _core.MODE_NORMAL)[1:]
    assert np.abs(u_sat[normal]).max() > 0.01
    assert np.array_equal(held[normal], u_sat[normal] / JW)  # a = torque / Jw [rad/s^2]
