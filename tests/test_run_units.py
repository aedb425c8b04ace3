"""Units resolved per run (issue 39, item 2): the record carries the command
interface and every field's unit; ``max_torque`` is the body torque the
wheels were asked for (and the applied one beside it) on both wheel kinds;
no output labels a torque in rad/s^2.

The torque-wheel run is flight_wheels on wheels that take motor torques
(tests/test_law_command.py ``torque_flight``) with a law of accelerations
the controller converts; every expected value is computed here from the
record and the scenario file's Cbar and Jw.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from sc_rt.results.record.fields import FIELDS
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate

from figcheck import record_figures
from test_law_command import FLIGHT, torque_flight
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
TORQUE_REQS = """
[[requirements]]
name = "tau"
kind = "max_torque"
bound = 0.5
unit = "N m"

[[requirements]]
name = "cmd_torque"
kind = "max_command"
bound = 0.2
unit = "N m"

[[requirements]]
name = "cmd_accel"
kind = "max_command"
bound = 2.6
unit = "rad/s^2"
"""


def _with_reqs(path: Path) -> Path:
    path.write_text(path.read_text() + TORQUE_REQS)
    return path


def _file_wheels(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Cbar (3, 4) and Jw (4,) as the scenario file states them."""
    sc = tomllib.loads(path.read_text())["spacecraft"]
    return np.asarray(sc["Cbar"], float), np.full(4, float(sc["Jw"]))


def _result(run, name: str) -> dict:
    return next(r for r in run.metrics["requirements"] if r["name"] == name)


@pytest.mark.parametrize("wheels", ["torque", "acceleration"])
def test_max_torque_is_the_body_torque_asked_for_and_applied_on_both_wheel_kinds(tmp_path, wheels):
    law = f"python:{(Path(__file__).parent / 'test_law_command.py').resolve()}:AccelPD"
    path = torque_flight(tmp_path, law) if wheels == "torque" else tmp_path / "flight.toml"
    if wheels == "acceleration":
        path.write_text(FLIGHT.read_text().replace('controller = "dsc"', f'controller = "{law}"', 1))
    scn = load_scenario(_with_reqs(path))
    run = simulate(scn, engine="cpp", duration=60.0)
    Cbar, Jw = _file_wheels(path)
    u_cmd, u_sat = np.asarray(run["u_cmd"], float), np.asarray(run["u_sat"], float)
    # the motor torques [N m] from the record: the command itself on torque wheels, Jw times it otherwise
    tau_cmd, tau_sat = (u_cmd, u_sat) if wheels == "torque" else (Jw * u_cmd, Jw * u_sat)
    asked = max(np.linalg.norm(Cbar @ row) for row in tau_cmd)
    applied = max(np.linalg.norm(Cbar @ row) for row in tau_sat)
    tau = _result(run, "tau")
    assert tau["value"] == pytest.approx(asked, rel=1e-12) and tau["unit"] == "N m"
    assert tau["applied"] == pytest.approx(applied, rel=1e-12)
    assert applied <= asked + 1e-15 and asked > 0.01
    # max_command per wheel, in its bound's unit on either kind (the drive's torque = Jw a)
    assert _result(run, "cmd_torque")["value"] == pytest.approx(np.abs(tau_cmd).max(), rel=1e-12)
    assert _result(run, "cmd_accel")["value"] == pytest.approx(np.abs(tau_cmd / Jw).max(), rel=1e-12)
    # the record says what the wheels take and each field's unit
    assert run.meta.wheel_command == wheels and run.meta.law_command == "acceleration"
    cmd_unit = "N m" if wheels == "torque" else "rad/s^2"
    assert run.meta.units["u_cmd"] == run.meta.units["u_sat"] == cmd_unit
    assert run.meta.units["vs"] == "rad/s^2"  # the law's own state, in the unit the law commands
    assert run.meta.units["wheel_accel"] == "rad/s^2" and run.meta.units["t"] == "s"
    assert set(run.meta.units) == {f.name for f in FIELDS}
    assert run.metrics["units"]["max_abs_u_cmd"] == cmd_unit and run.metrics["wheel_command"] == wheels


def test_a_torque_wheel_run_labels_its_commands_in_newton_metres(plugins, tmp_path, monkeypatch):
    path = _with_reqs(torque_flight(tmp_path, f"plugin:{plugins['accel_pd']}"))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", str(path), "--law",
                        f"plugin:{plugins['accel_pd']}", "--engine", "cpp", "--duration", "30", "--out", str(out)],
                       capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert r.returncode in (0, 1), r.stderr + r.stdout  # 1: a requirement not met is a verdict, not an error
    console = [line for line in r.stdout.splitlines() if "max |u_cmd| before saturation" in line]
    assert len(console) == 1 and "[N m]" in console[0] and "rad/s^2" not in console[0], r.stdout
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["units"]["max_abs_u_cmd"] == "N m" and metrics["wheel_command"] == "torque"
    assert metrics["law_command"] == "acceleration"
    with load_traj(out) as z:
        meta = json.loads(str(z["meta_json"]))
    assert meta["wheel_command"] == "torque" and meta["units"]["u_sat"] == "N m"
    html = (out / "report.html").read_text()
    assert "Wheel torque commands after saturation [N m]" in html
    assert "Wheel acceleration commands" not in html
    assert "<td>max |u_cmd| before saturation</td>" in html
    row = html.split("<td>max |u_cmd| before saturation</td>", 1)[1].split("</tr>", 1)[0]
    assert "N m" in row and "rad/s^2" not in row
    # the figure: the commands' axes in N m, the title a torque's
    from sc_rt.results.record.run import Run
    from sc_rt.results.present.figures import tracking_figures

    figs = record_figures(monkeypatch)
    tracking_figures(Run.load(out), tmp_path / "figs")
    fig = figs["wheel_commands.png"]
    left = [ax for ax in fig.axes if ax.get_ylabel().startswith("wheel ")]
    assert len(left) == 4 and all(ax.get_ylabel().endswith("[N m]") for ax in left)
    assert "Wheel torque commands" in left[0].get_title()


def test_the_mcap_and_live_schemas_of_a_torque_bench_say_newton_metres(tmp_path):
    import sc_rt_lcm
    from sc_rt.export.channels import channel_schema
    from sc_rt.export.mcap_derived import Deriver
    from sc_rt.wire.lcmdefs import load_definitions

    defs = load_definitions()
    scn = load_scenario(torque_flight(tmp_path))
    d = Deriver()
    d.config("A/", scn.controller_config_msg().encode())
    assert d.torque["A/"] is True
    _, schema = channel_schema(sc_rt_lcm.wheel_cmd_t, defs, d.torque["A/"])
    for k in ("u_cmd", "u_sat"):
        text = schema["properties"][k]["description"]
        assert "[N m]" in text and "rad/s^2" not in text, text
    _, plain = channel_schema(sc_rt_lcm.wheel_cmd_t, defs)
    assert "[rad/s^2]" in plain["properties"]["u_cmd"]["description"]
    d.config("P/", load_scenario(FLIGHT).controller_config_msg().encode())
    assert d.torque["P/"] is False


def test_the_law_rule_resolves_a_law_state_in_the_unit_the_law_commands():
    from sc_rt.results.record.fields import FIELD

    vs, u = FIELD["vs"], FIELD["u_cmd"]
    assert (vs.unit_rule, u.unit_rule) == ("law", "command")
    # (wheels take torque, law commands torque) -> the unit of a law state and of the command
    assert [vs.resolved_unit(w, law) for w, law in ((True, False), (False, True), (True, None), (False, None))] == \
        ["rad/s^2", "N m", "N m", "rad/s^2"]
    assert [u.resolved_unit(w, law) for w, law in ((True, False), (False, True))] == ["N m", "rad/s^2"]
