"""The Foxglove layout shipped with the package (``foxglove_layout.json``
next to this file): one run of a bench without a channel prefix, live
(``sc-rt live``, ``sc-rt hil --live``) or recorded (``sc-rt export``,
``--mcap``), on the same topics.

Tab "Attitude": the true attitude error per axis (the truth against the
reference) against its prescribed bound (``/derived/pointing``), the true
pointing error and the knowledge error (the truth against the estimate,
with sensors), the controller mode
(``SCRT_CMD.mode``: INIT, NORMAL, SAFE) and the frames B and D relative to
N in 3D (``/tf``). Tab "Wheels": the wheel speeds against their limit
(``max_wheel_speed`` of ``SCRT_CONFIG``, through a user script) and the
commands before and after saturation, in the wheels' unit (rad/s^2, or N m
on torque wheels: the ``SCRT_CMD`` schema of the bench says which). Tab
"Rods" (a run with magnetic control; without it the values are null): the
controller's rod dipole commands (``SCRT_CTRL_STATUS.rod_dipole_cmd``, rods
1 to 6, 0 beyond the run's), the body dipole they command (``m_B_cmd``), the
wheels' fill of the momentum manager's capacity (``wheel_fill``) and the
magnetic control's modes (``unloading``, ``detumble_mode``), and beside the
commanded body dipole the one the plant applied after the rods' limits and
faults (``SCRT_TRUTH.dipole_B``: where they part, a rod is clipped or
faulted).

``build_layout`` writes the file with the SDK's layout classes
(``foxglove.layouts``); tests/test_live.py checks that the shipped file is
what it builds and that every topic it reads is a topic of the export.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

__all__ = ["LAYOUT", "TOPICS", "SCRIPT_TOPIC", "build_layout", "referenced_topics", "message_paths"]

#: the shipped layout
LAYOUT = Path(__file__).resolve().parent / "foxglove_layout.json"
#: the topics the layout reads
TOPICS = ("/derived/pointing", "/derived/wheels", "/tf", "SCRT_CMD", "SCRT_CONFIG", "SCRT_CTRL_STATUS", "SCRT_TRUTH")
#: [-] the rods the Rods tab plots: the most a plant has (sc_rt.model.rods.MAX_RODS, rod_cmd_t.dipole's size)
RODS = 6
#: the topic the layout's user script writes (the wheel speed limit beside each wheel sample)
SCRIPT_TOPIC = "/studio_script/wheel_limits"

_SCRIPT = """// The wheel speed limit of the run (SCRT_CONFIG.max_wheel_speed, sent once at its start)
// beside each wheel sample, so that the plot draws it as a line.
import { Input } from "./types";

export const inputs = ["/derived/wheels", "SCRT_CONFIG"];
export const output = "%s";

type Output = { t: number; limit_rpm: number; minus_limit_rpm: number };
let limitRpm: number | undefined;

export default function script(event: Input<"/derived/wheels"> | Input<"SCRT_CONFIG">): Output | undefined {
  const msg = event.message as any;
  if (event.topic === "SCRT_CONFIG") {
    limitRpm = (msg.max_wheel_speed * 60) / (2 * Math.PI);
    return undefined;
  }
  if (limitRpm === undefined) {
    return undefined;
  }
  return { t: msg.t, limit_rpm: limitRpm, minus_limit_rpm: -limitRpm };
}
""" % SCRIPT_TOPIC


def build_layout() -> dict:
    """The layout as JSON data (needs ``foxglove.layouts``, of foxglove-sdk)."""
    import foxglove.layouts as fl

    def plot(title: str, series: list[tuple[str, str]], y_label: str):
        paths = [fl.PlotSeries(value=v, label=label, timestamp_method="receiveTime") for v, label in series]
        return fl.PlotPanel(title=title, config=fl.PlotConfig(paths=paths, y_axis_label=y_label,
                                                             show_legend=True))

    axes = []
    for ax in "xyz":
        axes.append(fl.SplitItem(content=plot(f"true attitude error {ax} and bound [arcsec]", [
            (f"/derived/pointing.true_sigma_BD_arcsec.{ax}", f"true 4 atan sigma_BD,{ax}"),
            (f"/derived/pointing.bound_upper_arcsec.{ax}", "upper bound"),
            (f"/derived/pointing.bound_lower_arcsec.{ax}", "lower bound")], "arcsec")))
    pointing = plot("true pointing error and knowledge error [arcsec]", [
        ("/derived/pointing.true_error_arcsec", "true 4 atan |sigma_BD|"),
        ("/derived/pointing.knowledge_error_arcsec", "knowledge (the estimate against the truth)")], "arcsec")
    modes = fl.StateTransitionsPanel(title="controller mode", config=fl.StateTransitionsConfig(paths=[
        fl.StateTransitionsSeries(value='"SCRT_CMD".mode', label="mode", timestamp_method="receiveTime",
                                  custom_states=fl.StateTransitionsDiscreteCustomStates(states=[
                                      fl.StateTransitionsDiscreteCustomState(value="0", label="INIT"),
                                      fl.StateTransitionsDiscreteCustomState(value="1", label="NORMAL"),
                                      fl.StateTransitionsDiscreteCustomState(value="2", label="SAFE")]))]))
    frames = fl.ThreeDeePanel(title="frames B and D in N", config=fl.ThreeDeeConfig(follow_tf="N"))
    wheels = plot("wheel speeds and limit [rpm]", [
        *[(f"/derived/wheels.speed_rpm.w{i}", f"wheel {i}") for i in range(1, 5)],
        (f"{SCRIPT_TOPIC}.limit_rpm", "+limit"), (f"{SCRIPT_TOPIC}.minus_limit_rpm", "-limit")], "rpm")
    # one layout for every run: the unit is the wheels' (the SCRT_CMD schema of a torque bench says N m)
    cmds = plot("wheel commands [rad/s^2; N m on torque wheels]", [
        *[(f'"SCRT_CMD".u_cmd[{i}]', f"u_cmd {i + 1}") for i in range(4)],
        *[(f'"SCRT_CMD".u_sat[{i}]', f"u_sat {i + 1}") for i in range(4)]], "rad/s^2 or N m (the wheels')")
    rods = _rods_tab(fl, plot)
    attitude = fl.SplitContainer(direction="row", items=[
        fl.SplitItem(proportion=2, content=fl.SplitContainer(direction="column", items=axes)),
        fl.SplitItem(proportion=2, content=fl.SplitContainer(direction="column", items=[
            fl.SplitItem(content=pointing), fl.SplitItem(proportion=0.5, content=modes),
            fl.SplitItem(content=frames)]))])
    wheel_tab = fl.SplitContainer(direction="column", items=[fl.SplitItem(content=wheels),
                                                             fl.SplitItem(content=cmds)])
    layout = fl.Layout(
        content=fl.TabContainer(tabs=[fl.TabItem(title="Attitude", content=attitude),
                                      fl.TabItem(title="Wheels", content=wheel_tab),
                                      fl.TabItem(title="Rods", content=rods)]),
        user_scripts={"wheel_limits": fl.UserScript(name="wheel limits", source_code=_SCRIPT)})
    return json.loads(layout.to_json())


def _rods_tab(fl, plot):
    """The tab of the magnetorquer rods: what the controller's status
    carries of its magnetic part (docs/MODEL.md section 17)."""
    st = '"SCRT_CTRL_STATUS"'
    dipoles = plot("rod dipole commands [A m^2] (before the plant's limits and faults)",
                   [(f"{st}.rod_dipole_cmd[{i}]", f"rod {i + 1}") for i in range(RODS)], "A m^2")
    truth = '"SCRT_TRUTH"'
    body = plot("body dipole: commanded m_B_cmd = G_B rod_dipole_cmd, applied dipole_B (limits, faults) [A m^2]",
                [(f"{st}.m_B_cmd[{i}]", f"m_B_cmd,{ax}") for i, ax in enumerate("xyz")]
                + [(f"{truth}.dipole_B[{i}]", f"applied,{ax}") for i, ax in enumerate("xyz")], "A m^2")
    fill = plot("wheels' fill of the momentum manager's capacity [-]", [(f"{st}.wheel_fill", "fill")], "-")

    def states(path: str, label: str, names: dict[int, str]):
        return fl.StateTransitionsSeries(value=path, label=label, timestamp_method="receiveTime",
                                         custom_states=fl.StateTransitionsDiscreteCustomStates(states=[
                                             fl.StateTransitionsDiscreteCustomState(value=str(v), label=n)
                                             for v, n in names.items()]))
    modes = fl.StateTransitionsPanel(title="magnetic control mode", config=fl.StateTransitionsConfig(paths=[
        states(f"{st}.unloading", "momentum unloading", {-1: "no manager", 0: "off", 1: "on"}),
        states(f"{st}.detumble_mode", "B-dot", {-1: "no B-dot", 0: "detumble", 1: "attitude"})]))
    return fl.SplitContainer(direction="column", items=[
        fl.SplitItem(content=dipoles), fl.SplitItem(content=body), fl.SplitItem(proportion=0.6, content=fill),
        fl.SplitItem(proportion=0.6, content=modes)])


def _walk(node, out: dict[str, list]) -> None:
    """Message paths ("value"), panel types and user scripts' sources of a layout."""
    if isinstance(node, dict):
        for k, v in node.items():
            if k == "value" and isinstance(v, str) and (v.startswith("/") or v.startswith('"')):
                out["paths"].append(v)
            elif k == "panelType" and isinstance(v, str):
                out["panels"].append(v)
            elif k == "sourceCode" and isinstance(v, str):
                out["scripts"].append(v)
            else:
                _walk(v, out)
    elif isinstance(node, list):
        for v in node:
            _walk(v, out)


def message_paths(layout: dict) -> list[str]:
    """Every message path of a layout (``"SCRT_CMD".u_cmd[0]``,
    ``/derived/pointing.true_error_arcsec``), in the layout's order."""
    found: dict[str, list] = {"paths": [], "panels": [], "scripts": []}
    _walk(layout, found)
    return found["paths"]


def referenced_topics(layout: dict) -> set[str]:
    """The topics a layout reads: those of its message paths (``/a/b.c`` ->
    ``/a/b``, ``"A".c`` -> ``A``) but its user scripts' outputs, its user
    scripts' inputs, and ``/tf`` for a 3D panel (ThreeDee)."""
    found: dict[str, list] = {"paths": [], "panels": [], "scripts": []}
    _walk(layout, found)
    out, outputs = set(), set()
    for src in found["scripts"]:
        m = re.search(r"export const inputs = \[([^\]]*)\]", src)
        out.update(json.loads("[" + m.group(1) + "]") if m else [])
        m = re.search(r'export const output = "([^"]+)"', src)
        if m:
            outputs.add(m.group(1))
    for p in found["paths"]:
        out.add(p[1:p.index('"', 1)] if p.startswith('"') else p.split(".", 1)[0].split("[", 1)[0])
    if "ThreeDee" in found["panels"]:
        out.add("/tf")
    return out - outputs
