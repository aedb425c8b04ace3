"""sc-rt live and sc-rt hil --live, for real: a lockstep run served on the
Foxglove SDK's WebSocket server, read by a Foxglove WebSocket client
(tests/fgclient.py, tornado) and checked against the run's own record
(its log, and the MCAP export of it: same topics, schemas and bytes);
the decimation against a direct computation; no work without a listener;
a port in use, bad options and clients speaking garbage: one line, exit 2
for sc-rt live, the run unaffected for sc-rt hil --live.

Every wait is bounded and waits on an event (a line, a message, the
server closing), never on a sleep.
"""

from __future__ import annotations

import asyncio
import json
import math
import shlex
import socket
import struct
import sys
import threading
from collections import defaultdict
from fractions import Fraction
from pathlib import Path

import lcm
import pytest
import sc_rt_lcm
from mcap.reader import make_reader
from tornado.httpclient import HTTPClientError

from sc_rt.live.layout import LAYOUT, TOPICS, build_layout, message_paths, referenced_topics
from sc_rt.live.ratelimit import RateLimiter, parse_rates
from sc_rt.live.server import LiveServer
from sc_rt.wire import codec as wire

import lcmnet
from fgclient import SUBPROTOCOL, FoxgloveClient

HERE = Path(__file__).resolve().parent
RATE_HZ, DURATION_S = 10, 20  # 201 states: far below the 50 Hz cap, nothing decimated
ROWS = RATE_HZ * DURATION_S + 1
LCM_TOPICS = ("SCRT_STATE", "SCRT_CMD", "SCRT_CTRL_STATUS", "SCRT_TRUTH", "SCRT_GUIDANCE", "SCRT_CONFIG")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def json_of(v):
    """A decoded LCM value as its JSON value (floats exact, not finite: null)."""
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, (list, tuple)):
        return [json_of(x) for x in v]
    if isinstance(v, (bytes, bytearray)):
        return list(v)
    if hasattr(v, "__slots__"):
        return {k: json_of(getattr(v, k)) for k in v.__slots__}
    return v


def read_mcap(path: Path) -> tuple[dict, dict]:
    """{topic: [payload bytes]} and {topic: (schema name, schema)} of an MCAP file."""
    msgs, schemas = defaultdict(list), {}
    with open(path, "rb") as f:
        for schema, ch, m in make_reader(f).iter_messages(log_time_order=False):
            msgs[ch.topic].append(m.data)
            schemas[ch.topic] = (schema.name, json.loads(schema.data))
    return msgs, schemas


# --------------------------------------------------------------------------- #
# decimation and the layout (no bus)

def _direct(times: list, rate: float) -> list[int]:
    """Which messages a cap of ``rate`` keeps, in exact arithmetic: the first,
    then each at least 1/rate after the last kept (a time that goes back starts again)."""
    period = Fraction(1) / Fraction(rate)
    kept, last = [], None
    for k, t in enumerate(times):
        ft = Fraction(t)
        if last is None or ft < last or ft - last >= period:
            kept.append(k)
            last = ft
    return kept


@pytest.mark.parametrize("f, rate", [(1000, 50), (1000, 30), (1000, 1000), (100, 50), (10, 50), (1000, 7)])
def test_rate_limiter_keeps_what_a_direct_computation_keeps(f, rate, rng):
    exact = [Fraction(k, f) for k in range(3000)]  # the grid's times; the messages carry their doubles
    grid = [k / f for k in range(3000)]
    lim = RateLimiter(rate)
    assert [k for k, t in enumerate(grid) if lim.keep(t)] == _direct(exact, rate)
    # on a grid: every ceil(f/rate)-th message (all of a channel slower than the cap)
    step = max(1, math.ceil(Fraction(f, rate)))
    assert _direct(exact, rate) == list(range(0, len(grid), step))
    # jittered times, and a second run on the bus (the time goes back): the same as the direct computation
    jitter = [t + float(rng.uniform(0, 0.2 / f)) for t in grid]
    times = jitter[:1500] + jitter[:1500]
    lim = RateLimiter(rate)
    assert [k for k, t in enumerate(times) if lim.keep(t)] == _direct(times, rate)
    # 0: every message; no time (not one message of the type): kept, the clock untouched
    assert all(RateLimiter(0).keep(t) for t in grid)
    lim = RateLimiter(rate)
    assert lim.keep(0.0) and lim.keep(None) and lim.keep(float("nan")) and not lim.keep(0.5 / rate)


def test_rate_option_items():
    assert parse_rates(["SCRT_CTRL_STATUS=200", "SCRT_STATE=0"]) == {"SCRT_CTRL_STATUS": 200.0, "SCRT_STATE": 0.0}
    for bad in ("SCRT_STATE", "=5", "SCRT_STATE=-1", "SCRT_STATE=x", "SCRT_STATE=nan"):
        with pytest.raises(ValueError, match="--rate"):
            parse_rates([bad])


def test_the_shipped_layout_is_what_build_layout_makes():
    shipped = json.loads(LAYOUT.read_text())
    assert shipped == build_layout()
    assert referenced_topics(shipped) == set(TOPICS)


# --------------------------------------------------------------------------- #
# a lockstep run served live (hil --live), clients speaking garbage beside it, against its own record

def _gated_controller(gate: Path) -> str:
    """sc-rt-controller as an external controller that starts when the client writes to ``gate``."""
    ctl = Path(sys.executable).parent / "sc-rt-controller"
    inner = (f"read go < {shlex.quote(str(gate))} && exec {shlex.quote(str(ctl))} --config \"$SCRT_CONFIG\" "
             "--mode \"$SCRT_MODE\" --lcm-url \"$SCRT_LCM_URL\" --summary \"$SCRT_SUMMARY\"")
    return "sh -c " + shlex.quote(inner)


def _drive(tmp: Path, port: int, hil: list[str], *flags: str, timeout: float = 240) -> dict:
    """tests/fgclient.py in the run's network namespace: the run, and what a client got."""
    res = tmp / "client.json"
    r = lcmnet.run([sys.executable, str(HERE / "fgclient.py"), "--port", str(port), "--out", str(res), *flags,
                    "--timeout", "120", "--", "hil", *hil], timeout=timeout)
    assert r.returncode == 0 and res.is_file(), r.stderr
    return json.loads(res.read_text())


@pytest.fixture(scope="module")
def live_run(tmp_path_factory):
    lcmnet.require()
    tmp = tmp_path_factory.mktemp("live")
    port = free_port()
    out = tmp / "hil"
    got = _drive(tmp, port, ["scenarios/paper_faults.toml", "--mode", "lockstep", "--control-rate", str(RATE_HZ),
                             "--duration", str(DURATION_S), "--out", str(out), "--no-plots", "--mcap",
                             "--external", _gated_controller(tmp / "gate"), "--live", str(port)],
                 "--gate", str(tmp / "gate"), "--garbage")
    assert "error" not in got, got.get("error")
    assert got["hil_rc"] == 0, got["hil_stderr"]
    return got, out


@pytest.mark.lcm
@pytest.mark.slow  # ~3 s: a lockstep run with its live server and a client
def test_live_run_is_bitwise_the_runs_record(live_run):
    got, out = live_run
    # the run: one line for the live server, the client on the SDK's subprotocol, to the server's close
    assert got["live_line"].startswith(f"sc-rt hil: live on ws://127.0.0.1:{got['port']} ")
    assert sum("live" in line for line in got["hil_stderr"].splitlines()) == 1, got["hil_stderr"]
    assert got["subprotocol"] == SUBPROTOCOL and got["gate_opened"] and got["closed"]
    # clients speaking garbage came first (raw bytes, the older subprotocol alone: HTTP 400, junk frames)
    assert got["garbage"]["old_subprotocol"] == 400 and "raw_answer" in got["garbage"]
    msgs = {t: [p.encode() for _, p in v] for t, v in got["messages"].items()}
    mcap, schemas = read_mcap(out / "run.mcap")
    # same topics, schemas and metadata as the export: a layout for a recording works live
    for topic, (name, schema) in schemas.items():
        if topic.startswith("SCRT_HIL") or topic == "LCM_SELF_TEST":
            continue  # the run's start and end markers (foreign, raw): on the bus before the client came
        ch = got["channels"][topic]
        assert (ch["encoding"], ch["schemaEncoding"], ch["schemaName"]) == ("json", "jsonschema", name), topic
        assert json.loads(ch["schema"]) == schema, topic
    layout = referenced_topics(json.loads(LAYOUT.read_text()))
    assert layout <= set(schemas), sorted(layout - set(schemas))
    # the LCM channels: the very bytes of the export, from the client's first message to the run's end,
    # but for the copies of the first state the emulator sends again until the controller answers (same
    # time: the cap keeps one; the rate limiter on the record's own times says which)
    for topic in LCM_TOPICS:
        live, rec = msgs[topic], mcap[topic]
        assert live and live[0] in rec, topic
        assert live == capped(rec[rec.index(live[0]):], topic != "SCRT_CONFIG"), topic
    for topic in ("SCRT_CMD", "SCRT_CTRL_STATUS"):  # the controller started after the client subscribed
        assert len(msgs[topic]) == ROWS and msgs[topic][0] == mcap[topic][0], topic
    assert [json.loads(p)["seq"] for p in msgs["SCRT_STATE"]] == list(range(ROWS))
    # and the values are the logged messages', bit for bit
    logged = defaultdict(list)
    for e in lcm.EventLog(str(out / "run.lcmlog"), "r"):
        cls = wire.identify(e.data)
        if e.channel in LCM_TOPICS and cls is not None:
            logged[e.channel].append(json_of(cls.decode(e.data)))
    for topic in LCM_TOPICS:
        live = [json.loads(p) for p in msgs[topic]]
        assert all(m in logged[topic] for m in live), topic
    # the derived topics: the export's bytes (the pointing with the run's bound), the frames but their stamp
    pointing = msgs["/derived/pointing"]
    rec = mcap["/derived/pointing"]
    assert len(pointing) == ROWS and pointing == capped(rec[rec.index(pointing[0]):])
    assert all("bound_upper_arcsec" in json.loads(p) for p in pointing)
    wheels = msgs["/derived/wheels"]
    assert wheels == capped(mcap["/derived/wheels"][mcap["/derived/wheels"].index(wheels[0]):])

    def frames(payloads, child):
        out = []
        for p in payloads:
            d = json.loads(p)
            d.pop("timestamp")
            if d["child_frame_id"] == child and (not out or out[-1] != d):  # copies of the first state: one
                out.append(d)
        return out
    for child in ("B", "D"):
        live = frames(msgs["/tf"], child)
        assert len(live) == ROWS and live == frames(mcap["/tf"], child)[-ROWS:], child


@pytest.mark.lcm
@pytest.mark.slow  # ~3 s: a lockstep run of day_hold with its live server and a client
def test_a_magnetic_run_serves_its_field_and_rods_live_as_the_export(tmp_path):
    """Issue 43, the bus side: the field (SCRT_MAG) and the rods' commands
    (SCRT_ROD_CMD) are served live with the export's schemas and bytes, and
    the status's magnetic fields carry their units in its schema."""
    lcmnet.require()
    port, out = free_port(), tmp_path / "hil"
    got = _drive(tmp_path, port, ["day_hold", "--mode", "lockstep", "--duration", "10", "--out", str(out),
                                  "--no-plots", "--mcap", "--external", _gated_controller(tmp_path / "gate"),
                                  "--live", str(port)], "--gate", str(tmp_path / "gate"))
    assert "error" not in got and got["hil_rc"] == 0, got.get("error") or got["hil_stderr"]
    mcap, schemas = read_mcap(out / "run.mcap")
    for topic in ("SCRT_MAG", "SCRT_ROD_CMD", "SCRT_CTRL_STATUS"):
        ch = got["channels"][topic]
        assert (ch["schemaName"], json.loads(ch["schema"])) == schemas[topic], topic
    status = schemas["SCRT_CTRL_STATUS"][1]["properties"]
    assert status["rod_dipole_cmd"]["description"].startswith("[A m^2]")
    assert status["B_B"]["description"].startswith("[T]")
    rods = [p.encode() for _, p in got["messages"]["SCRT_ROD_CMD"]]
    # the controller started after the client subscribed: a rod command per row of the run, the export's
    # bytes (but for the controller's re-answers of the first state: the cap keeps one per time)
    assert len(rods) == 101 and rods == capped(mcap["SCRT_ROD_CMD"])
    assert any(any(abs(d) > 1.0 for d in json.loads(p)["dipole"][:3]) for p in rods)
    # the shipped layout (its Rods tab too) reads only what this magnetic run publishes: every path a
    # field of its topic's schema in the export, and the Rods tab's values numbers in what was served
    shipped = json.loads(LAYOUT.read_text())
    for path in message_paths(shipped):
        topic, steps = _path_steps(path)
        if topic.startswith("/studio_script/"):
            continue  # the layout's own user script writes it
        assert topic in schemas, path
        node = schemas[topic][1]
        for step in steps:
            node = node["items"] if isinstance(step, int) else node["properties"][step]
    status = [json.loads(p) for _, p in got["messages"]["SCRT_CTRL_STATUS"]]
    rod_paths = [p for p in message_paths(shipped) if '"SCRT_CTRL_STATUS".' in p]
    assert {p.split(".")[1].split("[")[0] for p in rod_paths} == {
        "rod_dipole_cmd", "m_B_cmd", "wheel_fill", "unloading", "detumble_mode"}
    for m in status:
        for p in rod_paths:
            v = m
            for step in _path_steps(p)[1]:
                v = v[step]
            assert isinstance(v, (int, float)), (p, v)
    assert {m["unloading"] for m in status} <= {0, 1} and {m["detumble_mode"] for m in status} == {-1}
    assert any(abs(v) > 1.0 for m in status for v in m["m_B_cmd"])
    # the Rods tab's applied body dipole: the plant's truth, served (healthy rods within their limits here)
    truths = [json.loads(p) for _, p in got["messages"]["SCRT_TRUTH"]]
    assert truths and all(isinstance(v, float) for m in truths for v in m["dipole_B"])
    assert any(abs(v) > 1.0 for m in truths for v in m["dipole_B"])


def _path_steps(path: str) -> tuple[str, list]:
    """(topic, [field, index, ...]) of a Foxglove message path: ``"T".a[2]`` or ``/t/u.a.b``."""
    if path.startswith('"'):
        topic, rest = path[1:path.index('"', 1)], path[path.index('"', 1) + 2:]
    else:
        topic, _, rest = path.partition(".")
    steps: list = []
    for part in rest.split("."):
        name, *idx = part.replace("]", "").split("[")
        steps += [name, *(int(i) for i in idx)]
    return topic, steps


def capped(payloads: list[bytes], periodic: bool = True) -> list[bytes]:
    """The messages sc-rt live's default cap keeps (50 Hz of their own time), computed on the record."""
    lim = RateLimiter(50.0 if periodic else 0.0)
    return [p for p in payloads if lim.keep(json.loads(p).get("t"))]


@pytest.mark.lcm
@pytest.mark.slow  # ~2 s: a short lockstep run
def test_hil_live_on_a_port_in_use_is_one_line_and_the_run_goes_on(tmp_path):
    lcmnet.require()
    port = free_port()
    out = tmp_path / "hil"
    got = _drive(tmp_path, port, ["scenarios/paper_faults.toml", "--duration", "5", "--out", str(out),
                                  "--no-plots", "--live", str(port)], "--occupy")
    assert got["hil_rc"] == 0, got["hil_stderr"]
    lines = [x for x in got["hil_stderr"].splitlines() if "live" in x]
    assert len(lines) == 1 and lines == [got["live_line"].rstrip("\n")], got["hil_stderr"]
    assert lines[0].startswith(f"sc-rt hil: --live {port}: not serving (") and "in use" in lines[0], lines
    assert lines[0].endswith("the run goes on without it")
    assert json.loads((out / "metrics.json").read_text())["steps"] == 51


# --------------------------------------------------------------------------- #
# bad input to sc-rt live: one line, exit 2, nothing started

def test_live_on_a_port_in_use_exits_2_with_one_line(capsys):
    from sc_rt.cli.main import main

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert main(["live", "--port", str(port), "--lcm-url", "memq://"]) == 2
    cap = capsys.readouterr()
    assert cap.out == "" and len(cap.err.splitlines()) == 1, cap.err
    assert cap.err.startswith(f"sc-rt live: error: --port {port}: cannot serve on 127.0.0.1:{port}: ")
    assert "in use" in cap.err


@pytest.mark.parametrize("args, needle", [
    (["--port", "70000"], "argument --port: 70000"),
    (["--port", "x"], "argument --port: 'x'"),
    (["--rate", "SCRT_STATE"], "argument --rate: 'SCRT_STATE'"),
    (["--max-rate", "-1"], "argument --max-rate: -1"),
    (["--lcm-url", "udpm://1.2.3.4:7667"], "argument --lcm-url: udpm://1.2.3.4:7667"),
    (["--host", "203.0.113.7", "--port", "1", "--lcm-url", "memq://"], "--port 1: cannot serve on 203.0.113.7:1"),
])
def test_bad_options_exit_2_naming_the_option_and_value(args, needle, capsys):
    from sc_rt.cli.main import main

    try:
        rc = main(["live", *args])
    except SystemExit as e:
        rc = e.code
    err = capsys.readouterr().err
    assert rc == 2 and len(err.splitlines()) == 1 and needle in err, err


# --------------------------------------------------------------------------- #
# the server in this process, on LCM's in-process bus (memq)

@pytest.fixture
def server(request):
    srv = LiveServer("memq://", port=0, ros2=getattr(request, "param", False)).start()
    stop = threading.Event()
    loop = threading.Thread(target=srv.run, args=(stop.is_set, 0.05), daemon=True)
    loop.start()
    yield srv
    stop.set()
    loop.join(10)
    srv.close()
    assert not loop.is_alive()


def _state(seq: int, t: float) -> sc_rt_lcm.plant_state_t:
    m = sc_rt_lcm.plant_state_t()
    m.seq, m.t, m.sigma_BN, m.omega_BN_B = seq, t, [0.1 + seq * 1e-3, -0.2, 1 / 3], [1e-3, math.pi, -2.5e-17]
    m.wheel_speed = [float(seq), 2.0, -3.0, 4.5]
    return m


async def _until(c: FoxgloveClient, topic: str, pred, timeout: float = 10.0) -> list[dict]:
    """Messages of ``topic`` until one satisfies ``pred`` (all, that one last)."""
    out = []
    while True:
        kind, v = await c.read(timeout)
        assert kind != "closed"
        if kind == "data" and v[0] == topic:
            out.append(json.loads(v[2]))
            if pred(out[-1]):
                return out


def test_garbage_clients_leave_the_server_serving(server):
    async def scenario():
        url = f"ws://127.0.0.1:{server.port}"
        for junk in (b"\x00\xff garbage \r\n\r\n", b"GET / HTTP/1.1\r\nHost: x\r\n\r\n", b"\x16\x03\x01\x00"):
            r, w = await asyncio.wait_for(asyncio.open_connection("127.0.0.1", server.port), 10)
            w.write(junk)
            await w.drain()
            await asyncio.wait_for(r.read(), 10)  # the server answers or closes: never hangs
            w.close()
            await w.wait_closed()
        # the older subprotocol alone is refused at the handshake (HTTP 400): the SDK speaks foxglove.sdk.v1
        with pytest.raises(HTTPClientError) as e:
            await FoxgloveClient.connect(url, subprotocols=("foxglove.websocket.v1",))
        assert e.value.code == 400
        bad = await FoxgloveClient.connect(url)
        await bad.advertised(["SCRT_STATE"])
        for m in (b"\x02\x00\x00", "not json", json.dumps({"op": "nope"}), json.dumps({"op": "subscribe"}),
                  json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 99999}]}),
                  json.dumps({"op": "unsubscribe", "subscriptionIds": [42]})):
            bad.ws.write_message(m, binary=isinstance(m, bytes))
        good = await FoxgloveClient.connect(url)
        assert good.subprotocol == SUBPROTOCOL
        await good.advertised(["SCRT_STATE", "SCRT_CONFIG"])
        cfg = sc_rt_lcm.controller_config_t()
        cfg.scenario = "garbage test"
        server.lc.publish("SCRT_CONFIG", cfg.encode())
        assert server.wait_received(1, 10)
        good.subscribe(["SCRT_STATE"])
        good.subscribe(["SCRT_CONFIG"])  # after the state's: its replay says the bus is listened to
        assert (await _until(good, "SCRT_CONFIG", lambda d: True))[-1]["scenario"] == "garbage test"
        sent = _state(7, 0.7)
        server.lc.publish("SCRT_STATE", sent.encode())
        got = (await _until(good, "SCRT_STATE", lambda d: d["seq"] == 7))[-1]
        assert got == json_of(sent)  # bit for bit
        await bad.close()
        await good.close()

    asyncio.run(scenario())


def test_no_work_without_a_listener_and_the_decimation_end_to_end(server):
    async def scenario():
        c = await FoxgloveClient.connect(f"ws://127.0.0.1:{server.port}")
        await c.advertised(["SCRT_STATE", "SCRT_CONFIG"])
        for k in range(200):  # a client connected, none subscribed: the bus is not even listened to
            server.lc.publish("SCRT_STATE", _state(k, k / 1000).encode())
        server.lc.publish("SCRT_CONFIG", sc_rt_lcm.controller_config_t().encode())
        assert server.wait_received(1, 10)
        assert server.bridge.stats["received"] == 1 and server.bridge.stats["sent"] == 0  # nothing decoded
        c.subscribe(["SCRT_STATE"])
        c.subscribe(["SCRT_CONFIG"])  # the configuration, sent before: replayed to the new subscriber
        await _until(c, "SCRT_CONFIG", lambda d: True)
        assert server.bridge.stats["received"] == 1 and server.bridge.stats["sent"] == 1
        # a 1 kHz channel under the default 50 Hz cap: the states the direct computation keeps
        times = [k / 1000 for k in range(1000)]
        for k, t in enumerate(times):
            server.lc.publish("SCRT_STATE", _state(k, t).encode())
        want = _direct([Fraction(k, 1000) for k in range(1000)], 50.0)
        got = await _until(c, "SCRT_STATE", lambda d: d["seq"] == want[-1])
        assert [d["seq"] for d in got] == want == list(range(0, 1000, 20))
        assert got[3] == json_of(_state(60, 0.06))
        assert server.bridge.stats["ratelimit"] == 1000 - len(want)
        await c.close()

    asyncio.run(scenario())


@pytest.mark.parametrize("server", [True], indirect=True)
def test_ros2_twins_carry_the_same_values_in_cdr(server):
    """--ros2: each topic again as cdr + ros2msg under /ros2/ (what PlotJuggler's Foxglove Bridge client lists)."""
    async def scenario():
        c = await FoxgloveClient.connect(f"ws://127.0.0.1:{server.port}")
        await c.advertised(["/ros2/SCRT_STATE", "/ros2/derived/pointing", "SCRT_CONFIG"])
        ch = c.channels["/ros2/SCRT_STATE"]
        assert (ch["encoding"], ch["schemaEncoding"]) == ("cdr", "ros2msg")
        assert ch["schema"].splitlines() == ["int64 utime", "int64 seq", "int64 session", "float64 t",
                                             "float64[3] sigma_BN", "float64[3] omega_BN_B", "float64[4] wheel_speed"]
        assert "MSG: sc_rt_live/True_sigma_BD_arcsec" in c.channels["/ros2/derived/pointing"]["schema"]
        server.lc.publish("SCRT_CONFIG", sc_rt_lcm.controller_config_t().encode())
        assert server.wait_received(1, 10)
        c.subscribe(["/ros2/SCRT_STATE"])
        c.subscribe(["SCRT_CONFIG"])
        await _until(c, "SCRT_CONFIG", lambda d: True)
        sent = _state(3, 0.125)
        sent.omega_BN_B = [float("nan"), 1e300, -0.0]
        server.lc.publish("SCRT_STATE", sent.encode())
        while True:
            kind, v = await c.read(10)
            if kind == "data" and v[0] == "/ros2/SCRT_STATE":
                break
        data = v[2]
        assert data[:4] == b"\x00\x01\x00\x00" and len(data) == 4 + 4 * 8 + 10 * 8  # header, 4 scalars, 10 doubles
        utime, seq, session, t, *xs = struct.unpack("<qqqd10d", data[4:])
        assert (utime, seq, session) == (sent.utime, sent.seq, sent.session)
        want = [sent.t, *sent.sigma_BN, *sent.omega_BN_B, *sent.wheel_speed]
        got = [t, *xs]
        for a, b in zip(got, want):  # bit for bit; a value that is not finite: NaN (JSON's null)
            assert (math.isnan(a) and not math.isfinite(b)) or struct.pack("<d", a) == struct.pack("<d", b)
        await c.close()

    asyncio.run(scenario())
