"""The layouts the C++ bindings write, by name and order: step_packed's row
(_core.PACKED_FIELDS, read by sc_rt.sim.engines.PACKED) and the columns of
simulate_closed_loop (_core.CLOSED_LOOP_FIELDS)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.model import actuators, plant
from sc_rt.scenario.reader import load_scenario
from sc_rt.sim import engines

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "paper_faults.toml"


@pytest.fixture(scope="module")
def scn():
    return load_scenario(SCENARIO)


def test_packed_fields_are_what_the_engine_slices():
    names = [n for n, _ in _core.PACKED_FIELDS]
    assert len(set(names)) == len(names)
    assert list(engines.PACKED) == names
    o = 0
    for name, width in _core.PACKED_FIELDS:
        assert width >= 1
        assert engines.PACKED[name] == slice(o, o + width), name
        o += width
    assert o == _core.PACKED_SIZE


def test_packed_row_holds_each_named_field_of_the_command(scn):
    # two controllers on the same input: step() gives the Command, step_packed
    # the row; each named slice must hold that field of the Command
    cfg = scn.core_config()
    x = np.array([0.3, -0.2, 0.1, 0.01, -0.02, 0.015, 10.0, -20.0, 30.0, -40.0])
    a, b = _core.Controller(cfg), _core.Controller(cfg)
    m0 = _core.Measurement(0.0, x[0:3], x[3:6], x[6:10])
    a.reset(m0)
    b.reset(m0)
    for t in (0.0, 0.1, 0.2):
        cmd = a.step(_core.Measurement(t, x[0:3], x[3:6], x[6:10]))
        row = _core.step_packed(b, t, x)
        assert row.shape == (_core.PACKED_SIZE,)
        for name, width in _core.PACKED_FIELDS:
            want = np.atleast_1d(np.asarray(getattr(cmd, name), dtype=float))
            assert want.shape == (width,), name
            np.testing.assert_array_equal(row[engines.PACKED[name]], want, err_msg=name)
    # not a trivial row: the fields differ from each other
    assert len({float(v) for v in row}) > 20


def test_closed_loop_fields_are_the_result_columns(scn):
    res = _core.simulate_closed_loop(
        scn.core_config(), plant.plant_params_to_cpp(scn.plant),
        actuators.actuator_params_to_cpp(scn.actuators),
        np.concatenate([scn.initial.sigma_BN, scn.initial.omega_BN_B, scn.initial.wheel_speed]),
        5, 2, 10.0)
    assert (res.pop("rows"), res.pop("diverged")) == (6, False)
    assert res.pop("law_failures") == {"reset": 0, "step": 0, "after": 0, "last": None}
    assert res.pop("telemetry_names") == []  # the law's (dsc-ppc names none)
    assert list(res) == [n for n, _ in _core.CLOSED_LOOP_FIELDS]
    for name, width in _core.CLOSED_LOOP_FIELDS:
        assert res[name].shape == ((6,) if width == 1 else (6, width)), name


def test_closed_loop_fields_are_columns_of_the_python_engine(scn):
    # the cpp engine's columns are the python engine's, same names and widths
    run = engines.simulate(scn, engine="python", duration=0.5)
    for name, width in _core.CLOSED_LOOP_FIELDS:
        col = np.asarray(run[name])
        assert col.shape[1:] == (() if width == 1 else (width,)), name
