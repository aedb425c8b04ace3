"""Sensors and the MEKF in the offline loop (issue #15): the C++ engine's
300 s @ 10 Hz loop of scenarios/ppc_feasible_10hz_sensors.toml (plant step
0.01 s) with its sensors and the estimator feeding the law, against the same
scenario without [sensors] (same plant step), measured alternately; and the
navigation's cost per control step (sensor ticks, MEKF propagation and
updates, the measurement), the difference of the two loops over the 3001
control steps, with the gyro at 100 Hz and at 10 Hz.

Targets: the sensors add <= 30 % to the loop; <= 1 us per control step.

    .venv/bin/python bench/bench_sensors.py [--quick]
"""

from __future__ import annotations

import dataclasses
import sys

from common import ROOT, alternate, machine, summary, write

from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import simulate


def main(quick: bool = False) -> None:
    scn = load_scenario(ROOT / "scenarios" / "ppc_feasible_10hz_sensors.toml")
    g10 = dataclasses.replace(scn.sensors, gyro=dataclasses.replace(scn.sensors.gyro, rate_hz=10.0))
    cases = {"no_sensors": dataclasses.replace(scn, sensors=None),
             "gyro_100hz": scn,
             "gyro_10hz": dataclasses.replace(scn, sensors=g10),
             "gyro_100hz_truth_fed": dataclasses.replace(
                 scn, sensors=dataclasses.replace(scn.sensors, measurement="truth"))}
    loops: dict[str, list[float]] = {k: [] for k in cases}

    def run(name):
        loops[name].append(simulate(cases[name], engine="cpp").metrics["wall_s"])

    runs = 3 if quick else 9
    alternate({k: (lambda k=k: run(k)) for k in cases}, runs=runs)
    loops = {k: v[1:] for k, v in loops.items()}  # drop the warm-up
    steps = int(round(scn.run.duration * scn.run.control_rate_hz)) + 1
    res = {"machine": machine(), "scenario": scn.name, "law": scn.run.controller, "engine": "cpp",
           "duration_s": scn.run.duration, "control_rate_hz": scn.run.control_rate_hz,
           "plant_step_s": scn.run.plant_step, "control_steps": steps}
    base = summary(loops["no_sensors"], "s")
    res["loop_no_sensors_s"] = base
    for k in ("gyro_100hz", "gyro_10hz", "gyro_100hz_truth_fed"):
        s = summary(loops[k], "s")
        res[f"loop_{k}_s"] = s
        res[f"overhead_{k}_fraction"] = s["median"] / base["median"] - 1.0
        res[f"nav_{k}_per_control_step_us"] = (s["median"] - base["median"]) / steps * 1e6
    res["target_overhead_le_30pct"] = ("pass" if res["overhead_gyro_100hz_fraction"] <= 0.30
                                       and res["overhead_gyro_10hz_fraction"] <= 0.30 else "miss")
    res["target_nav_step_le_1us"] = ("pass" if max(res["nav_gyro_100hz_per_control_step_us"],
                                                   res["nav_gyro_10hz_per_control_step_us"]) <= 1.0 else "miss")
    # a law at the gyro's rate: ppc_feasible_100hz_sensors (100 Hz law, 100 Hz gyro, one plant step
    # per period) against itself without [sensors]; its truth-fed variant so that the loop holds
    s100 = load_scenario(ROOT / "scenarios" / "ppc_feasible_100hz_sensors.toml")
    s100 = dataclasses.replace(s100, sensors=dataclasses.replace(s100.sensors, measurement="truth"))
    c100 = {"no_sensors": dataclasses.replace(s100, sensors=None), "gyro_100hz": s100}
    l100: dict[str, list[float]] = {k: [] for k in c100}
    alternate({k: (lambda k=k: l100[k].append(simulate(c100[k], engine="cpp").metrics["wall_s"]))
               for k in c100}, runs=runs)
    l100 = {k: v[1:] for k, v in l100.items()}
    steps100 = int(round(s100.run.duration * s100.run.control_rate_hz)) + 1
    b100 = summary(l100["no_sensors"], "s")
    res["law_100hz_loop_no_sensors_s"] = b100
    res["law_100hz_loop_gyro_100hz_s"] = summary(l100["gyro_100hz"], "s")
    res["law_100hz_overhead_fraction"] = res["law_100hz_loop_gyro_100hz_s"]["median"] / b100["median"] - 1.0
    res["law_100hz_nav_per_control_step_us"] = (
        (res["law_100hz_loop_gyro_100hz_s"]["median"] - b100["median"]) / steps100 * 1e6)
    write("sensors", res)


if __name__ == "__main__":
    main("--quick" in sys.argv)
