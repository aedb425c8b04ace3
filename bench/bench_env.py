"""The orbit and the geomagnetic field (issue 43): what one evaluation costs
in C++, timed in C++ (_core.time_environment, the GIL released): the orbit's
gravity-gradient terms (a Kepler solve), the Sun, the IGRF-14 field (degree
13), the tilted dipole and WMM2025 (degree 12) in ECI along the orbit
(position, Earth rotation, the field), and a plant RK4 step with the orbit's gravity gradient against
one with the constant-rate form. Target: an IGRF-14 evaluation <= 10 us
(a day at 10 Hz is 864,000 of them: under 10 s).

    .venv/bin/python bench/bench_env.py [--quick | --smoke]

(--smoke: 1000 evaluations, 2 repetitions: a check that it runs.)
"""

from __future__ import annotations

import math
import statistics

from common import machine, mode, summary, write

from sc_rt import _core
from sc_rt.model.orbit import R_EARTH, OrbitParams, orbit_params_to_cpp

IGRF_TARGET_US = 10.0  # [us] one IGRF-14 evaluation in ECI
KINDS = ("orbit_gg", "sun", "igrf_eci", "dipole_eci", "wmm2025_eci", "plant_step_orbit", "plant_step_w0")


def main(size: str = "full") -> None:
    n, reps = {"smoke": (1000, 2), "quick": (20000, 5), "full": (100000, 11)}[size]
    orbit = OrbitParams(a=R_EARTH + 500e3, e=0.001, i=math.radians(97.4), raan=1.0, j2=True)
    d = _core.time_environment(orbit_params_to_cpp(orbit), n, reps)
    per_us = {k: [s / n * 1e6 for s in d[k]] for k in KINDS}
    igrf = statistics.median(per_us["igrf_eci"])
    result = {
        "machine": machine(),
        "evaluations_per_run": n,
        **{f"{k}_us": summary(v, "us") for k, v in per_us.items()},
        "orbit_gg_added_to_plant_step_us": statistics.median(per_us["plant_step_orbit"])
        - statistics.median(per_us["plant_step_w0"]),
        "day_at_10hz_igrf_s": igrf * 864000 * 1e-6,
        "target_igrf_us": "pass" if igrf <= IGRF_TARGET_US else "miss",
    }
    write("env", result)


if __name__ == "__main__":
    main(mode())
