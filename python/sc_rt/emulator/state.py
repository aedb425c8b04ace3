"""What the plant emulator's parts share, and how it is configured.

- ``Options``: the emulator's settings (mode, bus, timing, watchdog,
  scheduling), one frozen value instead of a long keyword list.
- ``Shared``: the few values its parts (the receiver, emulator/receiver.py;
  the publisher, emulator/outbox.py; the loops, emulator/process.py) read
  and write across their boundary: the counters, the wheels' and the rods'
  faults as applied now (a fault command changes them), the run's time, and
  why the run is invalid or stopping. Everything else a part keeps to itself.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from sc_rt.model.actuators import ActuatorParams
from sc_rt.model.rods import Magnetorquers

__all__ = ["Options", "Shared"]


@dataclass(frozen=True)
class Options:
    """How an emulator runs (``Emulator(scn, Options(...))``)."""

    #: "lockstep" (one row per answered state) or "realtime" (a tick per period)
    mode: str = "lockstep"
    #: the LCM URL (``udpm://...?ttl=0``, ``memq://`` for a bus in this process)
    url: str = "memq://"
    #: channel-name prefix (two benches on one URL)
    prefix: str = ""
    #: [Hz] override of the scenario's control rate
    rate: float | None = None
    #: wall clock per simulated second, real time (2.0: twice as fast)
    time_scale: float = 1.0
    #: [s] override of the scenario's duration
    duration: float | None = None
    #: apply fault_cmd_t and rod_fault_cmd_t messages (``sc-rt fault``)
    accept_fault_commands: bool = False
    #: [s] lockstep: wait this long for the answer to a state, ``retries`` times
    cmd_timeout: float = 1.0
    retries: int = 3
    #: lockstep: a state still unanswered after the retries stops the run (sc-rt hil: a failed run,
    #: named); False: the watchdog applies zero and the run goes on (sc-rt emulator, a restartable peer)
    stop_unanswered: bool = False
    #: real time: a command older than this many periods is replaced by zero (None: the scenario's)
    stale_periods: float | None = None
    #: lockstep: wait for the controller's status too (None: when the controller sends them)
    wait_status: bool | None = None
    #: [s] wait this long for a first answer to state 0 (None: no wait)
    start_timeout: float | None = None
    #: HMAC-SHA256 key of the bus (wire/auth.py), None: no authentication
    auth_key: bytes | None = None
    #: [us] real time: poll instead of sleeping for this long before each tick
    spin_us: float = 100.0
    #: the emulator thread's CPU, and SCHED_FIFO + mlockall (emulator/rtproc.py)
    cpu: int | None = None
    realtime_priority: bool = False
    #: freeze the garbage collector while the run lasts
    freeze_gc: bool = True
    #: the C++ plant twin (bitwise the Python model), False: the Python model
    cpp_plant: bool = True
    #: where a run longer than two record chunks writes its rows as it runs
    #: (trajectory.arrow, results/record/store.py); None: a temporary directory
    record_dir: Any = None
    #: rows per record chunk (None: results/record/store.py CHUNK_ROWS)
    record_chunk: int | None = None
    #: lockstep: pace the states by sc-rt-logger's acknowledgements (emulator/logpace.py; sc-rt hil)
    log_paced: bool = False


@dataclass
class Shared:
    """The values the emulator's parts share (module docstring)."""

    counters: Counter
    #: the wheels as applied now (its faults change with fault commands)
    act: ActuatorParams
    #: [s] the run's time of what arrives now (the row being computed)
    t_now: float = 0.0
    #: why the run is invalid (another bench on our channels), None: valid
    invalid: str | None = None
    #: why the run stops early, None: it goes on
    stopped: str | None = None
    #: the fault commands applied or rejected, in order (a wheel's: "wheel"; a rod's: "rod")
    faults_applied: list[dict[str, Any]] = field(default_factory=list)
    #: the plant's magnetorquer rods as applied now (a rod fault command replaces them;
    #: None: the plant has none)
    rods: Magnetorquers | None = None
    #: the seqs of the newest fault commands applied and refused (-1: none), echoed in
    #: each row's plant_truth_t for ``sc-rt fault`` to wait for its own
    fault_seq_applied: int = -1
    fault_seq_refused: int = -1

    def collision(self, reason: str | None) -> None:
        """Another bench on our URL and prefix (emulator/collision.py): the
        run is invalid and stops at the loop's next check."""
        if reason is not None and self.invalid is None:
            self.invalid = reason
            self.counters["bench_collision"] += 1
            if self.stopped is None:
                self.stopped = reason
