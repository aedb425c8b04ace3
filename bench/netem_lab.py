"""A lossy, slow link between the controller and the plant: two network
namespaces joined by a veth pair (as tests/test_robustness.py's cross-host
run), with ``tc netem`` on both ends (both directions), a real-time run, and
what each side counted compared with what netem was configured to do.

Used by bench/bench_netem.py (every case, 30 s each) and tests/test_netem.py
(one short case). Needs root (ip netns, tc; Debian: iproute2).

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
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

__all__ = ["netem_available", "run_case", "binomial_bound", "parse_netem"]


def netem_available() -> str | None:
    """None when tc netem works here, else why not (a kernel without
    CONFIG_NET_SCH_NETEM, no tc, no namespaces)."""
    if shutil.which("tc") is None:
        return "tc not found (Debian: apt-get install iproute2)"
    name = f"scrt-nprobe-{os.getpid()}"
    r = subprocess.run(["ip", "netns", "add", name], capture_output=True)
    if r.returncode != 0:
        return "cannot create network namespaces (needs root and ip netns)"
    try:
        for c in (f"ip -n {name} link add d0 type veth peer name d1", f"ip -n {name} link set d0 up",
                  f"ip netns exec {name} tc qdisc add dev d0 root netem delay 1ms"):
            r = subprocess.run(c.split(), capture_output=True, text=True)
            if r.returncode != 0:
                return f"tc netem not available ({c}: {r.stderr.strip()})"
    finally:
        subprocess.run(["ip", "netns", "del", name], capture_output=True)
    return None


def nft_available() -> str | None:
    """None when nftables can impair a link here (netdev egress: loss,
    duplication, corruption; no delay), else why not."""
    if shutil.which("nft") is None:
        return "nft not found (Debian: apt-get install nftables)"
    name = f"scrt-fprobe-{os.getpid()}"
    if subprocess.run(["ip", "netns", "add", name], capture_output=True).returncode != 0:
        return "cannot create network namespaces (needs root and ip netns)"
    try:
        subprocess.run(["ip", "-n", name, "link", "add", "d0", "type", "veth", "peer", "name", "d1"],
                       capture_output=True)
        r = subprocess.run(["ip", "netns", "exec", name, "nft", "-f", "-"], capture_output=True, text=True,
                           input=_nft_rules("d0", {"loss": 0.01, "duplicate": 0.01, "corrupt": 0.01}, 7667))
        return None if r.returncode == 0 else f"nft egress filtering not available: {r.stderr.strip()}"
    finally:
        subprocess.run(["ip", "netns", "del", name], capture_output=True)


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
    loss / duplicate / corrupt probabilities through nft."""
    if backend == "netem":
        _sh(f"ip netns exec {ns} tc qdisc add dev {dev} root netem {spec}")
        return
    p = parse_netem(spec)
    if p["delay_ms"] or p["jitter_ms"] or p["reorder"]:
        raise ValueError(f"{spec!r}: delay and reordering need tc netem (this kernel: {netem_available()})")
    subprocess.run(["ip", "netns", "exec", ns, "nft", "-f", "-"], input=_nft_rules(dev, p, port), text=True,
                   check=True, capture_output=True)


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


def run_case(work: Path, netem: str | None, *, duration: float = 30.0, rate: float = 100.0,
             scenario: str = "ppc_feasible_100hz", port: int = 7731, tag: str = "",
             backend: str = "netem", auth_key: Path | None = None) -> dict[str, Any]:
    """One real-time run across the veth pair with ``netem`` (None: a clean
    link) on both ends; returns the measured and expected counts."""
    import sc_rt_lcm

    from sc_rt.bus.lcmio import lcm_binary
    from sc_rt.scenario.reader import load_scenario
    from sc_rt.scenario.overrides import with_overrides

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
        auth = ["--auth-key", str(auth_key)] if auth_key else []
        logger = lcm_binary("lcm-logger")
        for ns, log in ((a, log_a), (b, log_b)):
            procs.append(subprocess.Popen(["ip", "netns", "exec", ns, logger, "-q", "-f", "--flush-interval=20",
                                           "--lcm-url", url, str(log)], stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL))
        exe = str(Path(sys.executable).parent / "sc-rt-controller")
        ctl = subprocess.Popen(["ip", "netns", "exec", a, exe, "--config", str(cfg), "--mode", "realtime",
                                "--lcm-url", url, "--summary", str(work / "ctl.json"), *auth],
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
        for p in reversed(procs):  # the controller, then the loggers after their last flush
            if p.poll() is None:
                p.send_signal(signal.SIGTERM if p is procs[-1] else signal.SIGINT)
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
            if p.stderr:
                p.stderr.close()
        subprocess.run(["ip", "netns", "del", a], capture_output=True)
        subprocess.run(["ip", "netns", "del", b], capture_output=True)

    summary = json.loads((work / "ctl.json").read_text())
    emu = json.loads((out / "emulator.json").read_text())
    metrics = json.loads((out / "metrics.json").read_text())
    tr = np.load(out / "trajectory.npz")
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
    res["checks"] = checks
    (work / "netem_result.json").write_text(json.dumps(res, indent=2, default=float) + "\n")
    return res
