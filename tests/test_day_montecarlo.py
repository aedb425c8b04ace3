"""The Monte Carlo of the day-long hold (issue 43 acceptance;
scenarios/day_hold.toml's [montecarlo]): the orbit's phase, the residual
dipole and a stuck rod (which rod, when, at what dipole) are drawn per run,
each within the distribution the file declares, and each run is the
scenario a user gets by writing those values into the file by hand
(checked bitwise against an independent run of that hand-edited file).
The runs are shortened to 30 min here; docs/SCENARIOS.md ("A day in
orbit") gives the whole-day campaign's verdict.

Fails on the old main: no day_hold scenario, no [momentum] or rod faults to
draw."""

from __future__ import annotations

import re
import tomllib

import numpy as np

from sc_rt import simulate
from sc_rt.cli.main import main
from sc_rt.scenario.reader import scenario_from_data
from sc_rt.scenario.shipped import resolve
from sc_rt.studies.campaign import RunStore

DURATION = 1800.0  # [s]


def _short_text() -> str:
    return re.sub(r"(?m)^duration = 86400\.0", f"duration = {DURATION}", resolve("day_hold").read_text())


def test_each_run_draws_the_declared_values_and_is_the_hand_edited_scenario(tmp_path):
    path = tmp_path / "day_hold.toml"
    path.write_text(_short_text())
    out = tmp_path / "mc"
    rc = main(["montecarlo", str(path), "--runs", "3", "--workers", "1", "--seed", "5", "--out", str(out)])
    assert rc in (0, 1)  # 1: three runs cannot demonstrate a requirement at 95 % (the verdict says so)
    rows = sorted(RunStore(out, []).read().to_pylist(), key=lambda r: r["run"])
    assert [r["run"] for r in rows] == [0, 1, 2] and all(r["status"] == "ok" for r in rows), rows
    nominal = tomllib.loads(path.read_text())
    for r in rows:
        ma, rod = r["orbit.mean_anomaly"], r["magnetorquers.faults[0].rod"]
        onset, dip = r["magnetorquers.faults[0].onset"], r["magnetorquers.faults[0].dipole"]
        res = [r[f"environment.residual_dipole[{i}]"] for i in range(3)]
        assert 0.0 <= ma < 360.0 and rod in (1, 2, 3) and 0.0 <= onset < 172800.0 and -20.0 <= dip <= 20.0, r
        assert all(abs(v - n) < 6 * 0.2 for v, n in zip(res, nominal["environment"]["residual_dipole"])), res
        # the same values written into the file by hand, run on their own
        data = tomllib.loads(path.read_text())
        data.pop("montecarlo")
        data["orbit"]["mean_anomaly"] = ma
        data["environment"]["residual_dipole"] = res
        data["magnetorquers"]["faults"][0].update(rod=int(rod), onset=onset, dipole=dip)
        run = simulate(scenario_from_data(data, "hand.toml"), engine="cpp")
        assert r["max_abs_u_cmd"] == float(np.max(np.abs(run["u_cmd"]))), r["run"]
        assert [r[f"final_wheel_speed[{i}]"] for i in range(4)] == run["wheel_speed"][-1].tolist(), r["run"]
    # the runs differ where they drew differently
    assert len({r["orbit.mean_anomaly"] for r in rows}) == 3
    assert len({r["final_wheel_speed[0]"] for r in rows}) == 3
