"""The ``[momentum]`` and ``[bdot]`` tables (sc_rt.scenario.tables.momentum): their
defaults, a bad value refused with exit 2 and one line naming the key and
the value, the tables they need, and ``sc-rt hil`` refusing them until the
bus carries the dipoles. All fail on the old main (unknown tables)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from magscn import MAG
from sc_rt import _core
from sc_rt.cli.main import main
from sc_rt.scenario.reader import load_scenario
from sc_rt.scenario.shipped import resolve

BASE = Path(resolve("flight_wheels")).read_text()


def _write(tmp_path, text: str) -> Path:
    p = tmp_path / "mag.toml"
    p.write_text(text)
    return p


def _run(capsys, args) -> tuple[int, list[str]]:
    capsys.readouterr()
    try:
        rc = main(args)
    except SystemExit as e:
        rc = e.code
    cap = capsys.readouterr()
    return rc, (cap.err + cap.out).strip().splitlines()


def test_defaults_and_the_core_config(tmp_path):
    scn = load_scenario(_write(tmp_path, BASE + MAG + "[momentum]\ncapacity = 2.0\n[bdot]\n"))
    m, b = scn.magnetic_control.momentum, scn.magnetic_control.bdot
    assert (m.kind, m.gain, m.hysteresis, m.on_fraction, m.off_fraction, m.null_gain) == (
        "cross_product", 0.005, True, 0.5, 0.1, 0.0)
    assert b.gain_auto and b.derivative == "difference" and (b.rate_on, b.rate_off) == (0.035, 0.0087)
    # auto: 2 n (1 + sin xi_m) J_min with J_min = 10 kg m^2 and a 500 km orbit (n = 1.107e-3 rad/s)
    n = math.sqrt(scn.plant.orbit.mu / scn.plant.orbit.a ** 3)
    assert 2 * n * 10.0 <= b.gain <= 4 * n * 10.0
    cfg = scn.core_config()
    assert cfg.magnetic.momentum_enabled and cfg.magnetic.bdot_enabled and cfg.magnetic.rods_enabled
    assert cfg.magnetic.momentum.capacity == 2.0 and cfg.magnetic.bdot.gain == b.gain
    assert cfg.magnetic.rods.dipole_max.tolist() == [30.0, 30.0, 30.0]
    off = load_scenario(_write(tmp_path, BASE + MAG + "[momentum]\nenabled = false\ncapacity = 2.0\n"))
    assert off.magnetic_control is None and not off.core_config().magnetic.active()


@pytest.mark.parametrize(("extra", "key", "needle"), [
    ('[momentum]\nkind = "sideways"\n', "momentum.kind", "sideways"),
    ("[momentum]\ngain = -1\n", "momentum.gain", "-1"),
    ("[momentum]\ncapacity = 2\non_fraction = 0.2\noff_fraction = 0.3\n", "momentum.off_fraction", "< on_fraction"),
    ("[momentum]\nnull_gian = 1\n", "momentum.null_gian", "did you mean"),
    ("[momentum]\ncapacity = -1\n", "momentum.capacity", "-1"),
    ('[bdot]\ngain = "fast"\n', "bdot.gain", "auto"),
    ('[bdot]\nderivative = "numeric"\n', "bdot.derivative", "numeric"),
    ("[bdot]\nrate_on = 0.01\nrate_off = 0.02\n", "bdot.rate_off", "< rate_on"),
])
def test_a_bad_value_exits_2_naming_the_key(tmp_path, capsys, extra, key, needle):
    path = _write(tmp_path, BASE + MAG + extra)
    rc, err = _run(capsys, ["check", str(path)])
    assert rc == 2
    hit = [line for line in err if key in line]
    assert len(hit) == 1 and needle in hit[0], err


@pytest.mark.parametrize("missing", ["[orbit]", "[magnetorquers]"])
def test_both_need_an_orbit_and_rods(tmp_path, capsys, missing):
    mag = MAG.replace("[magnetorquers]\naxes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]\n"
                      "max_dipole = 30.0\n", "") if missing == "[magnetorquers]" else ""
    for table in ("[momentum]\ncapacity = 2.0\n", "[bdot]\n"):
        rc, err = _run(capsys, ["check", str(_write(tmp_path, BASE + mag + table))])
        name = table.split("]")[0][1:]
        assert rc == 2 and any(f"{name}." in line and missing in line for line in err), err




def test_the_mode_switch_flag_is_a_bit_of_its_own():
    others = [getattr(_core, n) for n in dir(_core) if n.startswith("FLAG_") and n != "FLAG_MODE_SWITCH"]
    assert _core.FLAG_MODE_SWITCH == 8192 and all(f & 8192 == 0 for f in others)


def test_the_tables_round_trip_through_the_scenarios_data(tmp_path):
    """What Monte Carlo workers rebuild a scenario from (sc_rt.scenario.keys.scenario_data)."""
    from sc_rt.scenario.keys import scenario_data
    from sc_rt.scenario.reader import scenario_from_data

    scn = load_scenario(_write(tmp_path, BASE + MAG + '[momentum]\nkind = "continuous"\ncapacity = 3.0\n'
                               'null_bias = 7.0\n[bdot]\nderivative = "analytic"\nfilter_tau = 0.5\n'))
    back = scenario_from_data(scenario_data(scn), "rt.toml")
    assert back.magnetic_control == scn.magnetic_control


def test_the_unsampled_engine_refuses_magnetic_control():
    from magscn import mag_scenario
    from sc_rt import simulate

    scn = mag_scenario("[momentum]\ncapacity = 2.0\n", duration=1.0, paper_wheels=True)
    with pytest.raises(ValueError, match=r"no magnetic control \(\[momentum\], \[bdot\]\)"):
        simulate(scn, engine="unsampled")
