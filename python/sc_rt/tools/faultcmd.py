"""``sc-rt fault``: live fault injection, a wheel's (``fault_cmd_t`` on
SCRT_FAULT) or a magnetorquer rod's (``rod_fault_cmd_t`` on SCRT_ROD_FAULT).

An emulator applies them only when started with ``--accept-fault-commands``
(``sc-rt hil`` / ``sc-rt emulator``): a bench is never faulted by accident.
The emulator records what it applied (``faults_applied`` in timing.json) and
echoes the fault state of every wheel and every rod in ``plant_truth_t``
(``fault_effectiveness`` / ``fault_bias`` / ``fault_stuck``; ``rod_fault``
and a stuck rod's ``rod_dipole``): ``send`` waits for that echo (applied,
or not heard by any emulator), and refuses an onset the emulator's clock
(``plant_truth_t.t``) has already passed.
"""

from __future__ import annotations

import math
import select
import time
from collections import Counter
from dataclasses import dataclass

import sc_rt_lcm

from sc_rt.model.rods import MAX_RODS, ROD_FAULTS
from sc_rt.wire.auth import open_bus
from sc_rt.wire.lcmio import channel
from sc_rt.wire.codec import decode_as

__all__ = ["FaultArgError", "inject_msg", "clear_msg", "rod_inject_msg", "rod_clear_msg", "publish", "send", "Sent"]


class FaultArgError(ValueError):
    """An invalid fault argument (the CLI exits with code 2)."""


def _check_wheel(wheel: int) -> None:
    if not (isinstance(wheel, int) and 1 <= wheel <= 4):
        raise FaultArgError(f"--wheel must be 1..4, got {wheel}")


def _check_window(at: float | None, until: float | None) -> None:
    if at is not None and not (math.isfinite(at) and at >= 0):
        raise FaultArgError(f"--at must be a simulation time >= 0 s, got {at}")
    if until is not None:
        if not (math.isfinite(until) and until >= 0):
            raise FaultArgError(f"--until must be a simulation time >= 0 s, got {until}")
        if at is not None and not until > at:
            raise FaultArgError(f"--until must be after --at, got --at {at} --until {until}")


def _base(wheel: int, action: int) -> sc_rt_lcm.fault_cmd_t:
    m = sc_rt_lcm.fault_cmd_t()
    m.utime = time.time_ns() // 1000
    m.seq = m.utime  # one-shot publisher: the wall clock orders commands
    m.wheel = wheel
    m.action = action
    m.t_end = -1.0
    m.effectiveness = 1.0
    m.rate = 1.0
    m.friction = 1.0
    return m


def inject_msg(wheel: int, *, effectiveness: float = 1.0, bias: float = 0.0, stuck: bool = False,
               at: float | None = None, until: float | None = None,
               rate: float = 1.0, friction: float = 1.0) -> sc_rt_lcm.fault_cmd_t:
    """A validated ACTION_INJECT command. ``at`` is the onset in simulation
    time [s]; None: now (the emulator's current time). ``until``: the end in
    simulation time, None: no end. ``rate`` [1/s]: a of (16). ``friction``:
    the friction multiplier (torque-commanded wheels)."""
    _check_wheel(wheel)
    for name, v in (("effectiveness", effectiveness), ("bias", bias), ("rate", rate), ("friction", friction)):
        if not math.isfinite(v):
            raise FaultArgError(f"--{name} must be finite, got {v}")
    if not 0.0 <= effectiveness <= 1.0:
        raise FaultArgError(f"--effectiveness must be in [0, 1], got {effectiveness}")
    if not rate > 0:
        raise FaultArgError(f"--rate must be > 0, got {rate}")
    if not friction >= 0:
        raise FaultArgError(f"--friction must be >= 0, got {friction}")
    if stuck and friction != 1.0:
        raise FaultArgError("a stuck (seized) wheel ignores --friction: give --stuck or --friction")
    _check_window(at, until)
    if effectiveness == 1.0 and bias == 0.0 and friction == 1.0 and not stuck:
        raise FaultArgError("a fault with --effectiveness 1, --bias 0, --friction 1 and not --stuck changes nothing: "
                            "give one of them (sc-rt fault clear heals a wheel)")
    m = _base(wheel, sc_rt_lcm.fault_cmd_t.ACTION_INJECT)
    m.now = at is None
    m.t_onset = 0.0 if at is None else float(at)
    m.t_end = -1.0 if until is None else float(until)
    m.effectiveness = float(effectiveness)
    m.bias = float(bias)
    m.rate = float(rate)
    m.stuck = bool(stuck)
    m.friction = float(friction)
    return m


def clear_msg(wheel: int) -> sc_rt_lcm.fault_cmd_t:
    """An ACTION_CLEAR command: the wheel is healthy again from the emulator's
    current time on."""
    _check_wheel(wheel)
    m = _base(wheel, sc_rt_lcm.fault_cmd_t.ACTION_CLEAR)
    m.now = True
    return m


def _check_rod(rod: int) -> None:
    # the plant's rod count is the emulator's to check (it refuses a rod beyond it, timing.json)
    if not (isinstance(rod, int) and 1 <= rod <= MAX_RODS):
        raise FaultArgError(f"--rod must be 1..{MAX_RODS}, got {rod}")


def _rod_base(rod: int, action: int) -> sc_rt_lcm.rod_fault_cmd_t:
    m = sc_rt_lcm.rod_fault_cmd_t()
    m.utime = time.time_ns() // 1000
    m.seq = m.utime  # one-shot publisher: the wall clock orders commands (one line with the wheels')
    m.rod = rod
    m.action = action
    m.t_end = -1.0
    return m


def rod_inject_msg(rod: int, kind: str, *, dipole: float | None = None, at: float | None = None,
                   until: float | None = None) -> sc_rt_lcm.rod_fault_cmd_t:
    """A validated ACTION_INJECT rod command: ``kind`` "dead", "stuck" or
    "reversed" (model.rods.ROD_FAULTS), ``dipole`` [A m^2] a stuck rod's
    (required for "stuck", refused otherwise), ``at`` the onset in simulation
    time [s] (None: now), ``until`` the end (None: no end)."""
    _check_rod(rod)
    if kind not in ROD_FAULTS:
        raise FaultArgError(f"--kind must be one of {', '.join(ROD_FAULTS)}, got {kind!r}")
    if kind == "stuck" and dipole is None:
        raise FaultArgError("a stuck rod needs its dipole: give --dipole X [A m^2]")
    if kind != "stuck" and dipole is not None:
        raise FaultArgError(f"--dipole is a stuck rod's value: --kind {kind} takes none")
    if dipole is not None and not math.isfinite(dipole):
        raise FaultArgError(f"--dipole must be finite, got {dipole}")
    _check_window(at, until)
    m = _rod_base(rod, sc_rt_lcm.rod_fault_cmd_t.ACTION_INJECT)
    m.kind = ROD_FAULTS[kind]
    m.dipole = 0.0 if dipole is None else float(dipole)
    m.now = at is None
    m.t_onset = 0.0 if at is None else float(at)
    m.t_end = -1.0 if until is None else float(until)
    return m


def rod_clear_msg(rod: int) -> sc_rt_lcm.rod_fault_cmd_t:
    """An ACTION_CLEAR rod command: the rod is healthy again from the
    emulator's current time on."""
    _check_rod(rod)
    m = _rod_base(rod, sc_rt_lcm.rod_fault_cmd_t.ACTION_CLEAR)
    m.now = True
    return m


def _channel_of(msg) -> str:
    return "SCRT_ROD_FAULT" if isinstance(msg, sc_rt_lcm.rod_fault_cmd_t) else "SCRT_FAULT"


def publish(msg, url: str, prefix: str = "", auth_key: bytes | None = None) -> str:
    """Publish once on ``prefix + SCRT_FAULT`` (a rod's: SCRT_ROD_FAULT; tagged
    with auth_key, wire/auth.py); returns the channel."""
    ch = channel(_channel_of(msg), prefix)
    open_bus(url, auth_key).publish(ch, msg.encode())
    return ch


@dataclass
class Sent:
    """What became of a fault command (``send``)."""

    channel: str  # where it was published
    truth_channel: str  # where the echo was awaited
    applied_at: float | None = None  # the emulator's simulation time of the echo
    refused_at: float | None = None  # the emulator's simulation time when it said it refused the command
    emulator_t: float | None = None  # the emulator's time when the command left (None: not heard)


def _echoes(msg: sc_rt_lcm.fault_cmd_t, truth) -> bool:
    """plant_truth_t ``truth`` shows ``msg``'s fault state on its wheel."""
    w = msg.wheel - 1
    if msg.action == sc_rt_lcm.fault_cmd_t.ACTION_CLEAR:
        want = (1.0, 0.0, 0)
    else:
        want = (msg.effectiveness, msg.bias, 1 if msg.stuck else 0)
    got = (truth.fault_effectiveness[w], truth.fault_bias[w], 1 if truth.fault_stuck[w] else 0)
    return got == want


def _rod_echoes(msg: sc_rt_lcm.rod_fault_cmd_t, truth) -> bool:
    """plant_truth_t ``truth`` shows ``msg``'s fault state on its rod at
    ``truth.t``: none after a clear; after an inject the kind, active
    (``rod_fault`` the kind; a stuck rod's ``rod_dipole`` its dipole) inside
    the command's window, outside it minus the kind (``--now``: active from
    the emulator's time of arrival, so a fault the rod had pending, a
    scheduled one, does not pass for it)."""
    r = msg.rod - 1
    if truth.n_rods <= r:
        return False
    state = truth.rod_fault[r]
    if msg.action == sc_rt_lcm.rod_fault_cmd_t.ACTION_CLEAR:
        return state == 0
    ended = 0.0 <= msg.t_end <= truth.t
    active = not ended and (msg.now or msg.t_onset <= truth.t)
    if state != (msg.kind if active else -msg.kind):
        return False
    return not active or msg.kind != sc_rt_lcm.rod_fault_cmd_t.KIND_STUCK or truth.rod_dipole[r] == msg.dipole


def _echoed(msg, truth) -> bool:
    """``truth`` shows the fault state of ``msg``, a wheel's or a rod's command."""
    if isinstance(msg, sc_rt_lcm.rod_fault_cmd_t):
        return _rod_echoes(msg, truth)
    return _echoes(msg, truth)


def answer(msg, truth) -> str | None:
    """What plant_truth_t ``truth`` says of fault command ``msg``: "applied"
    (its ``fault_seq_applied`` is the command's seq; or a later command's, one
    sent after it, with the state ``msg`` asked for: ``_echoed``), "refused"
    (``fault_seq_refused``: the plant could not apply it), None: not yet.
    The seq, not the state alone: a fault the wheel or rod already had (a
    scheduled one pending, the same fault sent again) cannot pass for the
    command's echo."""
    if truth.fault_seq_applied == msg.seq:
        return "applied"
    if truth.fault_seq_refused == msg.seq:
        return "refused"
    if truth.fault_seq_applied > msg.seq and _echoed(msg, truth):
        return "applied"
    return None


def send(msg, url: str, prefix: str = "", timeout: float = 3.0,
         wait: bool = True, auth_key: bytes | None = None) -> Sent:
    """Publish ``msg`` (fault_cmd_t or rod_fault_cmd_t) and wait up to
    ``timeout`` s for an emulator's plant_truth_t to echo its fault state
    (``applied_at``; a wheel's or a rod's). An onset in
    the past of the emulator's clock (heard within the timeout before
    sending) raises FaultArgError and nothing is sent."""
    lc = open_bus(url, auth_key)
    ch, tch = channel(_channel_of(msg), prefix), channel("SCRT_TRUTH", prefix)
    res = Sent(ch, tch)
    seen: list = []
    bad: Counter = Counter()
    lc.subscribe(tch, lambda _c, data: seen.append(decode_as(sc_rt_lcm.plant_truth_t, data, bad)))

    def listen(until: float, stop) -> bool:
        fd = lc.fileno()
        while time.monotonic() < until:
            if select.select([fd], [], [], max(0.0, min(0.05, until - time.monotonic())))[0]:
                lc.handle()
            while seen:
                m = seen.pop(0)
                if m is not None and stop(m):
                    return True
        return False

    if auth_key is not None and msg.session == 0:
        # an authenticated bus: the command names its emulator's session (no replay into another run)
        sch: list = []
        lc.subscribe(channel("SCRT_STATE", prefix),
                     lambda _c, data: sch.append(decode_as(sc_rt_lcm.plant_state_t, data, bad)))
        end = time.monotonic() + min(timeout, 2.0)
        while time.monotonic() < end and not any(m is not None for m in sch):
            lc.handle_timeout(50)
        sessions = [m.session for m in sch if m is not None]
        if not sessions:
            raise FaultArgError(f"--auth-key: no emulator heard on {url} ({channel('SCRT_STATE', prefix)}) "
                                f"to address the command to")
        msg.session = sessions[-1]
    if wait and msg.action == msg.ACTION_INJECT and not msg.now:
        # the emulator's clock, to refuse an onset it has passed (one state period or the timeout)
        t_now: list = []
        listen(time.monotonic() + min(timeout, 1.0), lambda m: bool(t_now.append(m.t)) or True)
        if t_now:
            res.emulator_t = t_now[0]
            if msg.t_onset < t_now[0]:
                raise FaultArgError(f"--at {msg.t_onset:g}: the onset is in the past: the emulator on "
                                    f"{url} ({tch}) is at t = {t_now[0]:.3f} s")
    lc.publish(ch, msg.encode())
    if not wait:
        return res
    hit: list = []
    listen(time.monotonic() + timeout, lambda m: (a := answer(msg, m)) is not None and not hit.append((a, m.t)))
    if hit:
        if hit[0][0] == "applied":
            res.applied_at = hit[0][1]
        else:
            res.refused_at = hit[0][1]
    return res
