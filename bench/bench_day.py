"""A day in orbit on the C++ engine (issue 43): `scenarios/day_hold.toml`,
24 h at 10 Hz (864,000 control steps, one RK4 plant step each) with the
orbit's gravity gradient, IGRF-14 to degree 13 at every RK4 stage and once
per control step for the controller's field, the residual dipole, the rods
and the momentum manager. Target: the whole day <= 10 s (the engine's loop
and its recording, simulate()'s wall_s). Beside it: the bare loop of the
same arithmetic (_core.bare_closed_loop: nothing recorded) and what one
field evaluation costs in C++ (_core.time_environment's IGRF-14 in ECI),
so the field's share of the day is a product, not a guess.

    .venv/bin/python bench/bench_day.py [--quick | --smoke]

(--quick: 6 h, one run each; --smoke: 10 min: a check that it runs.)
"""

from __future__ import annotations

import statistics
import time

from common import alternate, machine, mode, summary, write

from sc_rt import _core
from sc_rt.model.orbit import orbit_params_to_cpp
from sc_rt.scenario.overrides import with_overrides
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import cpp_loop_args, simulate

DAY_TARGET_S = 10.0  # [s] 24 h at 10 Hz on the C++ engine with the full field


def main(size: str = "full") -> None:
    duration, runs = {"smoke": (600.0, 1), "quick": (6 * 3600.0, 1), "full": (86400.0, 3)}[size]
    scn = with_overrides(load_scenario("day_hold"), duration=duration)
    engine, bare = [], []

    def run_engine():
        r = simulate(scn, engine="cpp")
        assert r.metrics["finite"] and r.metrics.get("valid", True)
        engine.append(r.metrics["wall_s"])

    args = cpp_loop_args(scn)

    def run_bare():
        t0 = time.perf_counter()
        _core.bare_closed_loop(*args)
        bare.append(time.perf_counter() - t0)

    alternate({"engine": run_engine, "bare": run_bare}, runs=runs, warmup=0)
    steps = round(duration * scn.run.control_rate_hz)
    n_eval = 1000 if size == "smoke" else 100000
    env = _core.time_environment(orbit_params_to_cpp(scn.plant.orbit), n_eval, 3)
    igrf_us = statistics.median(s / n_eval * 1e6 for s in env["igrf_eci"])
    # per control step: 4 RK4 stages of the plant and the controller's field at t_k
    evals_per_step = 4 * scn.run.plant_substeps + 1
    day_s = statistics.median(engine) * 86400.0 / duration
    result = {
        "machine": machine(),
        "scenario": "day_hold",
        "duration_s": duration,
        "control_steps": steps,
        "engine_wall_s": summary(engine, "s"),
        "bare_loop_s": summary(bare, "s"),
        "engine_us_per_step": statistics.median(engine) / steps * 1e6,
        "bare_us_per_step": statistics.median(bare) / steps * 1e6,
        "igrf_eval_us": igrf_us,
        "igrf_evals_per_step": evals_per_step,
        "igrf_share_of_bare_step": igrf_us * evals_per_step / (statistics.median(bare) / steps * 1e6),
        "day_engine_s": day_s,
        "target_day_le_10s": "pass" if day_s <= DAY_TARGET_S else "miss",
    }
    write("day", result)


if __name__ == "__main__":
    main(mode())
