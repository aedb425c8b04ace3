"""A lossy, slow link between the controller and the plant: two network
namespaces joined by a veth pair (as tests/test_robustness.py's cross-host
run), with ``tc netem`` on both ends (both directions), a real-time run, and
what each side counted compared with what netem was configured to do.

Used by bench/bench_netem.py (every case, 30 s each) and tests/test_netem.py
(one short case). Needs root (ip netns, tc; Debian: iproute2).

Where the kernel has no sch_netem the link is impaired without it
(``backend_for``): loss, duplication and corruption by nftables on the
veth's egress ("nft"), delay, jitter and reordering by an NFQUEUE delay
line ("nfqueue": an iptables-legacy rule queues the sc-rt datagrams at
OUTPUT, bench/nfq_delay.py gives each its verdict after netem's draw of its
delay). The delay line records what it did per packet, so the reordering is
compared with an exact count, not only with a bound.

Per direction the analysis reads the log of a logger on the *receiving*
side (it receives exactly the datagrams the receiving process receives) and
replays the receiver's sequence rule (same seq as the newest: duplicate;
older: out of order) on it, so three counts meet: netem's configuration
(binomial expectation), the receiving process's own counters, and the log.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

__all__ = ["netem_available", "nft_available", "nfqueue_available", "backend_for", "run_case", "binomial_bound",
           "parse_netem", "swap_probability"]


def _in_scratch_netns(tag: str, check: Callable[[str], str | None]) -> str | None:
    """``check(name)`` run with a throwaway network namespace ``name`` (deleted
    afterwards), or why none can be made."""
    name = f"scrt-{tag}probe-{os.getpid()}"
    if subprocess.run(["ip", "netns", "add", name], capture_output=True).returncode != 0:
        return "cannot create network namespaces (needs root and ip netns)"
    try:
        return check(name)
    finally:
        subprocess.run(["ip", "netns", "del", name], capture_output=True)


def netem_available() -> str | None:
    """None when tc netem works here, else why not (a kernel without
    CONFIG_NET_SCH_NETEM, no tc, no namespaces)."""
    if shutil.which("tc") is None:
        return "tc not found (Debian: apt-get install iproute2)"

    def check(name: str) -> str | None:
        for c in (f"ip -n {name} link add d0 type veth peer name d1", f"ip -n {name} link set d0 up",
                  f"ip netns exec {name} tc qdisc add dev d0 root netem delay 1ms"):
            r = subprocess.run(c.split(), capture_output=True, text=True)
            if r.returncode != 0:
                return f"tc netem not available ({c}: {r.stderr.strip()})"
        return None

    return _in_scratch_netns("n", check)


def nft_available() -> str | None:
    """None when nftables can impair a link here (netdev egress: loss,
    duplication, corruption; no delay), else why not."""
    if shutil.which("nft") is None:
        return "nft not found (Debian: apt-get install nftables)"

    def check(name: str) -> str | None:
        subprocess.run(["ip", "-n", name, "link", "add", "d0", "type", "veth", "peer", "name", "d1"],
                       capture_output=True)
        r = subprocess.run(["ip", "netns", "exec", name, "nft", "-f", "-"], capture_output=True, text=True,
                           input=_nft_rules("d0", {"loss": 0.01, "duplicate": 0.01, "corrupt": 0.01}, 7667))
        return None if r.returncode == 0 else f"nft egress filtering not available: {r.stderr.strip()}"

    return _in_scratch_netns("f", check)


def nfqueue_available() -> str | None:
    """None when the NFQUEUE delay line works here (iptables-legacy's
    NFQUEUE target, an nfnetlink queue bound in a namespace), else why not."""
    if shutil.which("iptables-legacy") is None:
        return "iptables-legacy not found (Debian: apt-get install iptables)"

    def check(name: str) -> str | None:
        r = subprocess.run(["ip", "netns", "exec", name, "iptables-legacy", "-t", "mangle", "-A", "OUTPUT",
                            "-p", "udp", "--dport", "7667", "-j", "NFQUEUE", "--queue-num", "9"],
                           capture_output=True, text=True)
        if r.returncode != 0:
            return f"iptables NFQUEUE target not available: {r.stderr.strip()}"
        r = subprocess.run(["ip", "netns", "exec", name, sys.executable, "-c",
                            f"import sys; sys.path.insert(0, {str(HERE)!r}); import nfq_delay; nfq_delay.Queue(9)"],
                           capture_output=True, text=True)
        return None if r.returncode == 0 else f"cannot bind an nfnetlink queue: {r.stderr.strip()[-300:]}"

    return _in_scratch_netns("q", check)


def backend_for(spec: str | None, netem: bool | None = None) -> str:
    """The lab's backend for a netem spec: "netem" where the kernel has it,
    else "nft" (loss, duplicate, corrupt), "nfqueue" (delay, jitter,
    reorder) or both ("nft+nfqueue")."""
    if netem is None:
        netem = netem_available() is None
    if netem:
        return "netem"
    p = parse_netem(spec or "")
    parts = [name for name, keys in (("nft", ("loss", "duplicate", "corrupt")),
                                     ("nfqueue", ("delay_ms", "jitter_ms", "reorder")))
             if any(p[k] for k in keys)]
    return "+".join(parts) or "nft"


def delay_line_args(spec: str) -> list[str]:
    """bench/nfq_delay.py's options for a netem spec: "delay D [J]
    [distribution normal]", "reorder P [C]" (netem: with probability P, C
    correlated, a packet is sent at once; the others are delayed)."""
    p = parse_netem(spec)
    words = spec.split()
    args = ["--delay-ms", f"{p['delay_ms']:g}", "--jitter-ms", f"{p['jitter_ms']:g}",
            "--reorder", f"{p['reorder']:g}"]
    if "reorder" in words:
        i = words.index("reorder")
        if i + 2 < len(words) and words[i + 2].endswith("%"):
            args += ["--reorder-corr", f"{float(words[i + 2].rstrip('%')) / 100:g}"]
    if "distribution" in words:
        args += ["--distribution", words[words.index("distribution") + 1]]
    return args


def swap_probability(spec: str, spacing_s: float) -> float:
    """P(a message leaves after the next one of its channel) when a channel
    sends every ``spacing_s`` s through the delay of ``spec`` (netem's
    draws: delay d + jitter j uniform or normal; reorder r: at once with
    probability r, its correlation neglected). The receiver's rule counts
    message k out of order when a later one arrived first; while the delays'
    spread is below two spacings only k+1 can overtake k:

    both delayed: D_k - D_k+1 > T; uniform jitter: the difference is
      triangular on [-2j, 2j], P = (2j - T)^2 / (8 j^2) for T < 2j, else 0;
      normal jitter: N(0, 2 j^2), P = erfc(T / (2 j)) / 2;
    k delayed, k+1 at once: D_k > T.

    P = (1 - r)^2 P(both) + (1 - r) r P(D > T). At 100 Hz (T = 10 ms) the
    issue's 2 ms +- 1 ms and netem's "delay 2ms reorder 25%" reorder no
    channel (P = 0): only datagrams of different channels cross."""
    p = parse_netem(spec)
    t, d, j, r = spacing_s * 1e3, p["delay_ms"], p["jitter_ms"], p["reorder"]
    normal = "normal" in spec.split()
    if j == 0:
        both, late = 0.0, float(d > t)
    elif normal:
        both = 0.5 * math.erfc(t / (2 * j))
        late = 0.5 * math.erfc((t - d) / (math.sqrt(2) * j))
    else:
        both = (2 * j - t) ** 2 / (8 * j * j) if t < 2 * j else 0.0
        late = min(max((d + j - t) / (2 * j), 0.0), 1.0)
    return (1 - r) ** 2 * both + (1 - r) * r * late


def reorder_bound(n: int, p: float, z: float = 5.0) -> tuple[float, float]:
    """Expected count of out-of-order messages among n and the allowed
    deviation: ``binomial_bound``. The indicators X_k = "k overtaken by k+1"
    are not independent (neighbours share a delay), but while the delays'
    spread is below two spacings X_k and X_k+1 exclude each other (both
    would need D_k - D_k+2 > 2T), so Cov(X_k, X_k+1) = -p^2 and
    Var(sum) = n p (1 - p) - 2 (n - 1) p^2 <= n p (1 - p): the binomial
    bound holds."""
    return binomial_bound(n, p, z)


#: the byte of the UDP payload the nft corruption overwrites: inside every
#: sc-rt message's data after LCM's 8-byte header and the channel name
#: (plant_state_t on SCRT_STATE: a byte of sigma_BN[0])
CORRUPT_OFFSET = 60


def _nft_rules(dev: str, spec: dict[str, float], port: int) -> str:
    """netdev egress rules on dev: drop with p = loss, duplicate a delivered
    datagram with p = duplicate, overwrite one payload byte with p = corrupt
    (the UDP checksum is updated: the receiver gets the corrupted bytes)."""
    def ppm(p: float) -> int:
        return int(round(p * 1_000_000))

    lines = [f"table netdev scrt_impair_{dev} {{", "  chain eg {",
             f'    type filter hook egress device "{dev}" priority 0; policy accept;']
    if spec.get("loss"):
        lines.append(f"    udp dport {port} numgen random mod 1000000 < {ppm(spec['loss'])} drop")
    if spec.get("corrupt"):
        lines.append(f"    udp dport {port} numgen random mod 1000000 < {ppm(spec['corrupt'])} "
                     f"@th,{(8 + CORRUPT_OFFSET) * 8},8 set 0x5a")
    if spec.get("duplicate"):
        lines.append(f'    udp dport {port} numgen random mod 1000000 < {ppm(spec["duplicate"])} dup to "{dev}"')
    return "\n".join(lines + ["  }", "}", ""])


def impair(ns: str, dev: str, spec: str, backend: str, port: int) -> None:
    """Impair dev's egress in namespace ns: a netem spec through tc, or its
    loss / duplicate / corrupt probabilities through nft (the delay line is
    started by ``DelayLine``)."""
    if backend == "netem":
        _sh(f"ip netns exec {ns} tc qdisc add dev {dev} root netem {spec}")
        return
    p = parse_netem(spec)
    if (p["delay_ms"] or p["jitter_ms"] or p["reorder"]) and "nfqueue" not in backend:
        raise ValueError(f"{spec!r}: delay and reordering need tc netem or the nfqueue backend "
                         f"(this kernel: {netem_available()})")
    if "nft" in backend:
        subprocess.run(["ip", "netns", "exec", ns, "nft", "-f", "-"], input=_nft_rules(dev, p, port), text=True,
                       check=True, capture_output=True)


class DelayLine:
    """bench/nfq_delay.py in namespace ns, fed by an iptables-legacy rule:
    the sc-rt datagrams (udp dport = the LCM port) leaving through dev.
    OUTPUT, not POSTROUTING: a multicast datagram with IP_MULTICAST_LOOP
    passes POSTROUTING twice (the copy for the wire and the copy looped back
    to the namespace's own listeners), OUTPUT once, before it is cloned; the
    looped copy is delayed the same (only the namespace's own logger reads
    it)."""

    def __init__(self, ns: str, dev: str, spec: str, port: int, queue: int, record: Path, seed: int, cpu: int):
        self.ns, self.record = ns, record
        self.rule = ["-o", dev, "-p", "udp", "--dport", str(port), "-j", "NFQUEUE", "--queue-num", str(queue)]
        record.unlink(missing_ok=True)
        self.proc = subprocess.Popen(["ip", "netns", "exec", ns, sys.executable, str(HERE / "nfq_delay.py"),
                                      "--queue", str(queue), *delay_line_args(spec), "--seed", str(seed),
                                      "--cpu", str(cpu), "--out", str(record)],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if self.proc.stdout.readline().strip() != "bound":
            self.proc.wait(10)
            raise RuntimeError(f"the delay line did not start: {self.proc.stderr.read()[-2000:]}")
        from soak import lift

        self.sched = lift(self.proc.pid)
        try:
            _sh(f"ip netns exec {ns} iptables-legacy -t mangle -A OUTPUT " + " ".join(self.rule))
        except Exception:
            self.proc.kill()
            self.proc.wait()
            raise

    def stop(self) -> bool:
        """Takes the rule out, then the delay line gives every pending
        verdict and writes its record; whether it was alive until then."""
        alive = self.proc.poll() is None
        subprocess.run(["ip", "netns", "exec", self.ns, "iptables-legacy", "-t", "mangle", "-D", "OUTPUT",
                        *self.rule], capture_output=True)
        if alive:
            self.proc.send_signal(signal.SIGTERM)
        try:
            self.proc.wait(20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.proc.stdout.close()
        self.proc.stderr.close()
        return alive and self.proc.returncode == 0


def parse_netem(spec: str) -> dict[str, float]:
    """The probabilities of a netem spec ("loss 5% duplicate 1% ..."), as fractions."""
    words = spec.split()
    out = {"loss": 0.0, "duplicate": 0.0, "corrupt": 0.0, "reorder": 0.0, "delay_ms": 0.0, "jitter_ms": 0.0}
    for i, w in enumerate(words):
        if w in ("loss", "duplicate", "corrupt", "reorder") and i + 1 < len(words):
            out[w] = float(words[i + 1].rstrip("%")) / 100.0
        if w == "delay" and i + 1 < len(words):
            out["delay_ms"] = float(words[i + 1].rstrip("ms"))
            if i + 2 < len(words) and words[i + 2].endswith("ms"):
                out["jitter_ms"] = float(words[i + 2].rstrip("ms"))
    return out


def binomial_bound(n: int, p: float, z: float = 5.0) -> tuple[float, float]:
    """Expected count of n Bernoulli(p) trials and the allowed deviation:
    z standard deviations (z = 5: a false alarm below 1e-6 per comparison)
    plus 2 for the edges of the counting window."""
    return n * p, z * math.sqrt(max(n * p * (1 - p), 0.0)) + 2.0


def _settle(paths: list[Path], quiet: float = 0.15, limit: float = 3.0) -> None:
    """Until the files have not grown for ``quiet`` s (the loggers wrote what
    the delay lines released last), at most ``limit`` s."""
    def sizes():
        return [q.stat().st_size if q.exists() else 0 for q in paths]

    end, last, since = time.monotonic() + limit, sizes(), time.monotonic()
    while time.monotonic() < end and time.monotonic() - since < quiet:
        time.sleep(0.03)
        now = sizes()
        if now != last:
            last, since = now, time.monotonic()


def _sh(cmd: str) -> None:
    subprocess.run(cmd.split(), check=True, capture_output=True)


def _log_records(path: Path, channel: str, cls) -> list:
    import lcm

    out = []
    if not path.exists():
        return out
    for ev in lcm.EventLog(str(path), "r"):
        if ev.channel != channel:
            continue
        try:
            out.append(cls.decode(ev.data))
        except Exception:  # a corrupted datagram that reached the logger
            out.append(None)
    return out


def _gate(seqs: list[int]) -> dict[str, int]:
    """The receivers' sequence rule on an arrival order: accepted, duplicate, out of order."""
    acc = dup = ooo = 0
    newest = None
    for s in seqs:
        if newest is None or s > newest:
            newest = s
            acc += 1
        elif s == newest:
            dup += 1
        else:
            ooo += 1
    return {"accepted": acc, "duplicate": dup, "out_of_order": ooo}


def _direction(arrivals: list[int], first: int, last: int) -> dict[str, Any]:
    """What one receiver got of the seqs first..last, in its order of arrival."""
    inside = [s for s in arrivals if first <= s <= last]
    uniq = len(set(inside))
    n = last - first + 1
    return {"sent": n, "copies": len(inside), "unique": uniq, "lost": n - uniq,
            "duplicates": len(inside) - uniq, **{f"gate_{k}": v for k, v in _gate(inside).items()}}


def _pct(x: np.ndarray) -> dict[str, float] | None:
    if not len(x):
        return None
    return {"mean": float(x.mean()), "p50": float(np.percentile(x, 50)), "p99": float(np.percentile(x, 99)),
            "max": float(x.max())}


def _recorded(path: Path, channel: str, cls, session: int, first: int, last: int) -> dict[str, Any]:
    """What a delay line did to one channel's messages of one session, seqs
    first..last: the receiver's counts on the order in which they left
    (``_direction``), their delay and the line's own lateness [us]."""
    r = np.load(path)
    order = np.argsort(r["out_rank"], kind="stable")  # arrival indices in the order of leaving
    data, off, n = r["data"], r["data_off"], r["data_len"]
    left, delay, lateness = [], [], []
    for k in order:
        if r["channel"][k] != channel:
            continue
        try:
            m = cls.decode(data[off[k]:off[k] + n[k]].tobytes())
        except Exception:
            continue
        if m.session != session:
            continue
        left.append(m.seq)
        if first <= m.seq <= last:
            delay.append(r["t_out_ns"][k] - r["t_in_ns"][k])
            lateness.append(r["t_out_ns"][k] - r["t_due_ns"][k])
    # every datagram of the namespace's egress (all channels): the ones that
    # left after a datagram that arrived after them
    every = _gate(order.tolist())
    return {**_direction(left, first, last), "delay_us": _pct(np.array(delay) / 1e3),
            "lateness_us": _pct(np.array(lateness) / 1e3), "delays": np.array(delay) / 1e3,
            "all_channels": {"datagrams": int(len(order)), "left_out_of_order": every["out_of_order"],
                             "sent_at_once": int(r["at_once"].sum())}}


def _delay_line_checks(spec: str, rate: float, lines: list, lines_ok: list[bool], summary: dict,
                       emu_counters: dict, to_ctl: dict, to_emu: dict, rec_ctl: dict,
                       rec_emu: dict) -> dict[str, Any]:
    """The delay line's record against the receivers: per direction the
    messages it delayed, the ones it let leave out of order (the exact
    count), the receiving side's log and the receiving process's counter
    (equal up to ``edge``: 3 for the window's first and last messages, which
    a process counts and the seq window leaves out, plus 2 per message its
    side lost), and the analytic expectation (``swap_probability``,
    ``reorder_bound``)."""
    t = 1.0 / rate
    p_swap = swap_probability(spec, t)
    out: dict[str, Any] = {"alive": lines_ok, "sched": [ln.sched for ln in lines], "swap_probability": p_swap,
                           "spacing_s": t}
    checks = {}
    for name, rec, log, counted in (
            ("to_controller", rec_ctl, to_ctl, summary["rejected"]["out_of_order"]),
            ("to_emulator", rec_emu, to_emu, emu_counters.get("out_of_order", 0))):
        d = rec.pop("delays")
        e, tol = reorder_bound(max(rec["unique"] - 1, 0), p_swap)
        edge = 3 + 2 * log["lost"]
        rl = rec["gate_out_of_order"]
        checks[name] = {
            "delayed": rec["copies"], "delay_line_out_of_order": rl, "log_out_of_order": log["gate_out_of_order"],
            "counted_out_of_order": counted, "edge": edge, "expected": e, "expected_tol": tol,
            "expected_ok": abs(rl - e) <= tol,
            "log_agrees": abs(log["gate_out_of_order"] - rl) <= edge,
            "counter_agrees": abs(counted - rl) <= edge,
            # the delay line saw every message the receiver's window holds
            "complete": rec["lost"] == 0,
            "held_over_a_period": int((d > t * 1e6).sum()),
        }
        out[name] = rec
    out["checks"] = checks
    return out


def run_case(work: Path, netem: str | None, *, duration: float = 30.0, rate: float = 100.0,
             scenario: str = "ppc_feasible_100hz", port: int = 7731, tag: str = "",
             backend: str = "netem", auth_key: Path | None = None, seed: int = 1) -> dict[str, Any]:
    """One real-time run across the veth pair with ``netem`` (None: a clean
    link) on both ends; returns the measured and expected counts. backend:
    "netem", "nft", "nfqueue", "nft+nfqueue", or "auto" (``backend_for``);
    seed: the delay lines' draws (A's seed, B's seed + 1)."""
    import sc_rt_lcm

    from sc_rt.wire.lcmio import lcm_binary
    from sc_rt.scenario.reader import load_scenario
    from sc_rt.scenario.overrides import with_overrides

    if backend == "auto":
        backend = backend_for(netem)
    work.mkdir(parents=True, exist_ok=True)
    pid = os.getpid() % 100000
    a, b = f"scrtNA{pid}{tag}", f"scrtNB{pid}{tag}"
    va, vb = f"na{pid}{tag}", f"nb{pid}{tag}"
    url = f"udpm://239.255.76.67:{port}?ttl=1&recv_buf_size=4194304"
    scn = with_overrides(load_scenario(ROOT / "scenarios" / f"{scenario}.toml"), control_rate_hz=rate)
    cfg = work / "cfg.bin"
    cfg.write_bytes(scn.controller_config_msg().encode())
    log_a, log_b = work / "ctl_side.lcmlog", work / "emu_side.lcmlog"
    for p in (log_a, log_b):
        p.unlink(missing_ok=True)
    procs: list[subprocess.Popen] = []
    lines: list[DelayLine] = []
    lines_ok: list[bool] = []
    rec_a, rec_b = work / "delay_line_ctl_side.npz", work / "delay_line_emu_side.npz"
    try:
        for c in (f"ip netns add {a}", f"ip netns add {b}",
                  f"ip link add {va} type veth peer name {vb}",
                  f"ip link set {va} netns {a}", f"ip link set {vb} netns {b}",
                  f"ip -n {a} addr add 10.213.9.1/24 dev {va}", f"ip -n {b} addr add 10.213.9.2/24 dev {vb}",
                  f"ip -n {a} link set lo up", f"ip -n {b} link set lo up",
                  f"ip -n {a} link set {va} up", f"ip -n {b} link set {vb} up",
                  f"ip -n {a} route add 224.0.0.0/4 dev {va}", f"ip -n {b} route add 224.0.0.0/4 dev {vb}"):
            _sh(c)
        if netem:
            impair(a, va, netem, backend, port)
            impair(b, vb, netem, backend, port)
            if "nfqueue" in backend:  # one CPU each: a verdict's datagram enters that CPU's backlog, in order
                ncpu = os.cpu_count() or 1
                lines.append(DelayLine(a, va, netem, port, 1, rec_a, seed, 0))
                lines.append(DelayLine(b, vb, netem, port, 2, rec_b, seed + 1, 1 % ncpu))
        auth = ["--auth-key", str(auth_key)] if auth_key else []
        logger = lcm_binary("lcm-logger")
        for ns, log in ((a, log_a), (b, log_b)):
            procs.append(subprocess.Popen(["ip", "netns", "exec", ns, logger, "-q", "-f", "--flush-interval=20",
                                           "--lcm-url", url, str(log)], stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL))
        exe = str(Path(sys.executable).parent / "sc-rt-controller")
        ctl = subprocess.Popen(["ip", "netns", "exec", a, exe, "--config", str(cfg), "--mode", "realtime",
                                "--trigger", "timer", "--lcm-url", url, "--summary", str(work / "ctl.json"), *auth],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        procs.append(ctl)
        if "mode on" not in ctl.stderr.readline():
            raise RuntimeError("sc-rt-controller did not start")
        # the controller publishes (SAFE, no state yet) from its start: both
        # loggers listen once their logs grow (an event, not a sleep)
        end = time.monotonic() + 60
        while not (log_a.exists() and log_a.stat().st_size and log_b.exists() and log_b.stat().st_size):
            if time.monotonic() > end:
                raise RuntimeError("the loggers did not start")
            time.sleep(0.05)
        # lcm-logger's 30-message LCM queue drops bursts when it is descheduled
        # (bench/soak.py): its threads at SCHED_FIFO, so the logs count the link
        from soak import lift

        lifted = [lift(p.pid) for p in procs[:2]]
        out = work / "emu"
        r = subprocess.run(["ip", "netns", "exec", b, sys.executable, "-m", "sc_rt.cli", "emulator",
                            str(ROOT / "scenarios" / f"{scenario}.toml"), "--mode", "realtime", "--rate", f"{rate:g}",
                            "--duration", f"{duration:g}", "--lcm-url", url, "--out", str(out), *auth],
                           capture_output=True, text=True, timeout=duration * 10 + 120, cwd=ROOT)
        ctl_alive = ctl.poll() is None
        if r.returncode != 0:
            raise RuntimeError(f"emulator failed: {r.stderr[-2000:]}")
    finally:
        # the controller, the delay lines (their pending datagrams leave), then
        # the loggers after their last flush
        for p in reversed(procs):
            if len(procs) > 1 and p is procs[1] and lines:
                lines_ok = [ln.stop() for ln in lines]
                _settle([log_a, log_b])
            if p.poll() is None:
                p.send_signal(signal.SIGTERM if p is procs[-1] and len(procs) > 2 else signal.SIGINT)
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
            if p.stderr:
                p.stderr.close()
        if len(lines_ok) < len(lines):
            lines_ok = [ln.stop() for ln in lines]
        subprocess.run(["ip", "netns", "del", a], capture_output=True)
        subprocess.run(["ip", "netns", "del", b], capture_output=True)

    summary = json.loads((work / "ctl.json").read_text())
    emu = json.loads((out / "emulator.json").read_text())
    metrics = json.loads((out / "metrics.json").read_text())
    from sc_rt.results.record.run import Run

    tr = Run.load(out)  # trajectory.arrow (docs/RECORD.md)
    rows = emu["rows"]
    plant, ctl_session = metrics["plant_session"], metrics["controller_session"]
    # controller side: the states (seq 0..rows-1) as A's logger received them
    st = [m for m in _log_records(log_a, "SCRT_STATE", sc_rt_lcm.plant_state_t)]
    st_bad = sum(1 for m in st if m is None)
    st_seqs = [m.seq for m in st if m is not None and m.session == plant]
    to_ctl = _direction(st_seqs, 0, rows - 1)
    # emulator side: the commands of the emulator's window as B's logger received them
    applied = tr["cmd_seq_applied"]
    applied = applied[applied >= 0]
    c_first, c_last = int(applied.min()), int(applied.max())
    cm = _log_records(log_b, "SCRT_CMD", sc_rt_lcm.wheel_cmd_t)
    cm_bad = sum(1 for m in cm if m is None)
    cm_seqs = [m.seq for m in cm if m is not None and m.session == ctl_session]
    to_emu = _direction(cm_seqs, c_first, c_last)
    # the log keeps everything its logger received: the local publisher's
    # messages without a hole, every command the plant applied
    own_states = {m.seq for m in _log_records(log_b, "SCRT_STATE", sc_rt_lcm.plant_state_t)
                  if m is not None and m.session == plant}
    own_cmds = {m.seq for m in _log_records(log_a, "SCRT_CMD", sc_rt_lcm.wheel_cmd_t)
                if m is not None and m.session == ctl_session}
    log_ok = {
        "emu_side_states_complete": own_states == set(range(rows)),
        "ctl_side_cmds_complete": own_cmds == set(range(min(own_cmds), max(own_cmds) + 1)) if own_cmds else False,
        "applied_cmds_in_log": set(applied.tolist()) <= set(cm_seqs),
    }
    p = parse_netem(netem or "")
    mode = tr["ctrl_mode"]
    safe = mode == 2
    sig = np.linalg.norm(tr["sigma_BD"], axis=1)
    late = tr["t"] >= min(10.0, duration / 2)
    res = {
        "netem": netem or "none", "duration_s": duration, "rate_hz": rate, "rows": rows,
        "expected": p, "controller_alive": ctl_alive, "loggers": lifted,
        "to_controller": {**to_ctl, "undecodable_in_log": st_bad,
                          "controller_received": summary["received"],
                          "controller_auth_failed": summary.get("auth_failed", 0),
                          "controller_rejected": summary["rejected"]},
        "to_emulator": {**to_emu, "undecodable_in_log": cm_bad,
                        "emulator_counters": emu["counters"]},
        "stale": {"controller_stale_steps": summary["stale_states"], "controller_safe_steps": summary["safe_steps"],
                  "steps": summary["steps"], "rows_safe": int(safe.sum()),
                  "cmd_stale_ticks": emu["counters"].get("cmd_stale_ticks", 0),
                  "ends_normal": bool(mode[-1] == 1),
                  "state_age_us": summary["state_age_us"]},
        "log": log_ok,
        "result": {"bound_ok_fraction": float(np.mean(tr["bound_ok"][np.isfinite(tr["bound_ok"])]))
                   if np.any(np.isfinite(tr["bound_ok"])) else None,
                   "first_bound_violation_s": metrics.get("first_bound_violation_s"),
                   "max_sigma_BD_after_10s": float(sig[late].max()) if np.any(late) else None,
                   "finite": metrics.get("finite")},
        "latency_us": {"p50": float(np.nanpercentile(tr["latency_us"], 50)),
                       "p99": float(np.nanpercentile(tr["latency_us"], 99))},
    }
    # expectations per direction: a datagram is lost with p = loss (netem's
    # corruption is counted separately: the receiver's checksum drops it or
    # it arrives undecodable); a delivered one is duplicated with p = duplicate
    checks = {}
    for name, d in (("to_controller", to_ctl), ("to_emulator", to_emu)):
        lost_p = p["loss"] + (1 - p["loss"]) * p["corrupt"]
        e, tol = binomial_bound(d["sent"], lost_p)
        # corrupted datagrams either vanish (counted lost) or arrive broken:
        # the lost count lies between loss-only and loss+corruption expectations
        e_lo, tol_lo = binomial_bound(d["sent"], p["loss"])
        lo, hi = e_lo - tol_lo, e + tol
        ed, told = binomial_bound(d["unique"], p["duplicate"])
        checks[name] = {"lost": d["lost"], "lost_expected": [e_lo, e], "lost_ok": lo <= d["lost"] <= hi,
                        "duplicates": d["duplicates"], "dup_expected": ed,
                        "dup_ok": abs(d["duplicates"] - ed) <= told}
    # the receiving processes' own counters against the log of their side
    rej = summary["rejected"]
    checks["controller_counters_match_log"] = {
        # (a state whose tag fails is counted as auth_failed, not received)
        "received": [summary["received"] + summary.get("auth_failed", 0), to_ctl["copies"] + st_bad],
        "duplicate": [rej["duplicate"], to_ctl["gate_duplicate"]],
        "out_of_order": [rej["out_of_order"], to_ctl["gate_out_of_order"]]}
    c = emu["counters"]
    checks["emulator_counters_match_log"] = {
        "duplicate": [c.get("duplicate", 0), to_emu["gate_duplicate"]],
        "out_of_order": [c.get("out_of_order", 0), to_emu["gate_out_of_order"]]}
    if lines:
        res["delay_line"] = _delay_line_checks(
            netem, rate, lines, lines_ok, summary, emu["counters"], to_ctl, to_emu,
            _recorded(rec_b, "SCRT_STATE", sc_rt_lcm.plant_state_t, plant, 0, rows - 1),
            _recorded(rec_a, "SCRT_CMD", sc_rt_lcm.wheel_cmd_t, ctl_session, c_first, c_last))
        checks["delay_line"] = res["delay_line"]["checks"]
    res["backend"] = backend
    res["checks"] = checks
    (work / "netem_result.json").write_text(json.dumps(res, indent=2, default=float) + "\n")
    return res
