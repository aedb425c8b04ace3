"""A Foxglove WebSocket client (the protocol's own: a WebSocket client that
offers the subprotocol, reads serverInfo and advertise, subscribes, and
decodes the binary message-data frames), on tornado's websocket client;
and a driver that runs ``sc-rt hil ... --live PORT`` and records what a
client receives (tests/test_live.py, bench/bench_live.py).

    python tests/fgclient.py --port P --out RESULT.json [--gate FIFO] [--occupy] [--garbage]
        [--after-file FILE] [--topics T ...] [--no-client] [--timeout S] -- HIL ARGS...

Every wait is bounded; nothing synchronises on a sleep: the driver waits
for the run's "live on" line, for the advertisements, for the first state
(which proves the subscription active) before it opens the gate (a FIFO
the run's controller waits on), and reads until the server closes. With
``--after-file`` the client connects only once that file is not empty (the
run's log: its start record, the log's first message, has been published
and logged); a bounded poll of the file's size, the one event a file gives.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

from tornado.websocket import WebSocketClientConnection, websocket_connect

SUBPROTOCOL = "foxglove.sdk.v1"
MESSAGE_DATA = 0x01
_HEAD = struct.Struct("<BIQ")  # opcode, subscription id, log time [ns]


class FoxgloveClient:
    """One connection: its serverInfo, the channels advertised, its subscriptions."""

    def __init__(self, ws: WebSocketClientConnection):
        self.ws = ws
        self.info: dict | None = None
        self.channels: dict[str, dict] = {}  # topic -> advertised channel
        self.subs: dict[int, str] = {}  # subscription id -> topic
        self.other: list[dict] = []  # JSON messages other than serverInfo / advertise

    @classmethod
    async def connect(cls, url: str, subprotocols=(SUBPROTOCOL,), timeout: float = 10.0) -> FoxgloveClient:
        ws = await asyncio.wait_for(websocket_connect(url, subprotocols=list(subprotocols)), timeout)
        return cls(ws)

    @property
    def subprotocol(self) -> str | None:
        return self.ws.selected_subprotocol

    async def read(self, timeout: float):
        """The next frame: ("json", dict), ("data", (topic, log_ns, payload)) or ("closed", None)."""
        m = await asyncio.wait_for(self.ws.read_message(), timeout)
        if m is None:
            return "closed", None
        if isinstance(m, bytes):
            op, sid, log_ns = _HEAD.unpack_from(m)
            assert op == MESSAGE_DATA, op
            return "data", (self.subs[sid], log_ns, m[_HEAD.size:])
        d = json.loads(m)
        if d.get("op") == "serverInfo":
            self.info = d
        elif d.get("op") == "advertise":
            for ch in d["channels"]:
                self.channels[ch["topic"]] = ch
        else:
            self.other.append(d)
        return "json", d

    async def advertised(self, topics, timeout: float = 10.0) -> None:
        """Read until serverInfo and every topic of ``topics`` are advertised."""
        end = time.monotonic() + timeout
        while self.info is None or not set(topics) <= set(self.channels):
            kind, _ = await self.read(max(0.01, end - time.monotonic()))
            assert kind != "closed", "the server closed before advertising"

    def subscribe(self, topics) -> None:
        subs = []
        for topic in topics:
            sid = len(self.subs) + 1
            self.subs[sid] = topic
            subs.append({"id": sid, "channelId": self.channels[topic]["id"]})
        self.ws.write_message(json.dumps({"op": "subscribe", "subscriptions": subs}))

    async def close(self, timeout: float = 10.0) -> None:
        """Close, and read until the server has closed too (the socket released)."""
        self.ws.close()
        end = time.monotonic() + timeout
        while await asyncio.wait_for(self.ws.read_message(), max(0.01, end - time.monotonic())) is not None:
            pass


# --------------------------------------------------------------------------- #
# the driver


def _lines(stream, sink: list, cond: threading.Condition) -> None:
    for line in stream:
        with cond:
            sink.append(line)
            cond.notify_all()
    with cond:
        sink.append(None)  # end of the stream
        cond.notify_all()


def _wait_line(sink: list, cond: threading.Condition, words: tuple[str, ...], timeout: float) -> str | None:
    """The first line holding one of ``words`` (None: the stream ended or the time ran out)."""
    end = time.monotonic() + timeout
    i = 0
    with cond:
        while True:
            while i < len(sink):
                line = sink[i]
                i += 1
                if line is None:
                    return None
                if any(w in line for w in words):
                    return line
            left = end - time.monotonic()
            if left <= 0 or not cond.wait(left):
                return None


def _open_gate(path: str, timeout: float) -> bool:
    """Write a line to the FIFO the controller waits on (bounded: the open blocks until it reads)."""
    done = threading.Event()

    def go():
        with open(path, "w") as f:
            f.write("go\n")
        done.set()

    threading.Thread(target=go, daemon=True).start()
    return done.wait(timeout)


async def garbage(port: int) -> dict:
    """Clients that speak garbage: raw bytes, the older subprotocol alone, and one that
    speaks the right one and then sends junk (kept open: returned, to be closed)."""
    out: dict = {}
    t0 = time.monotonic()
    r, w = await asyncio.wait_for(asyncio.open_connection("127.0.0.1", port), 10)
    w.write(b"\x00\xff not http at all\r\n\r\n")
    await w.drain()
    out["raw_answer"] = (await asyncio.wait_for(r.read(), 10))[:12].decode(errors="replace")
    w.close()
    await w.wait_closed()
    try:
        await FoxgloveClient.connect(f"ws://127.0.0.1:{port}", subprotocols=("foxglove.websocket.v1",))
        out["old_subprotocol"] = "accepted"
    except Exception as e:  # tornado's HTTPClientError: the handshake refused
        out["old_subprotocol"] = getattr(e, "code", repr(e))
    bad = await FoxgloveClient.connect(f"ws://127.0.0.1:{port}")
    for m in (b"\x7f junk", "{not json", json.dumps({"op": "subscribe", "subscriptions": [{"id": 1}]})):
        bad.ws.write_message(m, binary=isinstance(m, bytes))
    out["client"] = bad
    out["seconds"] = time.monotonic() - t0
    return out


async def _client(port: int, topics, gate: str | None, timeout: float, res: dict, junk: bool = False) -> None:
    bad = None
    if junk:
        g = await garbage(port)
        bad = g.pop("client")
        res["garbage"] = g
    c = await FoxgloveClient.connect(f"ws://127.0.0.1:{port}")
    res["subprotocol"] = c.subprotocol
    await c.advertised([t for t in topics if not t.startswith("*")] or ["SCRT_STATE"], timeout=30)
    want = sorted(c.channels) if not topics or topics == ["*"] else topics
    res["server_info"] = c.info
    res["channels"] = c.channels
    c.subscribe(want)
    msgs: dict[str, list] = {t: [] for t in want}
    res["messages"] = msgs
    end = time.monotonic() + timeout
    opened = gate is None
    while time.monotonic() < end:
        kind, v = await c.read(max(0.01, end - time.monotonic()))
        if kind == "closed":
            res["closed"] = True
            break
        if kind != "data":
            continue
        topic, log_ns, payload = v
        msgs[topic].append([log_ns, payload.decode()])
        if topic == "SCRT_STATE" and not opened:  # the subscription is live: the run may start
            res["gate_opened"] = opened = _open_gate(gate, 30)
    res["other"] = c.other
    if "closed" not in res:
        await c.close()
    if bad is not None:
        bad.ws.close()


def _not_empty(path: str, timeout: float) -> bool:
    """Whether ``path`` is a file that is not empty within ``timeout`` seconds (polled every 10 ms)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if os.path.isfile(path) and os.path.getsize(path) > 0:
            return True
        time.sleep(0.01)
    return False


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--gate", help="a FIFO the run's controller waits on, opened after the first state arrives")
    p.add_argument("--occupy", action="store_true", help="hold the port (listening) during the run")
    p.add_argument("--no-client", action="store_true", help="connect no client (the run beside an idle server)")
    p.add_argument("--garbage", action="store_true", help="clients speaking garbage first (fgclient.garbage)")
    p.add_argument("--after-file", help="connect the client only once this file is not empty (the run's log)")
    p.add_argument("--topics", nargs="*", default=["*"])
    p.add_argument("--timeout", type=float, default=120.0)
    p.add_argument("hil", nargs=argparse.REMAINDER)
    a = p.parse_args(argv)
    hil = a.hil[1:] if a.hil[:1] == ["--"] else a.hil
    res: dict = {"port": a.port}
    held = None
    if a.occupy:
        held = socket.socket()
        held.bind(("127.0.0.1", a.port))
        held.listen()
    if a.gate and not os.path.exists(a.gate):
        os.mkfifo(a.gate)
    proc = subprocess.Popen([sys.executable, "-m", "sc_rt.cli", *hil], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    out_lines: list = []
    err_lines: list = []
    cond = threading.Condition()
    threads = [threading.Thread(target=_lines, args=(proc.stdout, out_lines, cond), daemon=True),
               threading.Thread(target=_lines, args=(proc.stderr, err_lines, cond), daemon=True)]
    for t in threads:
        t.start()
    try:
        line = _wait_line(err_lines, cond, ("sc-rt hil: live on", "not serving"), 120)
        res["live_line"] = line
        if line is not None and a.after_file:
            res["after_file"] = _not_empty(a.after_file, 60.0)
        if line is not None and "live on" in line and not a.no_client:
            asyncio.run(_client(a.port, a.topics, a.gate, a.timeout, res, a.garbage))
        proc.wait(timeout=a.timeout)
    except BaseException as e:  # the record says what went wrong; the run is stopped below
        res["error"] = f"{type(e).__name__}: {e}"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for t in threads:
            t.join(10)
        if held is not None:
            held.close()
    res["hil_rc"] = proc.returncode
    res["hil_stdout"] = "".join(x for x in out_lines if x)
    res["hil_stderr"] = "".join(x for x in err_lines if x)
    Path(a.out).write_text(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
