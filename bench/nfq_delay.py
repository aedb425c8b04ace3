"""An NFQUEUE delay line: netem's delay, jitter and reordering for a kernel
without sch_netem (bench/netem_lab.py's "nfqueue" backend).

An iptables rule in a network namespace sends the packets to delay to
NFQUEUE ``--queue-num N``; this program, run in that namespace, reads the
queue over a raw netlink socket (nfnetlink_queue, no library) and gives each
packet its NF_ACCEPT verdict after a delay drawn as ``tc netem`` draws it:

    delay D J [distribution normal]   D + uniform(-J, J) (netem's default), or D + J N(0, 1)
    reorder P [C]                     with probability P (correlation C) at once, else delayed

(netem's correlated draw u = (1 - C) rand + C u_prev, so as netem a
correlation lowers the fraction sent at once: "reorder 25% 50%" sends
about 7 % at once, not 25 %.)

A packet leaves when its verdict is given: packets whose delays cross leave
out of order, through the kernel's own path. Seeded. On SIGTERM or SIGINT it
gives every pending verdict, then writes its record (``--out``, npz), per
packet in order of arrival: the packet id, the arrival, due and verdict
times (CLOCK_MONOTONIC ns), the rank of its verdict, and the LCM datagram's
channel, sequence number and message bytes, so an analysis can compare what
was done with what each receiver counted.

    python bench/nfq_delay.py --queue 7 --delay-ms 2 --jitter-ms 1 --seed 1 --out rec.npz
"""

from __future__ import annotations

import argparse
import heapq
import os
import random
import select
import signal
import socket
import struct
import sys
import time

NETLINK_NETFILTER = 12
NFNL_SUBSYS_QUEUE = 3
NFQNL_MSG_PACKET, NFQNL_MSG_VERDICT, NFQNL_MSG_CONFIG = 0, 1, 2
NFQA_CFG_CMD, NFQA_CFG_PARAMS, NFQA_CFG_QUEUE_MAXLEN = 1, 2, 3
NFQNL_CFG_CMD_BIND = 1
NFQNL_COPY_PACKET = 2
NFQA_PACKET_HDR, NFQA_VERDICT_HDR, NFQA_PAYLOAD = 1, 2, 10
NLMSG_ERROR = 2
NLM_F_REQUEST, NLM_F_ACK = 1, 4
NF_ACCEPT = 1
LCM_SHORT = 0x4C433032  # "LC02": an LCM datagram with one whole message

_NLH = struct.Struct("=IHHII")  # nlmsghdr: len, type, flags, seq, pid
_NFG = struct.Struct("=BBH")  # nfgenmsg: family, version, res_id (big endian)
_NLA = struct.Struct("=HH")  # nlattr: len, type


def _attr(kind: int, payload: bytes) -> bytes:
    raw = _NLA.pack(_NLA.size + len(payload), kind) + payload
    return raw + b"\0" * (-len(raw) % 4)


def _msg(kind: int, queue: int, attrs: bytes, flags: int = NLM_F_REQUEST, seq: int = 0) -> bytes:
    body = _NFG.pack(socket.AF_UNSPEC, 0, socket.htons(queue)) + attrs
    return _NLH.pack(_NLH.size + len(body), (NFNL_SUBSYS_QUEUE << 8) | kind, flags, seq, 0) + body


def _attrs(buf: bytes, off: int, end: int) -> dict[int, bytes]:
    out = {}
    while off + _NLA.size <= end:
        n, kind = _NLA.unpack_from(buf, off)
        if n < _NLA.size:
            break
        out[kind & 0x3FFF] = buf[off + _NLA.size:off + n]
        off += (n + 3) & ~3
    return out


class Queue:
    """One bound nfnetlink queue: its packets (id, payload) and their verdicts."""

    def __init__(self, num: int, copy_range: int = 0xFFFF, maxlen: int = 4096):
        self.num = num
        self.sock = socket.socket(socket.AF_NETLINK, socket.SOCK_RAW, NETLINK_NETFILTER)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        self.sock.bind((0, 0))
        self._config(_attr(NFQA_CFG_CMD, struct.pack("!BxH", NFQNL_CFG_CMD_BIND, socket.AF_INET)), 1)
        self._config(_attr(NFQA_CFG_PARAMS, struct.pack("!IB", copy_range, NFQNL_COPY_PACKET)), 2)
        self._config(_attr(NFQA_CFG_QUEUE_MAXLEN, struct.pack("!I", maxlen)), 3)
        self.sock.setblocking(False)

    def _config(self, attrs: bytes, seq: int) -> None:
        self.sock.send(_msg(NFQNL_MSG_CONFIG, self.num, attrs, NLM_F_REQUEST | NLM_F_ACK, seq))
        buf = self.sock.recv(65536)
        _, kind, _, _, _ = _NLH.unpack_from(buf, 0)
        err = struct.unpack_from("=i", buf, _NLH.size)[0] if kind == NLMSG_ERROR else 0
        if err:
            raise OSError(-err, f"nfnetlink_queue config {seq} on queue {self.num}: {os.strerror(-err)}")

    def packets(self) -> list[tuple[int, bytes]]:
        """The packets waiting in the socket now (id, IP packet)."""
        out = []
        while True:
            try:
                buf = self.sock.recv(1 << 17)
            except BlockingIOError:
                return out
            off = 0
            while off + _NLH.size <= len(buf):
                n, kind, _, _, _ = _NLH.unpack_from(buf, off)
                if n < _NLH.size:
                    break
                if kind == (NFNL_SUBSYS_QUEUE << 8) | NFQNL_MSG_PACKET:
                    a = _attrs(buf, off + _NLH.size + _NFG.size, off + n)
                    if NFQA_PACKET_HDR in a:
                        out.append((struct.unpack_from("!I", a[NFQA_PACKET_HDR])[0], a.get(NFQA_PAYLOAD, b"")))
                off += (n + 3) & ~3

    def accept(self, pid: int) -> None:
        self.sock.send(_msg(NFQNL_MSG_VERDICT, self.num, _attr(NFQA_VERDICT_HDR, struct.pack("!II", NF_ACCEPT, pid))))


def lcm_fields(ip: bytes) -> tuple[str, int, bytes]:
    """(channel, LCM sequence number, message bytes) of a UDP/IPv4 packet
    carrying one whole LCM message, else ("", -1, b"")."""
    if len(ip) < 20 or ip[0] >> 4 != 4:
        return "", -1, b""
    udp = (ip[0] & 15) * 4
    lcm = ip[udp + 8:]
    if len(lcm) < 9 or struct.unpack_from("!I", lcm)[0] != LCM_SHORT:
        return "", -1, b""
    end = lcm.find(b"\0", 8)
    if end < 0:
        return "", -1, b""
    return lcm[8:end].decode("ascii", "replace"), struct.unpack_from("!I", lcm, 4)[0], lcm[end + 1:]


class Delay:
    """netem's draw of a packet's delay [ns]."""

    def __init__(self, delay_ms: float, jitter_ms: float, dist: str, reorder: float, reorder_corr: float,
                 seed: int):
        self.d, self.j, self.dist = delay_ms * 1e6, jitter_ms * 1e6, dist
        self.reorder, self.rho, self.last = reorder, reorder_corr, 0.0
        self.rng = random.Random(seed)

    def draw(self) -> tuple[int, bool]:
        """(delay, sent at once)."""
        if self.reorder:
            u = (1 - self.rho) * self.rng.random() + self.rho * self.last  # netem's correlated draw
            self.last = u
            if u < self.reorder:
                return 0, True
        if self.dist == "normal":
            x = self.d + self.j * self.rng.gauss(0.0, 1.0)
        else:
            x = self.d + self.j * (2 * self.rng.random() - 1)
        return max(int(x), 0), False


def run(q: Queue, delay: Delay, stop: list[bool]) -> dict[str, list]:
    rec: dict[str, list] = {k: [] for k in ("id", "t_in_ns", "t_due_ns", "t_out_ns", "at_once", "channel",
                                            "lcm_seq", "data")}
    due: list[tuple[int, int]] = []  # (due time, index of arrival)
    while True:
        now = time.monotonic_ns()
        timeout = 0.2 if not due else max(due[0][0] - now, 0) / 1e9
        if stop[0]:
            timeout = 0.0
        try:
            select.select([q.sock], [], [], timeout)
        except InterruptedError:
            pass
        t_in = time.monotonic_ns()
        for pid, ip in q.packets():
            d, at_once = delay.draw()
            ch, seq, data = lcm_fields(ip)
            k = len(rec["id"])
            for key, v in zip(rec, (pid, t_in, t_in + d, -1, at_once, ch, seq, data)):
                rec[key].append(v)
            heapq.heappush(due, (t_in + d, k))
        now = time.monotonic_ns()
        while due and (due[0][0] <= now or stop[0]):
            _, k = heapq.heappop(due)
            q.accept(rec["id"][k])
            rec["t_out_ns"][k] = time.monotonic_ns()
        if stop[0] and not due:
            return rec


def save(rec: dict[str, list], path: str) -> None:
    import numpy as np

    data = rec.pop("data")
    lens = np.array([len(b) for b in data], dtype=np.int64)
    t_out = np.array(rec["t_out_ns"], dtype=np.int64)
    # the rank of each packet's verdict: the order in which they left
    rank = np.empty(len(t_out), dtype=np.int64)
    rank[np.argsort(t_out, kind="stable")] = np.arange(len(t_out))
    np.savez(path, id=np.array(rec["id"], dtype=np.uint32), t_in_ns=np.array(rec["t_in_ns"], dtype=np.int64),
             t_due_ns=np.array(rec["t_due_ns"], dtype=np.int64), t_out_ns=t_out, out_rank=rank,
             at_once=np.array(rec["at_once"], dtype=bool), channel=np.array(rec["channel"], dtype=str),
             lcm_seq=np.array(rec["lcm_seq"], dtype=np.int64),
             data_off=np.concatenate([[0], np.cumsum(lens)[:-1]]).astype(np.int64) if len(lens) else lens,
             data_len=lens, data=np.frombuffer(b"".join(data), dtype=np.uint8))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--queue", type=int, required=True)
    ap.add_argument("--delay-ms", type=float, default=0.0)
    ap.add_argument("--jitter-ms", type=float, default=0.0)
    ap.add_argument("--distribution", choices=("uniform", "normal"), default="uniform")
    ap.add_argument("--reorder", type=float, default=0.0, help="fraction sent at once")
    ap.add_argument("--reorder-corr", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--cpu", type=int, default=None,
                    help="pin to this CPU: every verdict enters one CPU's backlog, in verdict order")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    if a.cpu is not None:
        os.sched_setaffinity(0, {a.cpu})
    q = Queue(a.queue)
    stop = [False]

    def _stop(*_):
        stop[0] = True

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    print("bound", flush=True)
    rec = run(q, Delay(a.delay_ms, a.jitter_ms, a.distribution, a.reorder, a.reorder_corr, a.seed), stop)
    save(rec, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
