"""A hostile LCM publisher for the robustness tests: malformed, truncated,
foreign, replayed and non-finite messages on every channel sc-rt subscribes
to. Run as a script: python fuzz_lcm.py URL N OUT.json [SEED [CHANNELS]]
(CHANNELS: a comma-separated subset of TARGETS, SENSORS and MAGNETIC, default
TARGETS).

It starts only once it has seen the genuine loop running (states and the
controller's commands on the bus, waiting up to START_TIMEOUT_S): a hostile
message before the peers have adopted each other's session could be adopted
in their place, and a fixed sleep is either too long or, on a loaded
machine, too short."""

from __future__ import annotations

import json
import math
import os
import random
import sys
import threading
import time
from collections import Counter, deque

import lcm
import sc_rt_lcm

TARGETS = {  # channel -> the type its subscriber expects
    "SCRT_STATE": sc_rt_lcm.plant_state_t,
    "SCRT_CMD": sc_rt_lcm.wheel_cmd_t,
    "SCRT_CTRL_STATUS": sc_rt_lcm.controller_status_t,
    "SCRT_FAULT": sc_rt_lcm.fault_cmd_t,
}
SENSORS = {  # a [sensors] run's channels, which sc-rt-controller subscribes to
    "SCRT_GYRO": sc_rt_lcm.gyro_t,
    "SCRT_STAR": sc_rt_lcm.star_tracker_t,
    "SCRT_TACH": sc_rt_lcm.tachometer_t,
    "SCRT_MAG": sc_rt_lcm.magnetometer_t,  # a magnetometer's samples ([sensors.magnetometer])
}
MAGNETIC = {  # a run with magnetorquers: the rods' commands and live rod faults, which the emulator subscribes to
    "SCRT_ROD_CMD": sc_rt_lcm.rod_cmd_t,
    "SCRT_ROD_FAULT": sc_rt_lcm.rod_fault_cmd_t,
}
START_TIMEOUT_S = 120.0
OTHER = [sc_rt_lcm.plant_state_t, sc_rt_lcm.wheel_cmd_t, sc_rt_lcm.controller_status_t,
         sc_rt_lcm.plant_truth_t, sc_rt_lcm.fault_cmd_t, sc_rt_lcm.rod_cmd_t, sc_rt_lcm.rod_fault_cmd_t]
FAULTS = (sc_rt_lcm.fault_cmd_t, sc_rt_lcm.rod_fault_cmd_t)


def _alive(pid: int) -> bool:
    """Whether pid runs (a zombie, exited but not reaped, does not)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def valid(cls, rng: random.Random, bad: float | None = None):
    m = cls()
    for slot in cls.__slots__:
        v = getattr(m, slot)
        if isinstance(v, list) and v and isinstance(v[0], float):
            setattr(m, slot, [bad if bad is not None else rng.uniform(-1, 1) for _ in v])
    if hasattr(m, "session"):
        m.session = rng.getrandbits(62)  # never the genuine peer's
    if hasattr(m, "seq"):
        m.seq = rng.randrange(0, 10**6)
    if cls is sc_rt_lcm.magnetometer_t and rng.random() < 0.5:  # a sample, not the ideal field
        m.source, m.frame = m.SOURCE_SENSOR, m.FRAME_SENSOR
    if cls is sc_rt_lcm.fault_cmd_t:
        m.wheel = rng.randrange(1, 5)
        m.action = 1
        m.effectiveness = 0.0
        m.rate = 1.0
        m.now = True
    if cls is sc_rt_lcm.rod_cmd_t:  # mostly the plant's rod count (3 in day_hold), sometimes another
        m.n_rods = 3 if rng.random() < 0.7 else rng.randrange(0, 7)
    if cls is sc_rt_lcm.rod_fault_cmd_t:
        m.rod, m.action, m.kind, m.now = rng.randrange(1, 7), 1, rng.randrange(1, 4), True
        m.dipole = rng.uniform(-50, 50) if m.kind == m.KIND_STUCK else 0.0
    return m


def refusable_rod_fault(rng: random.Random):
    """A rod_fault_cmd_t any emulator is addressed by (session 0) and that the
    plant must refuse whatever its time (``now`` or not): a rod beyond day_hold's
    three, an unknown kind or action, a stuck dipole beyond the rods' 100 A m^2
    or not finite, a dipole on a fault that takes none, an end that is not a
    number. It reaches ``_apply_rod_fault`` (the session check lets it by)."""
    m = valid(sc_rt_lcm.rod_fault_cmd_t, rng)
    m.session, m.rod, m.kind, m.dipole, m.now = 0, rng.randrange(1, 4), m.KIND_DEAD, 0.0, rng.random() < 0.5
    how = rng.randrange(6)
    if how == 0:
        m.rod = rng.randrange(4, 7)
    elif how == 1:
        m.kind = rng.choice((0, 4, 9))
    elif how == 2:
        m.action = rng.choice((0, 3))
    elif how == 3:
        m.kind, m.dipole = m.KIND_STUCK, rng.choice((100.5, -250.0, 1e300, math.nan, math.inf))
    elif how == 4:
        m.dipole = 1.0  # a dead rod takes no dipole
    else:
        m.t_end = math.nan
    return m


def _bad_fault(cls, rng: random.Random, bad: float):
    """A fault command (wheel or rod) with one non-finite or absurd number."""
    m = valid(cls, rng)
    if cls is sc_rt_lcm.fault_cmd_t:
        m.effectiveness = bad
    else:
        setattr(m, rng.choice(("dipole", "t_onset", "t_end")), bad)
    return m


def main(url: str, n: int, out: str, seed: int = 1, channels: str | None = None) -> None:
    rng = random.Random(seed)
    lc = lcm.LCM(url)
    sent: Counter = Counter()
    every = {**TARGETS, **SENSORS, **MAGNETIC}
    targets = TARGETS if not channels else {ch: every[ch] for ch in channels.split(",")}
    genuine = ("SCRT_STATE", "SCRT_CMD", "SCRT_CTRL_STATUS",
               *(c for c in targets if c in SENSORS or c == "SCRT_ROD_CMD"))
    recent: dict[str, deque] = {ch: deque(maxlen=50) for ch in genuine}  # for replays
    for ch in recent:
        lc.subscribe(ch, lambda c, d: recent[c].append(d))
    stop = threading.Event()

    def pump():
        while not stop.is_set():
            lc.handle_timeout(20)

    th = threading.Thread(target=pump, daemon=True)
    th.start()
    t_wait = time.monotonic()
    watched = os.environ.get("SCRT_WAIT_PID")  # the run's process: stop waiting if it dies
    while min(len(recent["SCRT_STATE"]), len(recent["SCRT_CMD"])) < 5:
        if time.monotonic() - t_wait > START_TIMEOUT_S or (watched and not _alive(int(watched))):
            stop.set()
            why = "the run has ended" if watched and not _alive(int(watched)) else f"in {START_TIMEOUT_S} s"
            sys.exit(f"fuzz_lcm: no genuine SCRT_STATE/SCRT_CMD traffic on {url}: {why}")
        time.sleep(0.01)
    waited = time.monotonic() - t_wait
    kinds = ["empty", "random", "truncated", "other_type", "trailing", "nan", "inf", "absurd", "replay"]
    i = 0
    t0 = time.monotonic()
    while i < n:
        ch = rng.choice(list(targets))
        cls = targets[ch]
        kind = rng.choice(kinds + (["refusable"] if ch == "SCRT_ROD_FAULT" else []))
        if kind == "refusable":  # reaches the plant's checks, which must refuse it
            data = refusable_rod_fault(rng).encode()
        elif kind == "empty":
            data = b""
        elif kind == "random":
            data = rng.randbytes(rng.randrange(1, 300))
        elif kind == "truncated":
            full = valid(cls, rng).encode()
            data = full[: rng.randrange(0, len(full))]
        elif kind == "other_type":
            data = valid(rng.choice([c for c in OTHER if c is not cls]), rng).encode()
        elif kind == "trailing":
            data = valid(cls, rng).encode() + rng.randbytes(rng.randrange(1, 40))
        elif kind in ("nan", "inf", "absurd"):
            bad = {"nan": math.nan, "inf": math.inf, "absurd": 1e300}[kind]
            if cls in FAULTS:
                data = _bad_fault(cls, rng, bad).encode()
            else:
                data = valid(cls, rng, bad).encode()
        else:  # replay of a genuine message seen earlier (old sequence number)
            q = recent.get(ch)
            if not q or len(q) < 5:
                continue
            data = q[rng.randrange(0, len(q) - 3)]
        lc.publish(ch, data)
        sent[f"{ch}:{kind}"] += 1
        i += 1
        if i % 500 == 0:
            time.sleep(0.01)  # pace: keep the receivers' socket buffers from overflowing
    stop.set()
    th.join()
    json.dump({"sent": dict(sent), "n": i, "seconds": time.monotonic() - t0, "waited_s": waited},
              open(out, "w"))


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), sys.argv[3], int(sys.argv[4]) if len(sys.argv) > 4 else 1,
         sys.argv[5] if len(sys.argv) > 5 else None)
