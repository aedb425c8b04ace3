"""Truth and estimate named everywhere (issue 39, items 4 and 7).

A star tracker blackout with a 3 deg/h gyro bias and the estimate in the
loop (``ppc_feasible_10hz_sensors`` with ``blackouts = [[10, 1e9]]``, 40 s):
the filter drifts, the law believes it holds a few arcsec while the truth
is 100 arcsec off. Every headline number must be the true error (the truth
against the reference), with the law's own beside it, named:

- metrics.json ``sigma_e_norm``, ``omega_e_norm`` and the pointing maximum,
  and the console's line, against the true errors computed here with numpy
  from the recorded truth (``sigma_BN``, ``omega_BN_B``) and the reference
  (``sigma_DN``, the scenario's omega_d(t)) through rotation matrices, not
  the code's MRP algebra; a law fed the truth says so once;
- ``/derived/pointing`` in the MCAP export and in the live view (a real
  Foxglove client on ``sc-rt hil --live``): the true error row by row equal
  to the one computed here from the run's record, the law's beside it, the
  knowledge error (truth against estimate) too;
- ``sc-rt hil --live`` with a Python law that names its telemetry: the live
  ``/derived/telemetry`` carries the names, though the client subscribed
  after the run's start record was published (item 7).
"""

from __future__ import annotations

import json
import math
import re
import sys
import threading
import tomllib
from pathlib import Path

import numpy as np
import pytest
import sc_rt_lcm
from mcap.reader import make_reader

import lcmnet
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
HERE = Path(__file__).resolve().parent
ARCSEC = 180.0 / math.pi * 3600.0  # [arcsec / rad]
BLACKOUT_S, DURATION_S, RATE_HZ = 10.0, 40.0, 10
ROWS = int(DURATION_S * RATE_HZ) + 1


def blackout_scenario(tmp: Path, measurement: str = "estimate") -> Path:
    """ppc_feasible_10hz_sensors with the star tracker dark from BLACKOUT_S
    on and a 3 deg/h gyro bias per axis ([controller] measurement as given)."""
    text = (ROOT / "scenarios" / "ppc_feasible_10hz_sensors.toml").read_text()
    for pat, new in ((r'(?m)^name = "ppc_feasible_10hz_sensors"$', 'name = "truth_blackout"'),
                     (r"(?m)^blackouts = \[\].*$", f"blackouts = [[{BLACKOUT_S}, 1.0e9]]"),
                     (r"(?m)^bias0 = .*$", "bias0 = [3.0, -3.0, 3.0]"),
                     (r'(?m)^measurement = "\w+"', f'measurement = "{measurement}"')):
        text, n = re.subn(pat, new, text)
        assert n == 1, pat
    p = tmp / f"truth_blackout_{measurement}.toml"
    p.write_text(text)
    return p


# --------------------------------------------------------------------------- #
# the true errors, computed here: rotation matrices, not the code's MRP algebra

def dcm(sigma) -> np.ndarray:
    """[BN] (n, 3, 3) of MRP rows (Schaub & Junkins)."""
    s = np.asarray(sigma, float).reshape(-1, 3)
    out = np.empty((len(s), 3, 3))
    for k, v in enumerate(s):
        x = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
        n2 = v @ v
        out[k] = np.eye(3) + (8.0 * x @ x - 4.0 * (1.0 - n2) * x) / (1.0 + n2) ** 2
    return out


def angle_arcsec(C: np.ndarray) -> np.ndarray:
    """The rotation angle [arcsec] of each DCM, from its trace and skew part."""
    vee = np.stack([C[:, 2, 1] - C[:, 1, 2], C[:, 0, 2] - C[:, 2, 0], C[:, 1, 0] - C[:, 0, 1]], axis=1)
    return np.arctan2(np.linalg.norm(vee, axis=1), np.trace(C, axis1=1, axis2=2) - 1.0) * ARCSEC


def true_pointing(sigma_BN, sigma_DN) -> np.ndarray:
    """The true pointing error [arcsec]: the angle of [BD] = [BN][DN]^T."""
    return angle_arcsec(dcm(sigma_BN) @ np.transpose(dcm(sigma_DN), (0, 2, 1)))


def true_rate_error(path: Path, t, sigma_BN, sigma_DN, omega_BN_B) -> np.ndarray:
    """omega_BN_B - [BD] omega_DN_D(t), omega_d(t) of the file's [guidance]
    (bias + cos cos(freq t) + sin sin(freq t))."""
    g = tomllib.loads(path.read_text())["guidance"]
    t = np.asarray(t, float)[:, None]
    wd = (np.asarray(g["omega_bias"]) + np.asarray(g["omega_cos"]) * np.cos(g["omega_freq"] * t)
          + np.asarray(g["omega_sin"]) * np.sin(g["omega_freq"] * t))
    BD = dcm(sigma_BN) @ np.transpose(dcm(sigma_DN), (0, 2, 1))
    return np.asarray(omega_BN_B) - np.einsum("nij,nj->ni", BD, wd)


def law_pointing(sigma_BD) -> np.ndarray:
    """4 atan |sigma| [arcsec] of the law's own MRPs."""
    return 4.0 * np.arctan(np.linalg.norm(np.asarray(sigma_BD, float), axis=1)) * ARCSEC


# --------------------------------------------------------------------------- #
# metrics.json, the console, report.html

def _sim(tmp: Path, path: Path, capsys) -> tuple[dict, dict, str]:
    from sc_rt.cli.main import main

    out = tmp / path.stem
    assert main(["sim", str(path), "--engine", "cpp", "--duration", str(DURATION_S), "--out", str(out),
                 "--no-plots"]) == 0
    console = capsys.readouterr().out
    with load_traj(out) as z:
        rec = {k: z[k] for k in z.files}
    return json.loads((out / "metrics.json").read_text()), rec, console


def _row(console: str, label: str) -> str:
    """The value column of the console row whose label starts with ``label``."""
    (line,) = [x for x in console.splitlines() if x.strip().startswith(label)]
    return line.strip()[len(label):].strip()


def test_metrics_and_console_headline_the_true_error_the_laws_beside_it(tmp_path, capsys):
    path = blackout_scenario(tmp_path)
    m, rec, console = _sim(tmp_path, path, capsys)
    t = rec["t"]
    true = true_pointing(rec["sigma_BN"], rec["sigma_DN"])
    law = law_pointing(rec["sigma_BD"])
    rate = np.linalg.norm(true_rate_error(path, t, rec["sigma_BN"], rec["sigma_DN"], rec["omega_BN_B"]), axis=1)
    assert m["measurement"] == "estimate"
    marks = {"30": 300, "40": 400}
    assert list(m["sigma_e_norm"]) == list(m["law_sigma_e_norm"]) == list(marks)
    for key, k in marks.items():
        assert t[k] == float(key)
        # metrics hold |sigma|: its angle 4 atan|sigma| is the true error computed here
        assert 4 * math.atan(m["sigma_e_norm"][key]) * ARCSEC == pytest.approx(true[k], rel=1e-9)
        assert 4 * math.atan(m["law_sigma_e_norm"][key]) * ARCSEC == pytest.approx(law[k], rel=1e-12)
        assert m["omega_e_norm"][key] == pytest.approx(rate[k], rel=1e-9)
    # the star tracker is dark from 10 s: the truth drifts away from what the law believes
    assert true[400] > 100.0 and true[400] > 5 * law[400], (true[400], law[400])
    after = t >= 30.0
    assert m["max_pointing_error_arcsec_after_30s"] == pytest.approx(true[after].max(), rel=1e-9)
    assert m["law_max_pointing_error_arcsec_after_30s"] == pytest.approx(law[after].max(), rel=1e-12)
    # the console names the true error and gives the law's on the row below
    lines = console.splitlines()
    (i,) = [j for j, x in enumerate(lines) if x.strip().startswith("true |sigma_BD| at 30/40 s")]
    assert lines[i + 1].strip().startswith("the law's (its estimate)")
    shown = [float(x) for x in _row(console, "true |sigma_BD| at 30/40 s").split(" / ")]
    assert shown == pytest.approx([math.tan(true[k] / ARCSEC / 4) for k in marks.values()], rel=5e-3)
    assert float(_row(console, "true max pointing error after 30 s [arcsec]")) == pytest.approx(
        true[after].max(), rel=5e-3)
    # report.html: the true error, the law's named beside it
    html = (tmp_path / path.stem / "report.html").read_text()
    assert re.search(r"Max true pointing error after 30 s: [\d ]+ arcsec \(the law&#x27;s, from its estimate",
                     html), html[:2000]


def test_a_law_fed_the_truth_says_so_once(tmp_path, capsys):
    path = blackout_scenario(tmp_path, "truth")
    m, rec, console = _sim(tmp_path, path, capsys)
    assert m["measurement"] == "truth" and not [k for k in m if k.startswith("law_") and k.endswith("_norm")]
    true = true_pointing(rec["sigma_BN"], rec["sigma_DN"])
    assert 4 * math.atan(m["sigma_e_norm"]["40"]) * ARCSEC == pytest.approx(true[400], rel=1e-9)
    assert _row(console, "true |sigma_BD| at 30/40 s").endswith("(= the law's: fed the truth)")
    assert "the law's (its estimate)" not in console


# --------------------------------------------------------------------------- #
# /derived/pointing in the MCAP and the live view

def _gated_controller(gate: Path) -> str:
    """sc-rt-controller as an external controller that starts when the client writes to ``gate``."""
    import shlex

    ctl = Path(sys.executable).parent / "sc-rt-controller"
    inner = (f"read go < {shlex.quote(str(gate))} && exec {shlex.quote(str(ctl))} --config \"$SCRT_CONFIG\" "
             "--mode \"$SCRT_MODE\" --lcm-url \"$SCRT_LCM_URL\" --summary \"$SCRT_SUMMARY\"")
    return "sh -c " + shlex.quote(inner)


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _drive(tmp: Path, hil: list[str], *flags: str, env=None) -> dict:
    """tests/fgclient.py in the run's network namespace: the run, and what a client got."""
    res = tmp / "client.json"
    port = _free_port()
    r = lcmnet.run([sys.executable, str(HERE / "fgclient.py"), "--port", str(port), "--out", str(res), *flags,
                    "--timeout", "120", "--", "hil", *hil, "--live", str(port)], timeout=240, env=env)
    assert r.returncode == 0 and res.is_file(), r.stderr
    got = json.loads(res.read_text())
    assert "error" not in got, got.get("error")
    assert got["hil_rc"] == 0, got["hil_stderr"]
    return got


def _mcap_rows(path: Path, topic: str) -> list[bytes]:
    with open(path, "rb") as f:
        return [m.data for _s, ch, m in make_reader(f).iter_messages(log_time_order=False) if ch.topic == topic]


@pytest.fixture(scope="module")
def blackout_live(tmp_path_factory):
    lcmnet.require()
    tmp = tmp_path_factory.mktemp("truth_live")
    path = blackout_scenario(tmp)
    out = tmp / "hil"
    got = _drive(tmp, [str(path), "--mode", "lockstep", "--duration", str(DURATION_S), "--out", str(out),
                       "--no-plots", "--mcap",
                       "--external", _gated_controller(tmp / "gate")],
                 "--gate", str(tmp / "gate"), "--topics", "/derived/pointing", "SCRT_STATE")
    with load_traj(out) as z:
        rec = {k: z[k] for k in z.files}
    return got, out, rec


def _check_pointing(rows: list[dict], rec: dict) -> np.ndarray:
    """Every pointing row against the record's row of its time: the true
    error computed here from the truth and the reference, the law's from its
    sigma_BD, the knowledge error from its estimate. Returns the rows' record indices."""
    t = rec["t"]
    k = np.searchsorted(t, [r["t"] for r in rows])
    assert np.array_equal(t[k], [r["t"] for r in rows])
    true = true_pointing(rec["sigma_BN"][k], rec["sigma_DN"][k])
    know = angle_arcsec(dcm(rec["sigma_BN"][k]) @ np.transpose(dcm(rec["sigma_BN_est"][k]), (0, 2, 1)))
    law = law_pointing(rec["sigma_BD"][k])
    got = {name: np.array([r[name] for r in rows]) for name in
           ("true_error_arcsec", "law_error_arcsec", "knowledge_error_arcsec")}
    np.testing.assert_allclose(got["true_error_arcsec"], true, rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(got["law_error_arcsec"], law, rtol=1e-12, atol=0)
    np.testing.assert_allclose(got["knowledge_error_arcsec"], know, rtol=1e-8, atol=1e-9)
    for r, kk in zip(rows, k):  # per axis: 4 atan of the MRP components of B relative to D
        sbd = rec["sigma_BD"][kk]
        assert [r["law_sigma_BD_arcsec"][a] for a in "xyz"] == pytest.approx(4 * np.arctan(sbd) * ARCSEC, rel=1e-12)
    # by the end the truth is far from what the law believed: they are not one number twice
    assert got["true_error_arcsec"][-1] > 5 * got["law_error_arcsec"][-1] and got["true_error_arcsec"][-1] > 100
    return k


@pytest.mark.lcm
def test_mcap_pointing_is_the_true_error_row_by_row_the_laws_beside_it(blackout_live):
    _got, out, rec = blackout_live
    rows = [json.loads(p) for p in _mcap_rows(out / "run.mcap", "/derived/pointing")]
    # one per controller_status_t (the first state may be answered twice: sent again until answered),
    # each with its truth
    k = _check_pointing(rows, rec)
    assert sorted(set(k.tolist())) == list(range(ROWS)) and len(rows) <= ROWS + 2
    # the bound is judged on the true error, as the run's own bound_ok
    assert [r["bound_ok"] for r in rows] == rec["bound_ok"][k].all(axis=1).tolist()


@pytest.mark.lcm
def test_the_live_view_gives_the_same_true_error(blackout_live):
    got, out, rec = blackout_live
    live = [p.encode() for _, p in got["messages"]["/derived/pointing"]]
    assert len(live) == ROWS  # 10 Hz: under the live cap, every status (the controller waited for the client)
    _check_pointing([json.loads(p) for p in live], rec)
    assert live == _mcap_rows(out / "run.mcap", "/derived/pointing")[-ROWS:]  # the export's very bytes


def test_the_shipped_layout_plots_the_true_and_the_knowledge_error():
    from sc_rt.export.mcap_derived import POINTING_SCHEMA
    from sc_rt.live.layout import LAYOUT

    paths = re.findall(r'"value": "/derived/pointing\.([\w.]+)"', LAYOUT.read_text())
    fields = {p.split(".")[0] for p in paths}
    assert {"true_error_arcsec", "knowledge_error_arcsec", "true_sigma_BD_arcsec"} <= fields
    assert fields <= set(POINTING_SCHEMA["properties"]), fields - set(POINTING_SCHEMA["properties"])


# --------------------------------------------------------------------------- #
# the live server in this process, on LCM's in-process bus (memq), a real client

@pytest.fixture
def server():
    from sc_rt.live.server import LiveServer

    srv = LiveServer("memq://", port=0).start()
    stop = threading.Event()
    loop = threading.Thread(target=srv.run, args=(stop.is_set, 0.05), daemon=True)
    loop.start()
    yield srv
    stop.set()
    loop.join(10)
    srv.close()
    assert not loop.is_alive()


async def _until(c, topic: str, pred, timeout: float = 10.0) -> list[dict]:
    """Messages of ``topic`` until one satisfies ``pred`` (all, that one last)."""
    out = []
    while True:
        kind, v = await c.read(timeout)
        assert kind != "closed"
        if kind == "data" and v[0] == topic:
            out.append(json.loads(v[2]))
            if pred(out[-1]):
                return out


def test_live_pointing_has_the_truth_of_states_it_does_not_send(server):
    """Only /derived/pointing listened to, a 1 kHz bench under the 50 Hz cap:
    the states no client asked for (and those beyond the cap) still give
    their truth to each status sent."""
    import asyncio

    from fgclient import FoxgloveClient

    rng = np.random.default_rng(7)
    sent = []
    for k in range(400):
        st = sc_rt_lcm.plant_state_t()
        st.seq, st.t, st.sigma_BN = k, k / 1000, list(rng.normal(0, 0.05, 3))
        cs = sc_rt_lcm.controller_status_t()
        cs.state_seq, cs.t, cs.mode, cs.cmd_seq = k, k / 1000, 1, k
        cs.sigma_DN, cs.sigma_BD = list(rng.normal(0, 0.05, 3)), list(rng.normal(0, 1e-4, 3))
        sent.append((st, cs))

    async def scenario():
        c = await FoxgloveClient.connect(f"ws://127.0.0.1:{server.port}")
        await c.advertised(["/derived/pointing", "SCRT_CONFIG"])
        server.lc.publish("SCRT_CONFIG", sc_rt_lcm.controller_config_t().encode())
        assert server.wait_received(1, 10)
        c.subscribe(["/derived/pointing"])
        c.subscribe(["SCRT_CONFIG"])  # after the pointing's: its replay says the bus is listened to
        await _until(c, "SCRT_CONFIG", lambda d: True)
        for st, cs in sent:
            server.lc.publish("SCRT_STATE", st.encode())
            server.lc.publish("SCRT_CTRL_STATUS", cs.encode())
        rows = await _until(c, "/derived/pointing", lambda d: d["t"] == 0.38)
        await c.close()
        return rows

    rows = asyncio.run(scenario())
    assert [r["t"] for r in rows] == [k / 1000 for k in range(0, 400, 20)]
    for r in rows:
        st, cs = sent[round(r["t"] * 1000)]
        assert r["true_error_arcsec"] == pytest.approx(true_pointing([st.sigma_BN], [cs.sigma_DN])[0], rel=1e-9)
        assert r["law_error_arcsec"] == pytest.approx(law_pointing([cs.sigma_BD])[0], rel=1e-12)
        assert "knowledge_error_arcsec" not in r  # no estimator (nav false)
    assert server.bridge.stats["idle"] >= len(sent)  # the states: their truth taken, never sent


# --------------------------------------------------------------------------- #
# item 7: the law's telemetry names live

NAMES = ["tau_x [N m]", "tau_norm [N m]", "k"]


def test_live_has_the_telemetry_names_of_a_start_record_sent_before_any_client(server):
    """The run's start record (SCRT_HIL_START, once at its start) comes
    before a client subscribes (sc-rt hil --live starts the server, then the
    run): the server keeps its telemetry names for the statuses that follow."""
    import asyncio

    from sc_rt.wire.startrec import encode_start

    from fgclient import FoxgloveClient

    server.lc.publish("SCRT_CONFIG", sc_rt_lcm.controller_config_t().encode())
    server.lc.publish("SCRT_HIL_START", encode_start({"scenario": "x", "telemetry_names": NAMES}))
    assert server.wait_received(2, 10)  # no client yet: the server heard the configuration and the start

    async def scenario():
        c = await FoxgloveClient.connect(f"ws://127.0.0.1:{server.port}")
        await c.advertised(["/derived/telemetry", "SCRT_CONFIG"])
        c.subscribe(["/derived/telemetry"])
        c.subscribe(["SCRT_CONFIG"])
        await _until(c, "SCRT_CONFIG", lambda d: True)
        cs = sc_rt_lcm.controller_status_t()
        cs.t, cs.n_telemetry, cs.telemetry = 0.1, 3, [1.0, 2.0, 3.0, 0, 0, 0, 0, 0]
        server.lc.publish("SCRT_CTRL_STATUS", cs.encode())
        row = (await _until(c, "/derived/telemetry", lambda d: True))[-1]
        await c.close()
        return row

    row = asyncio.run(scenario())
    assert row["names"] == NAMES and row["values"] == [1.0, 2.0, 3.0]


_GATED_LAW = """
import os

import numpy as np

B1, B2 = 0.05693, 0.2386


class TorquePD:
    # tests/test_law_telemetry.py's law: a PD that names its telemetry; its reset
    # waits on the FIFO $SC_RT_TEST_GATE (the client opens it once it listens)
    name = "torque-pd"
    telemetry_names = ("tau_x [N m]", "tau_norm [N m]", "k")

    def __init__(self, setup):
        self.J0, self.B_pinv = np.asarray(setup.model.J0), np.asarray(setup.model.B_pinv)

    def reset(self, inp):
        gate = os.environ.get("SC_RT_TEST_GATE")
        if gate:
            with open(gate) as f:
                f.readline()

    def step(self, inp):
        a = -(B1 * inp.e.sigma_BD + B2 * inp.e.omega_BD_B)
        tau = self.J0 @ a
        return -self.B_pinv @ -a, {"tau_x": tau[0], "tau_norm [N m]": float(np.linalg.norm(tau)), "k": 3.0}
"""


@pytest.mark.lcm
def test_hil_live_carries_a_python_laws_telemetry_names(tmp_path):
    """sc-rt hil --live with a Python law that names its telemetry; the
    client connects once the run's log holds its start record (so after it
    was sent), and the law waits for the client: /derived/telemetry live
    has the names, as the MCAP export of the run has them."""
    import os

    lcmnet.require()
    law = tmp_path / "named_law.py"
    law.write_text(_GATED_LAW)
    out, gate = tmp_path / "hil", tmp_path / "gate"
    got = _drive(tmp_path, ["paper_faults", "--law", f"{law}:TorquePD", "--mode", "lockstep", "--duration", "5",
                            "--control-rate", "10", "--out", str(out), "--no-plots", "--mcap"],
                 "--gate", str(gate), "--after-file", str(out / "run.lcmlog"),
                 "--topics", "/derived/telemetry", "SCRT_STATE", env={**os.environ, "SC_RT_TEST_GATE": str(gate)})
    assert got["after_file"] and got["gate_opened"]
    live = [json.loads(p) for _, p in got["messages"]["/derived/telemetry"]]
    assert len(live) == 51 and all(r["names"] == NAMES for r in live), live[:1]
    rec = [json.loads(p) for p in _mcap_rows(out / "run.mcap", "/derived/telemetry")]
    assert [r["names"] for r in rec[-51:]] == [NAMES] * 51
    assert [r["values"] for r in live] == [r["values"] for r in rec[-51:]]
