"""The bare loop bench/bench_sim.py compares the C++ engine with (issue #31,
item 7): ``_core.bare_closed_loop`` runs the engine's own loop with nothing
recorded. It must be the same arithmetic: the same rows, and bitwise the
plant state of the engine's last row."""

from __future__ import annotations

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.scenario.overrides import with_overrides
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim.engines import cpp_loop_args, simulate


@pytest.mark.parametrize("name, rate, duration", [("paper_faults", None, 60.0), ("ppc_feasible_100hz", None, 20.0),
                                                   ("paper_faults", 50.0, 30.0)])
def test_the_bare_loop_ends_where_the_engine_does(name, rate, duration):
    scn = with_overrides(load_scenario(name), control_rate_hz=rate, duration=duration)
    rows, diverged, last = _core.bare_closed_loop(*cpp_loop_args(scn))
    run = simulate(scn, engine="cpp")
    assert (rows, diverged) == (len(run), run.diverged)
    x = np.concatenate([run["sigma_BN"][-1], run["omega_BN_B"][-1], run["wheel_speed"][-1]])
    assert np.array_equal(last, x), (last, x)
    # and the python engine agrees with both (the twin is bitwise)
    assert np.array_equal(simulate(scn, engine="python")["wheel_speed"][-1], last[6:])


def test_a_bare_loop_that_records_nothing_differs_from_a_shorter_run():
    """The comparison can fail: a run one period shorter ends elsewhere."""
    scn = with_overrides(load_scenario("paper_faults"), duration=30.0)
    _, _, last = _core.bare_closed_loop(*cpp_loop_args(scn))
    short = with_overrides(scn, duration=29.9)
    _, _, last_short = _core.bare_closed_loop(*cpp_loop_args(short))
    assert not np.array_equal(last, last_short)
