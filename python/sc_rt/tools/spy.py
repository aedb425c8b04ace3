"""``sc-rt spy``: a terminal monitor of an LCM bus (no display needed).

Per channel: the type (recognised by its fingerprint among the ``sc_rt_lcm``
types), the rate, the jitter of the arrival intervals, the message count, the
undecodable count, and the newest values of our types (attitude error, wheel
speeds and commands, observer estimate, bound and saturation flags, timing,
fault state). Refreshes in place (ANSI); ``--once --json`` listens for
``--duration`` seconds and prints one snapshot for scripts and tests.

A message is never trusted: it is checked against its fingerprint and size
(fixed-size types) or decoded under guard (others), and anything else is
counted by kind, never fatal.
"""

from __future__ import annotations

import json
import math
import select
import sys
import time
from collections import Counter, deque
from dataclasses import dataclass, field

import numpy as np

from sc_rt.scenario.model import LAW_NAMES
from sc_rt.results.judge.estimation import ARCSEC  # [rad]
from sc_rt.results.judge.metrics import json_safe
from sc_rt.wire.auth import open_bus
from sc_rt.wire.codec import decode_any, identify, numpy_dtype, to_plain
from sc_rt.wire.startrec import decode_start

__all__ = ["Spy", "ChannelStats", "main_loop"]



def _consts(cls, prefix: str) -> dict[int, str]:
    return {getattr(cls, n): n[len(prefix):] for n in dir(cls) if n.startswith(prefix)}


def _flags(cls, value: int) -> list[str]:
    return [name for bit, name in sorted(_consts(cls, "FLAG_").items()) if value & bit]


@dataclass
class ChannelStats:
    name: str
    keep: float  # [s] arrival times kept (the rate window); inf: all
    count: int = 0
    bytes: int = 0
    type: str | None = None
    undecodable: Counter = field(default_factory=Counter)
    times: deque = field(default_factory=deque)
    latest_raw: bytes | None = None
    latest_cls: type | None = None
    latest_msg: object | None = None  # decoded (variable-size types) or lazily

    def add(self, now: float, data: bytes) -> None:
        self.count += 1
        self.bytes += len(data)
        self.times.append(now)
        if math.isfinite(self.keep):
            while self.times and now - self.times[0] > self.keep:
                self.times.popleft()
        cls = identify(data)
        if cls is None and (rec := decode_start(data)) is not None:  # sc-rt hil's start record: what the run is
            self.type, self.latest_raw, self.latest_cls, self.latest_msg = "start record", None, None, rec
            return
        if cls is None:
            self.undecodable["unknown_type"] += 1
            return
        dt = numpy_dtype(cls)
        if dt is not None:
            # fixed layout: fingerprint and size are the whole check; decode lazily
            if len(data) != dt.itemsize:
                self.undecodable["malformed" if len(data) < dt.itemsize else "trailing_bytes"] += 1
                return
            self.latest_raw, self.latest_cls, self.latest_msg = bytes(data), cls, None
        else:
            c, msg = decode_any(data, self.undecodable)
            if msg is None:
                return
            self.latest_raw, self.latest_cls, self.latest_msg = bytes(data), c, msg
        self.type = cls.__name__

    def latest(self):
        if self.latest_msg is None and self.latest_raw is not None:
            self.latest_msg = self.latest_cls.decode(self.latest_raw)
        return self.latest_msg

    def timing(self) -> dict:
        """rate [Hz] over the kept arrivals, mean period, jitter (standard
        deviation of the intervals) and the largest interval [ms]."""
        t = np.fromiter(self.times, float)
        if t.size < 2 or t[-1] <= t[0]:
            return {"rate_hz": None, "period_ms": None, "jitter_ms": None, "max_gap_ms": None}
        d = np.diff(t)
        return {"rate_hz": float((t.size - 1) / (t[-1] - t[0])), "period_ms": float(d.mean() * 1e3),
                "jitter_ms": float(d.std() * 1e3), "max_gap_ms": float(d.max() * 1e3)}

    def snapshot(self) -> dict:
        msg = self.latest()
        out = {"type": self.type, "count": self.count, **self.timing(),
               "undecodable": int(sum(self.undecodable.values())),
               "undecodable_kinds": dict(self.undecodable), "bytes": self.bytes}
        if isinstance(msg, dict):  # the start record
            law = msg.get("law") or {}
            out["summary"] = {"mode": msg.get("mode"), "trigger": msg.get("trigger"),
                              "control_rate_hz": msg.get("control_rate_hz"), "law": law.get("name"),
                              "scenario": msg.get("scenario")}
            out["latest"] = msg
        elif msg is not None:
            out["summary"] = summarize(msg)
            out["latest"] = to_plain(msg)
        return out


def _norm(v) -> float:
    return float(np.linalg.norm(np.asarray(v, float)))


def _nav_summary(msg) -> dict:
    """The estimator's figures of a controller_status_t (a [sensors] run)."""
    if not msg.nav:
        return {}
    p = np.asarray(msg.P_diag, float)
    return {"nav": {"sigma_BN_est": list(msg.sigma_BN_est), "bias_est": list(msg.bias_est),
                    "att_sigma_arcsec": list(np.sqrt(np.maximum(p[0:3], 0.0)) / ARCSEC),
                    "innovation_arcsec": [v / ARCSEC for v in msg.innovation], "nis": msg.nis,
                    "degraded": bool(msg.nav_flags), "gyro_used": msg.gyro_used,
                    "star_used": msg.star_used, "tach_used": msg.tach_used,
                    "sensor_rejected": msg.sensor_rejected}}


def summarize(msg) -> dict:
    """The figures a person watches, per type."""
    name = type(msg).__name__
    if name == "plant_state_t":
        return {"t": msg.t, "seq": msg.seq, "sigma_BN_norm": _norm(msg.sigma_BN),
                "omega_BN_B": list(msg.omega_BN_B), "wheel_speed": list(msg.wheel_speed)}
    if name == "wheel_cmd_t":
        return {"t": msg.t, "seq": msg.seq, "state_seq": msg.state_seq,
                "mode": _consts(type(msg), "MODE_").get(msg.mode, msg.mode),
                "u_cmd": list(msg.u_cmd), "u_sat": list(msg.u_sat), "flags": _flags(type(msg), msg.flags)}
    if name == "controller_status_t":
        import sc_rt_lcm

        return {"t": msg.t, "state_seq": msg.state_seq, "law": LAW_NAMES.get(msg.law, msg.law),
                "mode": _consts(sc_rt_lcm.wheel_cmd_t, "MODE_").get(msg.mode, msg.mode),
                "flags": _flags(sc_rt_lcm.wheel_cmd_t, msg.flags),
                "sigma_BD": list(msg.sigma_BD), "sigma_BD_norm": _norm(msg.sigma_BD),
                "omega_BD_B": list(msg.omega_BD_B), "z1": list(msg.z1), "z2": list(msg.z2),
                "chi": list(msg.chi), "lam": list(msg.lam), "u_sat": list(msg.u_sat),
                "wake_lateness_us": msg.wake_lateness_us, "compute_us": msg.compute_us,
                "state_age_us": msg.state_age_us, "steps": msg.steps,
                "deadline_misses": msg.deadline_misses, "stale_states": msg.stale_states,
                "rejected": msg.rejected, **_nav_summary(msg)}
    if name == "plant_truth_t":
        return {"t": msg.t, "seq": msg.seq, "cmd_seq_applied": msg.cmd_seq_applied,
                "wheel_accel": list(msg.wheel_accel), "delta2": list(msg.delta2),
                "fault_Y": list(msg.fault_Y), "fault_effectiveness": list(msg.fault_effectiveness),
                "fault_bias": list(msg.fault_bias), "fault_stuck": list(msg.fault_stuck),
                "cmd_stale": msg.cmd_stale, "n_rods": msg.n_rods, "rod_dipole": list(msg.rod_dipole[:msg.n_rods]),
                "dipole_B": list(msg.dipole_B), "rod_fault": list(msg.rod_fault[:msg.n_rods])}
    if name == "gyro_t":
        return {"t": msg.t, "seq": msg.seq, "omega": list(msg.omega)}
    if name == "star_tracker_t":
        return {"t_exposure": msg.t_exposure, "t_delivery": msg.t_delivery, "seq": msg.seq,
                "sigma_BN": list(msg.sigma_BN), "lost": msg.lost, "blacked_out": msg.blacked_out}
    if name == "tachometer_t":
        return {"t": msg.t, "seq": msg.seq, "wheel_speed": list(msg.wheel_speed)}
    if name == "magnetometer_t":
        return {"t": msg.t, "seq": msg.seq, "B": list(msg.B), "source": msg.source, "frame": msg.frame}
    if name == "rod_cmd_t":
        return {"t": msg.t, "seq": msg.seq, "state_seq": msg.state_seq, "dipole": list(msg.dipole[:msg.n_rods])}
    if name == "fault_cmd_t":
        return {k: getattr(msg, k) for k in ("seq", "wheel", "action", "now", "t_onset", "t_end",
                                             "effectiveness", "bias", "rate", "stuck")}
    if name == "rod_fault_cmd_t":
        return {k: getattr(msg, k) for k in ("seq", "rod", "action", "kind", "now", "t_onset", "t_end", "dipole")}
    if name == "controller_config_t":
        return {"scenario": msg.scenario, "law": LAW_NAMES.get(msg.law, msg.law),
                "control_rate_hz": msg.control_rate_hz}
    return {}


class Spy:
    """Listens on ``url`` to every channel matching ``channels`` (LCM's
    regex: the whole name must match) and keeps per-channel statistics."""

    def __init__(self, url: str, channels: str = ".*", window: float = 2.0, auth_key: bytes | None = None):
        self.url, self.pattern, self.window = url, channels, window
        #: with a key only verified messages are shown; the others are counted here (wire/auth.py)
        self.auth_failed: Counter = Counter()
        self.lc = open_bus(url, auth_key, self.auth_failed)
        self.stats: dict[str, ChannelStats] = {}
        self.start = time.monotonic()
        # a burst must not be dropped silently by LCM's default queue of 30
        self.lc.subscribe(channels, self._on).set_queue_capacity(100_000)

    def _on(self, ch: str, data: bytes) -> None:
        now = time.monotonic()
        s = self.stats.get(ch)
        if s is None:
            s = self.stats[ch] = ChannelStats(ch, self.window)
        try:
            s.add(now, data)
        except Exception as e:  # noqa: BLE001 - a monitor must outlive any message
            s.undecodable[f"error:{type(e).__name__}"] += 1

    def listen(self, seconds: float) -> None:
        fd = self.lc.fileno()
        end = time.monotonic() + seconds
        while (rem := end - time.monotonic()) > 0:
            if select.select([fd], [], [], min(rem, 0.1))[0]:
                self.lc.handle()

    def snapshot(self) -> dict:
        return {"url": self.url, "channels_regex": self.pattern,
                "listened_s": time.monotonic() - self.start,
                # --auth-key: messages whose tag did not verify, dropped before the statistics
                "auth_failed": int(self.auth_failed["auth_failed"]),
                "channels": {k: self.stats[k].snapshot() for k in sorted(self.stats)}}

    # --- terminal view ---------------------------------------------------
    def render(self) -> str:
        def f(v, fmt="{:.1f}"):
            return "-" if v is None else fmt.format(v)

        def vec(v, fmt="{:+.3e}"):
            return "[" + " ".join(fmt.format(x) for x in v) + "]"

        lines = [f"sc-rt spy  {self.url}  channels {self.pattern!r}  "
                 f"{time.monotonic() - self.start:.0f} s  (Ctrl-C quits)"
                 + ("" if self.stats else "  -- nothing heard yet on this URL"), "",
                 f"{'channel':<22} {'type':<20} {'Hz':>8} {'jitter ms':>10} {'count':>9} {'bad':>6}"]
        for name in sorted(self.stats):
            s = self.stats[name]
            tm = s.timing()
            bad = sum(s.undecodable.values())
            lines.append(f"{name[:22]:<22} {(s.type or '?')[:20]:<20} {f(tm['rate_hz']):>8} "
                         f"{f(tm['jitter_ms'], '{:.3f}'):>10} {s.count:>9} {bad:>6}")
        lines.append("")
        for name in sorted(self.stats):
            msg = self.stats[name].latest()
            if msg is None:
                continue
            m = summarize(msg)
            tn = type(msg).__name__
            if tn == "plant_state_t":
                lines.append(f"{name}: t {m['t']:.3f} s  seq {m['seq']}  |sigma_BN| {m['sigma_BN_norm']:.4f}"
                             f"  wheel speed {vec(m['wheel_speed'], '{:+.1f}')} rad/s")
            elif tn == "wheel_cmd_t":
                lines.append(f"{name}: t {m['t']:.3f} s  {m['mode']}  u_cmd {vec(m['u_cmd'])}  "
                             f"u_sat {vec(m['u_sat'])}  flags {','.join(m['flags']) or '-'}")
            elif tn == "controller_status_t":
                bounds = [x for x in m["flags"] if x.startswith("BOUND")]
                lines.append(f"{name}: t {m['t']:.3f} s  {m['law']} {m['mode']}  |sigma_BD| "
                             f"{m['sigma_BD_norm']:.3e}  sigma_BD {vec(m['sigma_BD'])}  "
                             f"bound {','.join(bounds) or 'ok'}")
                lines.append(f"{'':<{len(name)}}  omega_BD_B {vec(m['omega_BD_B'])}  z2 {vec(m['z2'])}  "
                             f"chi {vec(m['chi'], '{:.2e}')}")
                lines.append(f"{'':<{len(name)}}  wake late {m['wake_lateness_us']:.0f} us  compute "
                             f"{m['compute_us']:.1f} us  state age {m['state_age_us']:.0f} us  steps "
                             f"{m['steps']}  misses {m['deadline_misses']}  stale {m['stale_states']}  "
                             f"rejected {m['rejected']}")
                if "nav" in m:
                    n = m["nav"]
                    lines.append(f"{'':<{len(name)}}  estimate sigma_BN {vec(n['sigma_BN_est'])}  1-sigma "
                                 f"{vec(n['att_sigma_arcsec'], '{:.2f}')} arcsec  innovation "
                                 f"{vec(n['innovation_arcsec'], '{:+.2f}')} arcsec  NIS {n['nis']:.2f}"
                                 f"{'  DEGRADED' if n['degraded'] else ''}  sensors used {n['gyro_used']}/"
                                 f"{n['star_used']}/{n['tach_used']} rejected {n['sensor_rejected']}")
            elif tn == "gyro_t":
                lines.append(f"{name}: t {m['t']:.3f} s  seq {m['seq']}  omega {vec(m['omega'])} rad/s")
            elif tn == "star_tracker_t":
                lines.append(f"{name}: exposed {m['t_exposure']:.3f} s delivered {m['t_delivery']:.3f} s  "
                             f"seq {m['seq']}  sigma_BN {vec(m['sigma_BN'])}  lost {m['lost']}  "
                             f"blacked out {m['blacked_out']}")
            elif tn == "tachometer_t":
                lines.append(f"{name}: t {m['t']:.3f} s  seq {m['seq']}  wheel speed "
                             f"{vec(m['wheel_speed'], '{:+.2f}')} rad/s")
            elif tn == "magnetometer_t":
                frame = " (sensor frame)" if m["frame"] == 1 else ""  # magnetometer_t FRAME_SENSOR
                lines.append(f"{name}: t {m['t']:.3f} s  seq {m['seq']}  B {vec([b * 1e6 for b in m['B']])} uT{frame}")
            elif tn == "rod_cmd_t":
                lines.append(f"{name}: t {m['t']:.3f} s  seq {m['seq']}  state {m['state_seq']}  dipole "
                             f"{vec(m['dipole'], '{:+.2f}')} A m^2")
            elif tn == "plant_truth_t":
                lines.append(f"{name}: t {m['t']:.3f} s  wheel accel {vec(m['wheel_accel'])}  "
                             f"fault Y {vec(m['fault_Y'], '{:.2f}')}  L {vec(m['fault_effectiveness'], '{:.2f}')}"
                             f"  stuck {m['fault_stuck']}  stale {m['cmd_stale']}"
                             + (f"  rods {vec(m['rod_dipole'], '{:+.2f}')} A m^2  rod fault {m['rod_fault']}"
                                if m["n_rods"] else ""))
            elif tn in ("fault_cmd_t", "rod_fault_cmd_t"):
                lines.append(f"{name}: " + "  ".join(f"{k} {v}" for k, v in m.items()))
            elif tn == "controller_config_t":
                lines.append(f"{name}: scenario {m['scenario']}  law {m['law']}  "
                             f"{m['control_rate_hz']:g} Hz")
        return "\n".join(lines)


def main_loop(url: str, channels: str = ".*", once: bool = False, as_json: bool = False,
              duration: float | None = None, refresh: float = 0.5, window: float = 2.0,
              out=sys.stdout, auth_key: bytes | None = None) -> int:
    if once:
        spy = Spy(url, channels, window=math.inf, auth_key=auth_key)
        spy.listen(1.5 if duration is None else duration)
        snap = spy.snapshot()
        out.write(json.dumps(json_safe(snap), indent=2, default=float) + "\n" if as_json else spy.render() + "\n")
        return _heard(spy)
    spy = Spy(url, channels, window=window, auth_key=auth_key)
    end = math.inf if duration is None else time.monotonic() + duration
    tty = out.isatty() if hasattr(out, "isatty") else False
    try:
        if tty:
            out.write("\x1b[?25l\x1b[2J")  # hide the cursor, clear once
        while time.monotonic() < end:
            spy.listen(min(refresh, end - time.monotonic()))
            if as_json:
                out.write(json.dumps(json_safe(spy.snapshot()), default=float) + "\n")
            else:
                text = spy.render()
                if tty:  # redraw in place: home, each line cleared to its end, rest cleared
                    out.write("\x1b[H" + "\n".join(line + "\x1b[K" for line in text.split("\n")) + "\x1b[J")
                else:
                    out.write(text + "\n\n")
            out.flush()
    except KeyboardInterrupt:
        pass
    finally:
        if tty:
            out.write("\x1b[?25h\n")
            out.flush()
    return _heard(spy) if duration is not None else 0


def nothing_heard(spy: Spy) -> str | None:
    """The line that says nothing was heard (None: something was)."""
    if spy.stats:
        return None
    return (f"sc-rt spy: nothing heard on {spy.url} (channels {spy.pattern!r}) in "
            f"{time.monotonic() - spy.start:.1f} s: is a bench running there? (sc-rt hil prints its URL; "
            "--lcm-url or $SCRT_LCM_URL)")


def _heard(spy: Spy) -> int:
    """0 when something was heard; else the line on stderr and 1."""
    line = nothing_heard(spy)
    if line:
        print(line, file=sys.stderr)
    return 1 if line else 0
