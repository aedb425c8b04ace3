"""A bench run's timing set-up, as planned (sc_rt.plan.run.RunPlan.timing):
how it is scheduled (:class:`TimingSetup`), what "kept real time" means
(:class:`RealtimeLimits`), and :class:`Timing`, which holds them with the
mode, the time scale, the priority, the floor policy and the limits a run
is stopped by. Pure data (sc_rt.hil.floor and sc_rt.logs.timing use them)."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["TimingSetup", "RealtimeLimits", "Timing", "MODES", "CONTROLLER_MEMORY_LIMIT_MB"]

#: how a run is stepped: offline (sc_rt.sim), or the bench's two modes (sc_rt.hil)
MODES = ("offline", "lockstep", "realtime")
#: [MB] the controller process's resident memory beyond which the run stops, invalid
CONTROLLER_MEMORY_LIMIT_MB = 2048.0


@dataclass(frozen=True)
class TimingSetup:
    """How a bench run is scheduled, besides the mode and rate.

    trigger: the controller's, ``event`` (a step on each state's arrival,
    the default) or ``timer`` (its own clock, phase-locked to the state
    arrivals);
    controller_cpu / emulator_cpu: pin each to one CPU (None: the kernel
    places them); spin_us: the emulator polls instead of sleeping for the
    last spin_us before each tick; null_law: the floor's zero controller."""

    trigger: str = "event"
    controller_cpu: int | None = None
    emulator_cpu: int | None = None
    spin_us: float = 100.0
    null_law: bool = False

    def __post_init__(self) -> None:
        if self.trigger not in ("timer", "event"):
            raise ValueError(f"trigger must be timer or event, got {self.trigger!r}")

    def controller_args(self) -> list[str]:
        args = ["--trigger", self.trigger]
        if self.controller_cpu is not None:
            args += ["--cpu", str(self.controller_cpu)]
        return args + (["--null-law"] if self.null_law else [])

    def key(self) -> str:
        cpus = ("" if self.controller_cpu is None and self.emulator_cpu is None
                else f"-cpu{self.controller_cpu}.{self.emulator_cpu}")
        return f"{self.trigger}{cpus}-spin{self.spin_us:g}"


@dataclass(frozen=True)
class RealtimeLimits:
    """What "kept real time" means for a real-time bench run (docs/HIL.md,
    "When a run is valid"), as fractions: deadline misses per controller
    step (``misses``), periods the controller did not step at all
    (``skipped``: the rows it had no step for; a controller that cannot keep
    up, e.g. 886 steps/s at 1 kHz), rows run on the watchdog's zero
    (``dropped``) and stale states per step (``stale``: loose by default,
    because the timer trigger's phase lock takes about two seconds to
    acquire). Against the control period: answers later than one period
    per answer judged (``late``: after the timer's acquisition,
    sc_rt.logs.timing.ACQUIRE_S), the emulator's ticks later than one
    period per row (``late_ticks``), and
    the worst tick's lateness (``stall``, in periods: a plant that stalled).
    ``allowance`` events of each kind are always tolerated, so a short run
    is not judged by one event. ``sc-rt hil --rt-limits``."""

    misses: float = 0.01
    skipped: float = 0.01
    dropped: float = 0.01
    stale: float = 0.5
    late: float = 0.01
    late_ticks: float = 0.01
    stall: float = 25.0  # [periods], not a fraction
    allowance: int = 2


@dataclass(frozen=True)
class Timing:
    """The timing set-up of a run (``sc-rt hil``'s options; an offline run
    uses only ``mode = "offline"``).

    Parameters
    ----------
    mode : {"offline", "lockstep", "realtime"}
        How the run is stepped: offline (sc_rt.sim), or the bench's modes.
    time_scale : float
        [-] real time: simulated seconds per wall-clock second.
    realtime_priority : bool, optional
        SCHED_FIFO and mlockall for the controller and the emulator's thread;
        None: in real time yes, in lockstep no (``priority``).
    setup : TimingSetup
        The controller's trigger, the CPUs, the emulator's spin.
    floor : {"auto", "cached", "measure"}, optional
        The bench-floor policy (hil/floor.py); None: no comparison.
    rt_limits : RealtimeLimits
        What "kept real time" means for a real-time run.
    start_timeout : float, optional
        [s] how long an external controller may take to answer (None: its default).
    controller_memory_limit_mb : float
        [MB] the controller's resident memory beyond which the run stops, invalid.
    """

    mode: str = "offline"
    time_scale: float = 1.0
    realtime_priority: bool | None = None
    setup: TimingSetup = field(default_factory=TimingSetup)
    floor: str | None = None
    rt_limits: RealtimeLimits = field(default_factory=RealtimeLimits)
    start_timeout: float | None = None
    controller_memory_limit_mb: float = CONTROLLER_MEMORY_LIMIT_MB

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        if self.floor not in (None, "auto", "cached", "measure"):
            raise ValueError(f"floor must be auto, cached, measure or None, got {self.floor!r}")

    @property
    def priority(self) -> bool:
        """Whether the run asks for real-time priority (the default: in real time)."""
        return self.mode == "realtime" if self.realtime_priority is None else bool(self.realtime_priority)
