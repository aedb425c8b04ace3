"""sc-rt export --mcap: every LCM event in the MCAP with its channel, log time
and values (checked against lcm.EventLog + the generated decode); derived
frames against _core.mrp_to_dcm; schemas generated from the .lcm files and
validating the messages; damaged logs and bad output paths refused cleanly."""

from __future__ import annotations

import base64
import json
import math
import os
import struct
from collections import Counter, defaultdict
from pathlib import Path

import lcm
import numpy as np
import pytest
import sc_rt_lcm
from mcap.reader import make_reader

from sc_rt import _core
from sc_rt.wire import codec as wire
from sc_rt.wire.lcmdefs import json_schema, load_definitions, parse_lcm
from sc_rt.export.mcap_export import export_mcap

import lcmnet

ROOT = Path(__file__).resolve().parent.parent
ARCSEC = 180.0 / math.pi * 3600.0
DERIVED_TOPICS = ("/tf", "/derived/pointing", "/derived/wheels", "/derived/telemetry")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    lcmnet.require()
    out = tmp_path_factory.mktemp("mcap") / "hil"
    r = lcmnet.run_cli(["hil", "scenarios/paper_faults.toml", "--mode", "lockstep", "--duration", "30",
                        "--out", str(out), "--no-plots", "--mcap"])
    assert r.returncode == 0, r.stderr + r.stdout
    assert f"-> {out / 'run.mcap'}" in r.stdout
    return out


@pytest.fixture(scope="module")
def exported(run_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("mcap_out") / "run.mcap"
    summary = export_mcap(run_dir / "run.lcmlog", out)
    return summary, out, read_mcap(out)


def read_mcap(path: Path) -> list[tuple]:
    """(topic, lcm_channel metadata, schema name, log_time, publish_time, sequence, data) in file order."""
    out = []
    with open(path, "rb") as f:
        for schema, ch, m in make_reader(f).iter_messages(log_time_order=False):
            out.append((ch.topic, ch.metadata.get("lcm_channel"), schema.name if schema else None,
                        m.log_time, m.publish_time, m.sequence, m.data,
                        json.loads(schema.data) if schema else None))
    return out


def log_events(path: Path) -> list:
    return [(e.eventnum, e.timestamp, e.channel, e.data) for e in lcm.EventLog(str(path), "r")]


def same_value(json_v, lcm_v, where: str) -> None:
    """A JSON value equals the generated decode's value (floats exactly,
    null where the value is not finite)."""
    if isinstance(lcm_v, (list, tuple)):
        assert isinstance(json_v, list) and len(json_v) == len(lcm_v), where
        for i, (a, b) in enumerate(zip(json_v, lcm_v)):
            same_value(a, b, f"{where}[{i}]")
    elif isinstance(lcm_v, bool):
        assert json_v is lcm_v, where
    elif isinstance(lcm_v, float):
        if math.isfinite(lcm_v):
            assert type(json_v) is float and json_v == lcm_v, (where, json_v, lcm_v)
        else:
            assert json_v is None, where
    elif isinstance(lcm_v, int):
        assert type(json_v) is int and json_v == lcm_v, (where, json_v, lcm_v)
    else:
        assert json_v == lcm_v, where


# --- schemas from the .lcm files ---------------------------------------------

@pytest.mark.parametrize("name", sorted(wire.TYPES))
def test_schema_is_generated_from_the_lcm_definition(name):
    defs = load_definitions()
    cls = wire.TYPES[name]
    sch = json_schema(defs[name], defs)
    assert sch["title"] == f"sc_rt_lcm.{name}"
    assert list(sch["properties"]) == list(cls.__slots__) == sch["required"]
    for f, tn, dims in zip(cls.__slots__, cls.__typenames__, cls.__dimensions__):
        p = sch["properties"][f]
        for d in dims or ():
            assert p["type"] == "array", f
            if isinstance(d, int):
                assert p["minItems"] == p["maxItems"] == d, f
            else:  # a variable dimension: the length is field d
                assert d in cls.__slots__ and "minItems" not in p and "maxItems" not in p, f
            p = p["items"]
        want = {"double": "number", "float": "number", "boolean": "boolean", "string": "string"}.get(tn, "integer")
        assert p["type"] == want, f


def test_a_new_field_appears_without_edits():
    text = (ROOT / "lcmtypes" / "plant_state_t.lcm").read_text()
    text = text.replace("double wheel_speed[4];", "double wheel_speed[4];\n    // [K] new\n    float temp[2][3];\n"
                        "    boolean ok;\n    byte raw[5];\n    string note;")
    (s,) = parse_lcm(text, "x.lcm")
    sch = json_schema(s)["properties"]
    assert sch["temp"]["description"].startswith("[K] new")
    assert sch["temp"]["minItems"] == 2 and sch["temp"]["items"]["maxItems"] == 3
    assert sch["ok"]["type"] == "boolean" and sch["note"]["type"] == "string"
    assert sch["raw"]["items"] == {"type": "integer", "minimum": 0, "maximum": 255}
    with pytest.raises(ValueError, match="x.lcm:"):
        parse_lcm("package p;\nstruct a {\n  double x[3;\n}\n", "x.lcm")


# --- the round trip ------------------------------------------------------------

def test_every_event_is_in_the_mcap_with_its_channel_time_and_values(run_dir, exported):
    summary, _out, msgs = exported
    events = log_events(run_dir / "run.lcmlog")
    primary = [m for m in msgs if m[0] not in DERIVED_TOPICS]
    assert len(primary) == len(events) == summary.events
    assert summary.undecodable == 0
    seen = Counter()
    for (num, ts, ch, data), (topic, lcm_ch, sname, log_t, pub_t, seq, raw, _s) in zip(events, primary):
        assert lcm_ch == ch and log_t == ts * 1000 and seq == num
        body = json.loads(raw)
        cls = wire.identify(data)
        if ch.startswith("SCRT_") and cls is not None:
            assert topic == ch and sname == f"sc_rt_lcm.{cls.__name__}"
            msg = cls.decode(data)
            assert list(body) == list(cls.__slots__)
            for f in cls.__slots__:
                same_value(body[f], getattr(msg, f), f"{ch}.{f}")
            assert pub_t == msg.utime * 1000  # the publisher's clock
            seen[ch] += 1
        else:  # foreign channels (LCM_SELF_TEST, SCRT_HIL_START): the bytes themselves
            assert topic == ch and sname == "sc_rt.lcm_raw_event" and body["reason"] == "foreign_channel"
            assert base64.b64decode(body["data"]) == data and body["size"] == len(data)
            seen["foreign"] += 1
    assert seen["SCRT_STATE"] == seen["SCRT_CMD"] == seen["SCRT_TRUTH"] == seen["SCRT_CTRL_STATUS"] == 301
    assert seen["SCRT_CONFIG"] == 1 and seen["foreign"] == summary.foreign_events >= 2


def quat_from_dcm(C: np.ndarray) -> np.ndarray:
    """(x, y, z, w) of the rotation matrix C (Hamilton, active), Shepperd's
    method: independent of the exporter's MRP formula."""
    tr = np.trace(C)
    cands = [tr, C[0, 0], C[1, 1], C[2, 2]]
    i = int(np.argmax(cands))
    if i == 0:
        w = 0.5 * math.sqrt(1 + tr)
        x, y, z = (C[2, 1] - C[1, 2]) / (4 * w), (C[0, 2] - C[2, 0]) / (4 * w), (C[1, 0] - C[0, 1]) / (4 * w)
    elif i == 1:
        x = 0.5 * math.sqrt(1 + 2 * C[0, 0] - tr)
        w, y, z = (C[2, 1] - C[1, 2]) / (4 * x), (C[0, 1] + C[1, 0]) / (4 * x), (C[0, 2] + C[2, 0]) / (4 * x)
    elif i == 2:
        y = 0.5 * math.sqrt(1 + 2 * C[1, 1] - tr)
        w, x, z = (C[0, 2] - C[2, 0]) / (4 * y), (C[0, 1] + C[1, 0]) / (4 * y), (C[1, 2] + C[2, 1]) / (4 * y)
    else:
        z = 0.5 * math.sqrt(1 + 2 * C[2, 2] - tr)
        w, x, y = (C[1, 0] - C[0, 1]) / (4 * z), (C[0, 2] + C[2, 0]) / (4 * z), (C[1, 2] + C[2, 1]) / (4 * z)
    return np.array([x, y, z, w])


def test_frames_are_the_logged_attitudes(run_dir, exported):
    """/tf child B: sigma_BN of plant_state_t, child D: sigma_DN of
    guidance_t (controller_status_t in a log without guidance);
    rotation = [NB] = R(sigma)^T (B components to N)."""
    _s, _o, msgs = exported
    by_time = defaultdict(list)
    events = log_events(run_dir / "run.lcmlog")
    for e in events:
        by_time[e[1] * 1000].append(e)
    d_channel = "SCRT_GUIDANCE" if any(e[2] == "SCRT_GUIDANCE" for e in events) else "SCRT_CTRL_STATUS"
    n = Counter()
    for topic, _c, sname, log_t, _p, _q, raw, _s in msgs:
        if topic != "/tf":
            continue
        assert sname == "foxglove.FrameTransform"
        tf = json.loads(raw)
        want_ch, field = {"B": ("SCRT_STATE", "sigma_BN"), "D": (d_channel, "sigma_DN")}[tf["child_frame_id"]]
        assert tf["parent_frame_id"] == "N" and tf["translation"] == {"x": 0.0, "y": 0.0, "z": 0.0}
        (src,) = [e for e in by_time[log_t] if e[2] == want_ch]
        sigma = getattr(wire.TYPES[wire.identify(src[3]).__name__].decode(src[3]), field)
        q_ref = quat_from_dcm(np.asarray(_core.mrp_to_dcm(np.asarray(sigma))).T)
        q = np.array([tf["rotation"][k] for k in "xyzw"])
        assert min(np.max(np.abs(q - q_ref)), np.max(np.abs(q + q_ref))) < 1e-12, (tf, sigma)
        assert abs(np.linalg.norm(q) - 1.0) < 1e-12
        assert tf["timestamp"]["sec"] * 10**9 + tf["timestamp"]["nsec"] == log_t
        n[tf["child_frame_id"]] += 1
    assert n == {"B": 301, "D": sum(e[2] == d_channel for e in events)} and n["D"] >= 301


def test_pointing_error_and_bound_in_arcsec(run_dir, exported):
    from sc_rt.scenario.reader import load_scenario

    ppc = load_scenario(ROOT / "scenarios" / "paper_faults.toml").controller.ppc
    chi0, chiinf, gamma, dmin, dmax = (np.asarray(getattr(ppc, k), float)
                                       for k in ("chi0", "chiinf", "gamma", "dmin", "dmax"))
    _s, _o, msgs = exported
    events = log_events(run_dir / "run.lcmlog")
    status = [sc_rt_lcm.controller_status_t.decode(e[3]) for e in events if e[2] == "SCRT_CTRL_STATUS"]
    states = {}  # seq -> the plant's attitude (the copies of the first state: the same)
    for e in events:
        if e[2] == "SCRT_STATE":
            st = sc_rt_lcm.plant_state_t.decode(e[3])
            states[st.seq] = (st.t, np.asarray(st.sigma_BN))
    pts = [json.loads(m[6]) for m in msgs if m[0] == "/derived/pointing"]
    assert len(pts) == len(status) == 301
    first_bad = None
    for p, st in zip(pts, status):
        s = np.asarray(st.sigma_BD)
        assert p["t"] == st.t and p["mode"] == st.mode
        # the law's error: the status's sigma_BD
        assert math.isclose(p["law_error_arcsec"], math.degrees(4 * math.atan(np.linalg.norm(s))) * 3600,
                            rel_tol=1e-12)
        assert np.allclose([p["law_sigma_BD_arcsec"][k] for k in "xyz"], 4 * np.arctan(s) * ARCSEC)
        # the true error: the state it answers against the reference; without sensors the law was fed
        # the truth, so the two agree (to rounding); no estimator, no knowledge error
        t_state, s_bn = states[st.state_seq]
        assert t_state == st.t
        q = _rotation(s_bn, np.asarray(st.sigma_DN))
        assert math.isclose(p["true_error_arcsec"], math.degrees(q) * 3600, rel_tol=1e-9, abs_tol=1e-9)
        assert np.allclose([p["true_sigma_BD_arcsec"][k] for k in "xyz"], 4 * np.arctan(s) * ARCSEC,
                           rtol=1e-9, atol=1e-9)
        assert "knowledge_error_arcsec" not in p
        chi = (chi0 - chiinf) * np.exp(-gamma * st.t) + chiinf  # (29), independently of _core.ppc_chi
        assert np.allclose([p["chi"][k] for k in "xyz"], chi, rtol=1e-12, atol=0)
        assert np.allclose([p["bound_upper_arcsec"][k] for k in "xyz"], 4 * np.arctan(dmax * chi) * ARCSEC)
        assert np.allclose([p["bound_lower_arcsec"][k] for k in "xyz"], -4 * np.arctan(dmin * chi) * ARCSEC)
        if not p["bound_ok"] and first_bad is None:
            first_bad = p["t"]
    # the same first violation as the run's own metrics (bound from its scenario)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert first_bad == metrics["first_bound_violation_s"] is not None
    wheels = [json.loads(m[6]) for m in msgs if m[0] == "/derived/wheels"]
    states = [sc_rt_lcm.plant_state_t.decode(e[3]) for e in log_events(run_dir / "run.lcmlog") if e[2] == "SCRT_STATE"]
    assert len(wheels) == len(states)
    for w, st in zip(wheels, states):
        assert [w["speed_rad_s"][f"w{i}"] for i in range(1, 5)] == list(st.wheel_speed)
        assert np.allclose([w["speed_rpm"][f"w{i}"] for i in range(1, 5)], np.asarray(st.wheel_speed) * 30 / math.pi)


def _rotation(sigma_BN, sigma_DN) -> float:
    """The angle [rad] of the rotation from D to B, from their DCMs (numpy, not the exporter's MRP algebra)."""
    def dcm(s):
        s = np.asarray(s, float)
        x = np.array([[0, -s[2], s[1]], [s[2], 0, -s[0]], [-s[1], s[0], 0]])
        n2 = s @ s
        return np.eye(3) + (8 * x @ x - 4 * (1 - n2) * x) / (1 + n2) ** 2
    c = dcm(sigma_BN) @ dcm(sigma_DN).T
    return math.atan2(np.linalg.norm([c[2, 1] - c[1, 2], c[0, 2] - c[2, 0], c[1, 0] - c[0, 1]]), np.trace(c) - 1)


def _validate(schema: dict, body) -> None:
    """AssertionError when ``body`` does not match ``schema`` (jsonschema when installed)."""
    try:
        import jsonschema
    except ImportError:  # structural checks: every required key, the declared JSON types
        _structural(schema, body, "")
        return
    try:
        jsonschema.Draft202012Validator(schema).validate(body)
    except jsonschema.ValidationError as e:
        raise AssertionError(e.message) from e


def _structural(s: dict, v, where: str, nullable: bool = False) -> None:
    t = s.get("type")
    # a double that is not finite is null, as its field's description says (wire/lcmdefs.py)
    nullable = nullable or "(null: not finite)" in s.get("description", "")
    ok = {"object": dict, "array": list, "string": str, "boolean": bool}.get(t)
    if ok is not None:
        assert isinstance(v, ok), where
    elif t == "integer":
        assert type(v) is int and s.get("minimum", -math.inf) <= v <= s.get("maximum", math.inf), where
    elif t == "number":
        assert type(v) in (int, float) or (v is None and nullable), where
    if t == "object":
        assert set(s.get("required", ())) <= set(v), where
        if s.get("additionalProperties") is False:
            assert set(v) <= set(s["properties"]), where
        for k, x in v.items():
            if k in s.get("properties", {}):
                _structural(s["properties"][k], x, f"{where}.{k}")
    if t == "array":
        assert s.get("minItems", 0) <= len(v) <= s.get("maxItems", math.inf), where
        for i, x in enumerate(v):
            _structural(s["items"], x, f"{where}[{i}]", nullable)


def test_schemas_validate_every_exported_message(exported):
    _s, _o, msgs = exported
    n = Counter()
    for topic, _c, sname, _l, _p, _q, raw, schema in msgs:
        assert schema is not None, topic
        body = json.loads(raw)
        _validate(schema, body)
        _structural(schema, body, topic)  # also without the jsonschema package
        n[sname] += 1
    assert set(n) >= {"sc_rt_lcm.plant_state_t", "sc_rt_lcm.controller_config_t", "foxglove.FrameTransform",
                      "sc_rt.pointing", "sc_rt.wheels", "sc_rt.law_telemetry", "sc_rt.lcm_raw_event"}
    # a schema that can fail: a wrong value is refused
    sch = next(m[7] for m in msgs if m[2] == "sc_rt_lcm.plant_state_t")
    bad = json.loads(next(m[6] for m in msgs if m[2] == "sc_rt_lcm.plant_state_t"))
    bad["wheel_speed"] = bad["wheel_speed"][:3]
    with pytest.raises(AssertionError):
        _validate(sch, bad)
    with pytest.raises(AssertionError):
        _structural(sch, bad, "")


# --- damaged and hostile logs ------------------------------------------------

def _raw_event(num: int, ts: int, channel: bytes, data: bytes) -> bytes:
    return struct.pack(">IqqII", 0xEDA1DA01, num, ts, len(channel), len(data)) + channel + data


def test_undecodable_events_are_counted_and_carried_raw(run_dir, tmp_path):
    src = run_dir / "run.lcmlog"
    events = log_events(src)
    good_state = next(e[3] for e in events if e[2] == "SCRT_STATE")
    good_cmd = next(e[3] for e in events if e[2] == "SCRT_CMD")
    hostile = [("SCRT_STATE", b"garbage", "unknown_type"), ("SCRT_STATE", good_state[:-8], "malformed"),
               ("SCRT_STATE", good_state + b"\x00\x01", "trailing_bytes"), ("SCRT_CMD", good_state, "unknown_type"),
               ("SCRT_CTRL_STATUS", b"", "unknown_type"), ("SCRT_TRUTH", os.urandom(300), "unknown_type"),
               ("SCRT_CONFIG", b"\x00" * 40, "unknown_type"), ("SCRT_FAULT", good_cmd, "unknown_type"),
               ("SOMEONE_ELSE", b"hello", "foreign_channel")]
    bad = tmp_path / "hostile.lcmlog"
    w = lcm.EventLog(str(bad), "w", overwrite=True)
    injected = []
    for i, (_n, ts, ch, data) in enumerate(events):
        w.write_event(ts, ch, data)
        if i % 50 == 7:
            for hch, hdata, kind in hostile:
                w.write_event(ts, hch, hdata)
                injected.append((hch, hdata, kind, ts))
    w.close()
    with open(bad, "ab") as f:  # a channel name that is not UTF-8
        f.write(_raw_event(10**6, 5, b"\xff\xfeBAD", b"x"))
    reps = len(injected) // len(hostile)
    s = export_mcap(bad, tmp_path / "h.mcap")
    assert s.events == len(events) + len(injected) + 1
    assert s.undecodable == 8 * reps  # SOMEONE_ELSE and the non-UTF-8 name are foreign, not undecodable
    assert s.channels["SCRT_STATE"]["undecodable_kinds"] == {"unknown_type": reps, "malformed": reps,
                                                             "trailing_bytes": reps}
    for ch in ("SCRT_CMD", "SCRT_CTRL_STATUS", "SCRT_TRUTH", "SCRT_CONFIG", "SCRT_FAULT"):
        assert s.channels[ch]["undecodable_kinds"] == {"unknown_type": reps}, ch
    # foreign: LCM_SELF_TEST, SCRT_HIL_START and SCRT_HIL_END (hil's markers, published until the
    # logger has one: as many as the clean log holds), SOMEONE_ELSE, the bad name
    markers = sum(e[2] in ("LCM_SELF_TEST", "SCRT_HIL_START", "SCRT_HIL_END") for e in events)
    assert markers >= 3
    assert s.channels["SOMEONE_ELSE"]["raw"] == reps and s.foreign_events == markers + reps + 1
    msgs = read_mcap(tmp_path / "h.mcap")
    primary = [m for m in msgs if m[0] not in DERIVED_TOPICS]
    assert len(primary) == s.events  # nothing dropped
    raws = [(m[1], json.loads(m[6]), m[0], m[3]) for m in primary if m[2] == "sc_rt.lcm_raw_event"]
    got = [(c, base64.b64decode(b["data"]), b["reason"], t // 1000) for c, b, _topic, t in raws
           if b["reason"] != "foreign_channel" or c == "SOMEONE_ELSE"]
    got = [g for g in got if g[0] != "\\xff\\xfeBAD"]
    assert got == [(c, d, k, ts) for c, d, k, ts in injected]
    assert {t for c, b, t, _l in raws if b["reason"] not in ("foreign_channel", "channel_not_utf8")} == {
        f"{c}/undecodable" for c, _d, k in hostile if k != "foreign_channel"}
    (odd,) = [b for c, b, _t, _l in raws if b["reason"] == "channel_not_utf8"]
    assert odd["lcm_channel"] == "\\xff\\xfeBAD" and base64.b64decode(odd["data"]) == b"x"
    # the good events are all there, decoded as in the clean log
    assert s.channels["SCRT_STATE"]["json"] == 301 and s.derived["frame_B"] == 301


def test_non_finite_values_are_null_and_counted(tmp_path):
    log = tmp_path / "nan.lcmlog"
    w = lcm.EventLog(str(log), "w", overwrite=True)
    for k in range(3):
        m = sc_rt_lcm.plant_state_t()
        m.seq, m.t, m.utime = k, k / 10, 1_000_000 + k
        m.sigma_BN = [0.1, float("nan") if k == 1 else 0.2, 0.3]
        m.wheel_speed = [1.0, 2.0, float("inf") if k == 2 else 3.0, 4.0]
        w.write_event(1000 + k, "SCRT_STATE", m.encode())
    w.close()
    s = export_mcap(log, tmp_path / "n.mcap")
    assert s.non_finite_as_null == 2 and s.undecodable == 0
    msgs = read_mcap(tmp_path / "n.mcap")
    states = [json.loads(m[6]) for m in msgs if m[0] == "SCRT_STATE"]
    assert states[1]["sigma_BN"] == [0.1, None, 0.3] and states[2]["wheel_speed"][2] is None
    assert states[0]["sigma_BN"] == [0.1, 0.2, 0.3]
    tf = [json.loads(m[6]) for m in msgs if m[0] == "/tf"]
    assert len(tf) == 2  # no frame for the NaN attitude
    assert [m[4] for m in msgs if m[0] == "SCRT_STATE"] == [(1_000_000 + k) * 1000 for k in range(3)]


def _export_cli(*args):
    return lcmnet.run_cli(["export", *map(str, args)], netns=False)


def _no_leftovers(d: Path, keep=()) -> None:
    assert sorted(p.name for p in d.iterdir() if p.name not in keep) == [], list(d.iterdir())


def test_damaged_logs_are_refused_unless_partial(run_dir, tmp_path):
    data = (run_dir / "run.lcmlog").read_bytes()
    n = len(log_events(run_dir / "run.lcmlog"))
    logs = tmp_path / "logs"
    logs.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    torn = logs / "torn.lcmlog"
    torn.write_bytes(data[:-10])
    r = _export_cli(torn, "--mcap", out / "t.mcap")
    assert r.returncode == 2 and "truncated log" in r.stderr and "--partial" in r.stderr, r.stderr
    _no_leftovers(out)
    r = _export_cli(torn, "--mcap", out / "t.mcap", "--partial")
    assert r.returncode == 0, r.stderr
    assert "torn tail" in r.stdout
    assert len([m for m in read_mcap(out / "t.mcap") if m[0] not in DERIVED_TOPICS]) == n - 1
    # garbage in the middle
    cut = data.index(struct.pack(">I", 0xEDA1DA01), 5000)
    corrupt = logs / "corrupt.lcmlog"
    corrupt.write_bytes(data[:cut] + b"\x13" * 77 + data[cut:])
    r = _export_cli(corrupt, "--mcap", out / "c.mcap")
    assert r.returncode == 2 and f"corrupt log: no event header (sync word) at byte {cut}" in r.stderr, r.stderr
    assert not (out / "c.mcap").exists()
    s = export_mcap(corrupt, out / "c.mcap", partial=True)
    assert s.skipped_bytes == 77 and s.damaged_at == [cut] and s.events == n
    # not a log at all; an empty file; no file
    for name, content in (("text.lcmlog", b"hello world, not a log"), ("empty.lcmlog", b"")):
        (logs / name).write_bytes(content)
        r = _export_cli(logs / name, "--mcap", out / "x.mcap", "--partial")
        assert r.returncode == 2 and "not an LCM log" in r.stderr, r.stderr
        assert "--partial" not in r.stderr.split("error:")[1]
    r = _export_cli(logs / "missing.lcmlog", "--mcap", out / "x.mcap")
    assert r.returncode == 2 and "no such log" in r.stderr
    _no_leftovers(out, keep=("t.mcap", "c.mcap"))


def test_bad_output_paths(run_dir, tmp_path):
    log = run_dir / "run.lcmlog"
    r = _export_cli(log, "--mcap", tmp_path)
    assert r.returncode == 2 and f"--mcap {tmp_path}: is a directory" in r.stderr, r.stderr
    (tmp_path / "file").write_text("x")
    r = _export_cli(log, "--mcap", tmp_path / "file" / "x.mcap")
    assert r.returncode == 2 and "is not a directory" in r.stderr, r.stderr
    # an existing output is replaced only by a complete file: a failed export leaves it as it was
    keep = tmp_path / "keep.mcap"
    keep.write_bytes(b"previous")
    (tmp_path / "bad.lcmlog").write_bytes(log.read_bytes()[:-3])
    r = _export_cli(tmp_path / "bad.lcmlog", "--mcap", keep)
    assert r.returncode == 2 and keep.read_bytes() == b"previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.lcmlog", "file", "keep.mcap"]
    r = _export_cli(log, "--mcap", keep)
    assert r.returncode == 0 and keep.read_bytes()[:8] == b"\x89MCAP0\r\n"


def test_the_file_is_indexed_as_the_mcap_spec_says(exported):
    """Summary (statistics, chunk indexes) agrees with the messages; every
    message index entry points at a message record of its channel and time
    inside the decompressed chunk (what Foxglove's indexed reader uses)."""
    import zstandard
    from mcap.records import MessageIndex
    from mcap.stream_reader import StreamReader

    summary, out, msgs = exported
    with open(out, "rb") as f:
        kinds = Counter(type(r).__name__ for r in StreamReader(f, emit_chunks=False).records)
    assert kinds["Message"] == len(msgs) == summary.messages and kinds["Footer"] == 1
    with open(out, "rb") as f:
        r = make_reader(f, validate_crcs=True)
        s = r.get_summary()
        assert s.statistics.message_count == len(msgs)
        assert sum(s.statistics.channel_message_counts.values()) == len(msgs)
        assert len(list(r.iter_messages(topics=["/derived/pointing"]))) == summary.derived["pointing"]
        metas = {m.name: m.metadata for m in r.iter_metadata()}
        assert sorted(metas) == ["sc_rt.export", "sc_rt.run"]
        assert json.loads(metas["sc_rt.export"]["summary"])["events"] == summary.events
        # the run's start record, read from the log (issue #25): what the run was, not a guess
        run = metas["sc_rt.run"]
        assert run["mode"] == "lockstep" and run["scenario"] == "paper_faults"
        assert json.loads(run["law"])["name"] == "dsc-ppc" and json.loads(run["control_rate_hz"]) == 10.0
    checked = 0
    for ci in s.chunk_indexes:
        with open(out, "rb") as f:
            f.seek(ci.chunk_start_offset)
            chunk = next(iter(StreamReader(f, skip_magic=True, emit_chunks=True).records))
            body = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
            assert len(body) == ci.uncompressed_size
            for cid, off in ci.message_index_offsets.items():
                f.seek(off)
                mi = next(iter(StreamReader(f, skip_magic=True).records))
                assert isinstance(mi, MessageIndex) and mi.channel_id == cid
                for t, o in mi.records:
                    op, _n, ch, _sq, lt, _pt = struct.unpack_from("<BQHIQQ", body, o)
                    assert (op, ch, lt) == (5, cid, t)
                    assert ci.message_start_time <= t <= ci.message_end_time
                    checked += 1
    assert checked == len(msgs)


def test_fuzzed_logs_export_or_are_refused_never_crash(run_dir, tmp_path, rng):
    """Random framing damage, payloads, channel names and timestamps (out of
    MCAP's uint64 ns range too): either a clean refusal (damage without
    --partial) or a complete MCAP with every event, never an exception."""
    from sc_rt.export.mcap_export import ExportError

    good = [(e[2].encode(), e[3]) for e in log_events(run_dir / "run.lcmlog")]
    names = [b"SCRT_STATE", b"SCRT_CMD", b"SCRT_CTRL_STATUS", b"SCRT_TRUTH", b"SCRT_CONFIG", b"SCRT_FAULT",
             b"B2_SCRT_STATE", b"B2_SCRT_CTRL_STATUS", b"B2_SCRT_CONFIG", b"OTHER", b"\xff\x00", b"", b'q"%s']
    outcomes = Counter()
    for _it in range(120):
        parts = []
        for _ in range(int(rng.integers(1, 40))):
            if rng.random() < 0.5:
                ch, d = good[int(rng.integers(len(good)))]
                d = bytearray(d)
                for _ in range(int(rng.integers(0, 4))):
                    if d:
                        d[int(rng.integers(len(d)))] = int(rng.integers(256))
                if rng.random() < 0.3:
                    d = d[: int(rng.integers(0, len(d) + 1))]
                if rng.random() < 0.3:
                    ch = names[int(rng.integers(len(names)))]
            else:
                ch, d = names[int(rng.integers(len(names)))], rng.bytes(int(rng.integers(0, 400)))
            ts = [-1, 0, int(rng.integers(0, 2**62)), int(rng.integers(0, 2**41))][int(rng.integers(4))]
            parts.append(_raw_event(int(rng.integers(0, 2**40)), ts, ch, bytes(d)))
        data = b"".join(parts)
        if rng.random() < 0.3:
            i = int(rng.integers(len(data)))
            data = data[:i] + rng.bytes(int(rng.integers(1, 50))) + data[i:]
        if rng.random() < 0.3:
            data = data[: int(rng.integers(1, len(data) + 1))]
        log = tmp_path / "fuzz.lcmlog"
        log.write_bytes(data)
        for partial in (False, True):
            out = tmp_path / "fuzz.mcap"
            try:
                s = export_mcap(log, out, partial=partial)
            except ExportError:
                outcomes["refused"] += 1
                assert not partial or not data.startswith(struct.pack(">I", 0xEDA1DA01))
                continue
            msgs = read_mcap(out)
            assert len(msgs) == s.messages
            assert len([m for m in msgs if m[1] is not None]) == s.events  # lcm_channel: not derived
            for m in msgs:  # strict JSON: no NaN / Infinity
                json.loads(m[6], parse_constant=lambda c, m=m: pytest.fail(f"{m[0]}: {c} in the JSON"))
            outcomes["exported"] += 1
    assert outcomes["refused"] > 10 and outcomes["exported"] > 100, outcomes


def test_hil_and_report_write_the_same_mcap_as_export(run_dir, exported, tmp_path):
    """sc-rt hil --mcap wrote run.mcap; sc-rt report LOG --mcap OUT too: the
    same messages as sc-rt export (a bad --mcap path is refused before any work)."""
    _s, _o, msgs = exported
    strip = [(m[0], m[1], m[3], m[4], m[5], m[6]) for m in msgs]
    assert [(m[0], m[1], m[3], m[4], m[5], m[6]) for m in read_mcap(run_dir / "run.mcap")] == strip
    rep = tmp_path / "rep"
    r = lcmnet.run_cli(["report", str(run_dir / "run.lcmlog"), "--out", str(rep), "--no-plots",
                        "--mcap", str(rep / "log.mcap")], netns=False)
    assert r.returncode == 0, r.stderr
    assert [(m[0], m[1], m[3], m[4], m[5], m[6]) for m in read_mcap(rep / "log.mcap")] == strip
    r = lcmnet.run_cli(["report", str(run_dir / "run.lcmlog"), "--out", str(tmp_path / "rep2"),
                        "--mcap", str(tmp_path)], netns=False)
    assert r.returncode == 2 and "is a directory" in r.stderr and not (tmp_path / "rep2").exists()
    r = lcmnet.run_cli(["hil", "scenarios/paper_faults.toml", "--out", str(tmp_path / "hil2"),
                        "--mcap", str(rep / "log.mcap" / "x.mcap")], netns=False)
    assert r.returncode == 2 and "is not a directory" in r.stderr, r.stderr
    assert not (tmp_path / "hil2" / "run.lcmlog").exists()


def test_without_guidance_the_desired_frame_comes_from_the_status(tmp_path):
    """A log without guidance_t (an older bench, or only a controller's
    status), on a prefixed bench: frame D from controller_status_t.sigma_DN,
    frame ids and derived topics carry the prefix, no config: no bound."""
    log = tmp_path / "status.lcmlog"
    w = lcm.EventLog(str(log), "w", overwrite=True)
    for k in range(4):
        st = sc_rt_lcm.controller_status_t()
        st.t, st.state_seq, st.mode = k / 10, k, 1
        st.sigma_DN = [0.1 * k, -0.2, 0.05]
        st.sigma_BD = [1e-3, 0.0, -2e-3]
        w.write_event(1000 + k, "B2_SCRT_CTRL_STATUS", st.encode())
    w.close()
    s = export_mcap(log, tmp_path / "s.mcap")
    assert s.derived == {"frame_D": 4, "pointing": 4, "telemetry": 4}
    msgs = read_mcap(tmp_path / "s.mcap")
    tfs = [json.loads(m[6]) for m in msgs if m[0] == "/tf"]
    assert [(t["parent_frame_id"], t["child_frame_id"]) for t in tfs] == [("B2_N", "B2_D")] * 4
    q = np.array([[t["rotation"][c] for c in "xyzw"] for t in tfs])
    for k in range(4):
        ref = quat_from_dcm(np.asarray(_core.mrp_to_dcm(np.array([0.1 * k, -0.2, 0.05]))).T)
        assert min(np.abs(q[k] - ref).max(), np.abs(q[k] + ref).max()) < 1e-12
    pts = [json.loads(m[6]) for m in msgs if m[0] == "/derived/B2/pointing"]
    assert len(pts) == 4 and "chi" not in pts[0] and "bound_ok" not in pts[0]
    assert math.isclose(pts[0]["law_error_arcsec"], 4 * math.atan(math.hypot(1e-3, 2e-3)) * ARCSEC)
    assert "true_error_arcsec" not in pts[0]  # no plant state in the log: no truth
