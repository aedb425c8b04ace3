"""``sc-rt fault``: live wheel-fault injection (``fault_cmd_t`` on SCRT_FAULT).

An emulator applies it only when started with ``--accept-fault-commands``
(``sc-rt hil`` / ``sc-rt emulator``): a bench is never faulted by accident.
The emulator records what it applied (``faults_applied`` in timing.json) and
echoes the fault state of every wheel in ``plant_truth_t``.
"""

from __future__ import annotations

import math
import time

import sc_rt_lcm

from sc_rt.bus.lcmio import channel, open_lcm

__all__ = ["FaultArgError", "inject_msg", "clear_msg", "publish"]


class FaultArgError(ValueError):
    """An invalid fault argument (the CLI exits with code 2)."""


def _check_wheel(wheel: int) -> None:
    if not (isinstance(wheel, int) and 1 <= wheel <= 4):
        raise FaultArgError(f"--wheel must be 1..4, got {wheel}")


def _base(wheel: int, action: int) -> sc_rt_lcm.fault_cmd_t:
    m = sc_rt_lcm.fault_cmd_t()
    m.utime = time.time_ns() // 1000
    m.seq = m.utime  # one-shot publisher: the wall clock orders commands
    m.wheel = wheel
    m.action = action
    m.t_end = -1.0
    m.effectiveness = 1.0
    m.rate = 1.0
    return m


def inject_msg(wheel: int, *, effectiveness: float = 1.0, bias: float = 0.0, stuck: bool = False,
               at: float | None = None, until: float | None = None,
               rate: float = 1.0) -> sc_rt_lcm.fault_cmd_t:
    """A validated ACTION_INJECT command. ``at`` is the onset in simulation
    time [s]; None: now (the emulator's current time). ``until``: the end in
    simulation time, None: no end. ``rate`` [1/s]: a of (16)."""
    _check_wheel(wheel)
    for name, v in (("effectiveness", effectiveness), ("bias", bias), ("rate", rate)):
        if not math.isfinite(v):
            raise FaultArgError(f"--{name} must be finite, got {v}")
    if not 0.0 <= effectiveness <= 1.0:
        raise FaultArgError(f"--effectiveness must be in [0, 1], got {effectiveness}")
    if not rate > 0:
        raise FaultArgError(f"--rate must be > 0, got {rate}")
    if at is not None and not (math.isfinite(at) and at >= 0):
        raise FaultArgError(f"--at must be a simulation time >= 0 s, got {at}")
    if until is not None:
        if not (math.isfinite(until) and until >= 0):
            raise FaultArgError(f"--until must be a simulation time >= 0 s, got {until}")
        if at is not None and not until > at:
            raise FaultArgError(f"--until must be after --at, got --at {at} --until {until}")
    m = _base(wheel, sc_rt_lcm.fault_cmd_t.ACTION_INJECT)
    m.now = at is None
    m.t_onset = 0.0 if at is None else float(at)
    m.t_end = -1.0 if until is None else float(until)
    m.effectiveness = float(effectiveness)
    m.bias = float(bias)
    m.rate = float(rate)
    m.stuck = bool(stuck)
    return m


def clear_msg(wheel: int) -> sc_rt_lcm.fault_cmd_t:
    """An ACTION_CLEAR command: the wheel is healthy again from the emulator's
    current time on."""
    _check_wheel(wheel)
    m = _base(wheel, sc_rt_lcm.fault_cmd_t.ACTION_CLEAR)
    m.now = True
    return m


def publish(msg: sc_rt_lcm.fault_cmd_t, url: str, prefix: str = "") -> str:
    """Publish once on ``prefix + SCRT_FAULT``; returns the channel."""
    ch = channel("SCRT_FAULT", prefix)
    open_lcm(url).publish(ch, msg.encode())
    return ch
