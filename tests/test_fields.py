"""One field table in the core (cpp/include/sc_rt/fields.hpp, issue 39 item 1):
every mirror of it equals it, and a mirror edited by hand is caught.

The mirrors: the C++ closed loop's result columns (the dicts of
simulate_closed_loop, its sensed variant and the chunked ClosedLoop), the
bindings' packed layouts (PACKED_FIELDS, NAV_FIELDS), controller_status_t as
generated at build time (its Python class and its .lcm source), the status
codec's field lists and the core part of the Python FIELDS. Each check is a
function of (table, mirror) returning the differences, so the same function
is shown to catch an edited copy of a mirror."""

from __future__ import annotations

import copy
import re

import numpy as np
import pytest
import sc_rt_lcm

from sc_rt import _core, pylaw
from sc_rt.model import actuators, plant
from sc_rt.results.record import fields
from sc_rt.scenario.overrides import grid, initial_state, with_overrides
from sc_rt.scenario.reader import load_scenario
from sc_rt.scenario.tables.sensors import nav_config
from sc_rt.sim import engines
from sc_rt.wire import codec

TABLE = _core.FIELD_TABLE
KEYS = ("name", "width", "dtype", "unit", "unit_rule", "source", "group", "packed", "bus", "core", "doc")


def _shape(width: int) -> tuple[int, ...]:
    return () if width == 1 else (width,)


# --- the checks: (table, mirror) -> list of differences ([] when equal)

def columns_problems(table, pairs, groups=("loop",)) -> list:
    """(name, width) pairs (CLOSED_LOOP_FIELDS, a result dict's columns) against
    the table's fields of ``groups``, in table order."""
    want = [(r["name"], r["width"]) for r in table if r["group"] in groups]
    got = [(n, int(w)) for n, w in pairs]
    return [] if got == want else [("columns", got, want)]


def packed_problems(table, pairs, size) -> list:
    """PACKED_FIELDS/PACKED_SIZE against the table's packed fields."""
    want = [(r["name"], r["width"]) for r in table if r["packed"]]
    out = [] if [tuple(p) for p in pairs] == want else [("packed", list(pairs), want)]
    if size != sum(w for _, w in want):
        out.append(("packed size", size))
    return out


def nav_problems(table, pairs, size) -> list:
    """NAV_FIELDS/NAV_SIZE: the table's nav fields, then nav_flags."""
    want = [(r["name"], r["width"]) for r in table if r["group"] == "nav"] + [("nav_flags", 1)]
    out = [] if [tuple(p) for p in pairs] == want else [("nav", list(pairs), want)]
    if size != sum(w for _, w in want):
        out.append(("nav size", size))
    return out


def status_class_problems(table, cls) -> list:
    """The generated controller_status_t class: its last members are the
    table's bus fields in table order, doubles of the table's width."""
    bus = [r for r in table if r["bus"]]
    names = list(cls.__slots__)[-len(bus):]
    types = list(cls.__typenames__)[-len(bus):]
    dims = list(cls.__dimensions__)[-len(bus):]
    out = []
    for r, n, t, d in zip(bus, names, types, dims):
        want_d = None if r["width"] == 1 else [r["width"]]
        if (n, t, d) != (r["name"], "double", want_d):
            out.append((r["name"], n, t, d))
    return out


_MEMBER = re.compile(r"^\s*(\w+)\s+(\w+)(?:\[(\d+)\])?;", re.M)


def status_lcm_problems(table, text: str) -> list:
    """The generated .lcm source of controller_status_t: its members end with
    the table's bus fields, each declared as the table says."""
    members = [(n, t, int(d) if d else 1) for t, n, d in _MEMBER.findall(text)]
    bus = [(r["name"], "double", r["width"]) for r in table if r["bus"]]
    return [] if members[-len(bus):] == bus else [("lcm", members[-len(bus):], bus)]


def codec_problems(table, run_fields, nav_fields) -> list:
    want_run = tuple(r["name"] for r in table if r["bus"] and r["group"] == "loop")
    want_nav = tuple(r["name"] for r in table if r["bus"] and r["group"] == "nav")
    out = []
    if tuple(run_fields) != want_run:
        out.append(("STATUS_RUN_FIELDS", run_fields, want_run))
    if tuple(nav_fields) != want_nav:
        out.append(("STATUS_NAV_FIELDS", nav_fields, want_nav))
    return out


def python_fields_problems(table, field_map) -> list:
    """The Python FIELDS' core part: every table row is a Field with the
    table's shape, unit, unit rule, source, doc, dtype and core flag."""
    out = []
    for r in table:
        f = field_map.get(r["name"])
        if f is None:
            out.append((r["name"], "missing"))
            continue
        got = (f.shape, f.unit, f.unit_rule, f.source, f.doc, f.dtype, f.core)
        want = (_shape(r["width"]), r["unit"], r["unit_rule"], r["source"], r["doc"], r["dtype"], r["core"])
        if got != want:
            out.append((r["name"], got, want))
    return out


# --- the table itself

def test_table_is_well_formed():
    names = [r["name"] for r in TABLE]
    assert len(set(names)) == len(names) and len(names) >= 30
    for r in TABLE:
        assert set(r) == set(KEYS), r
        assert r["width"] >= 1 and r["dtype"] in ("f8", "i8") and r["group"] in ("loop", "nav")
        assert r["unit_rule"] in ("", "command", "law") and r["doc"], r["name"]
        assert r["source"] in fields.SOURCES, r["name"]
    groups = [r["group"] for r in TABLE]
    assert groups == sorted(groups, key=("loop", "nav").index)  # every loop field before the nav ones
    assert {r["name"]: r["width"] for r in TABLE}["telemetry"] == _core.LAW_MAX_TELEMETRY


def test_command_unit_resolves_per_wheel_interface():
    u = fields.FIELD["u_cmd"]
    assert (u.resolved_unit(False), u.resolved_unit(True)) == ("rad/s^2", "N m")
    w = fields.FIELD["omega_BN_B"]
    assert (w.resolved_unit(False), w.resolved_unit(True)) == ("rad/s", "rad/s")


# --- each mirror equals the table

@pytest.fixture(scope="module")
def scn():
    return load_scenario("paper_faults")


def _x0(s):
    return np.concatenate([s.initial.sigma_BN, s.initial.omega_BN_B, s.initial.wheel_speed])


def _args(s):
    return (s.core_config(), plant.plant_params_to_cpp(s.plant), actuators.actuator_params_to_cpp(s.actuators),
            _x0(s))


def _dict_columns(d) -> list[tuple[str, int]]:
    skip = ("rows", "diverged", "law_failures", "telemetry_names")
    return [(k, 1 if v.ndim == 1 else v.shape[1]) for k, v in d.items() if k not in skip]


def test_closed_loop_result_columns_are_the_table(scn):
    assert columns_problems(TABLE, _core.CLOSED_LOOP_FIELDS) == []
    short = with_overrides(scn, duration=2.0)
    res = _core.simulate_closed_loop(*engines.cpp_loop_args(short))
    assert columns_problems(TABLE, _dict_columns(res)) == []
    for r in TABLE:
        if r["group"] == "loop":
            assert res[r["name"]].dtype == np.dtype(r["dtype"]), r["name"]
    loop = _core.ClosedLoop(*engines.cpp_loop_args(short))
    chunk = loop.run(7)
    assert columns_problems(TABLE, _dict_columns(chunk)) == []
    # the column-major buffer holds each field where the table puts it: the
    # values equal the python engine's (an independent loop, bitwise equal by design)
    run = engines.simulate(short, engine="python")
    assert res["rows"] == len(run["t"]) == 21
    for name in ("t", "sigma_BN", "wheel_speed", "u_cmd", "delta2", "lam", "x2d", "flags", "ctrl_mode"):
        np.testing.assert_array_equal(res[name], np.asarray(run[name]), err_msg=name)
        np.testing.assert_array_equal(chunk[name], np.asarray(run[name])[:7], err_msg=name)


def test_sensed_result_columns_are_the_table():
    s = with_overrides(load_scenario("paper_faults_sensors"), duration=0.5)
    n_ctrl, n_sub, _, rate = grid(s)
    res = _core.simulate_closed_loop_sensed(*_args(s)[:3], initial_state(s), n_ctrl, n_sub, rate,
                                            nav_config(s.sensors, s.run.plant_step, str(s.path)))
    assert columns_problems(TABLE, _dict_columns(res), ("loop", "nav")) == []
    assert np.isfinite(res["P_diag"]).all() and (res["P_diag"] > 0).all()


def test_packed_layouts_are_the_table():
    assert packed_problems(TABLE, _core.PACKED_FIELDS, _core.PACKED_SIZE) == []
    assert nav_problems(TABLE, _core.NAV_FIELDS, _core.NAV_SIZE) == []
    assert list(engines.RECORDED) == [n for n, _ in _core.PACKED_FIELDS if n not in ("flags", "ctrl_mode")]
    # a Python law's fixed slots (pylaw.TELEMETRY: LawOutput's layout) have the table's widths
    widths = {r["name"]: r["width"] for r in TABLE}
    assert {k: w for k, (_, w) in pylaw.TELEMETRY.items()} == {k: widths[k] for k in pylaw.TELEMETRY}


def test_status_message_is_generated_from_the_table():
    assert status_class_problems(TABLE, sc_rt_lcm.controller_status_t) == []
    src = [p for p in codec.lcm_sources() if p.name == "controller_status_t.lcm"]
    assert len(src) == 1
    assert status_lcm_problems(TABLE, src[0].read_text()) == []


def test_codec_and_python_fields_are_the_table():
    assert codec_problems(TABLE, codec.STATUS_RUN_FIELDS, codec.STATUS_NAV_FIELDS) == []
    assert python_fields_problems(TABLE, fields.FIELD) == []
    # the Python-only fields are not the core's
    core = {r["name"] for r in TABLE}
    assert {f.name for f in fields.FIELDS} > core
    assert fields.merge_fields(fields.core_fields()) == fields.FIELDS


# --- a mirror edited by hand is caught

def test_an_edited_mirror_is_caught(tmp_path):
    # the result's columns: one width changed, one column dropped
    cols = [tuple(c) for c in _core.CLOSED_LOOP_FIELDS]
    assert columns_problems(TABLE, [cols[0], (cols[1][0], 4)] + cols[2:]) != []
    assert columns_problems(TABLE, cols[:-1]) != []
    # the packed layout: two fields swapped
    packed = [tuple(p) for p in _core.PACKED_FIELDS]
    assert packed_problems(TABLE, [packed[1], packed[0]] + packed[2:], _core.PACKED_SIZE) != []
    assert nav_problems(TABLE, list(_core.NAV_FIELDS)[:-1], _core.NAV_SIZE) != []
    # the .lcm: a temporary copy of the generated source with a field's width edited
    src = next(p for p in codec.lcm_sources() if p.name == "controller_status_t.lcm")
    text = src.read_text()
    edited = tmp_path / "controller_status_t.lcm"
    edited.write_text(text.replace("double sigma_BD[3];", "double sigma_BD[4];"))
    assert edited.read_text() != text
    assert status_lcm_problems(TABLE, edited.read_text()) != []

    # the generated class with a member renamed
    class Renamed:
        __slots__ = list(sc_rt_lcm.controller_status_t.__slots__)
        __typenames__ = sc_rt_lcm.controller_status_t.__typenames__
        __dimensions__ = sc_rt_lcm.controller_status_t.__dimensions__

    Renamed.__slots__[-1] = "nis_renamed"
    assert status_class_problems(TABLE, Renamed) != []
    # the codec's list with a name added by hand
    assert codec_problems(TABLE, codec.STATUS_RUN_FIELDS + ("u_cmd",), codec.STATUS_NAV_FIELDS) != []
    # the Python fields: a Field edited, and a table row edited (its copy)
    edited_fields = dict(fields.FIELD)
    edited_fields["z2"] = fields.Field("z2", (3,), "N m", "controller", "edited")
    assert python_fields_problems(TABLE, edited_fields) != []
    table = copy.deepcopy(TABLE)
    table[0]["unit"] = "ms"
    assert python_fields_problems(table, fields.FIELD) != []
    assert python_fields_problems(table, {f.name: f for f in fields.core_fields(table)}) == []
