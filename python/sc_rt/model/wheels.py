"""Flight-like reaction wheel torques (issue #28, first part): the limits a
torque-commanded wheel applies to its command and its friction, per wheel,
as pure functions of the command and the wheel speed. The C++ twin is
``sc_rt._core.wheel_applied_torque`` / ``wheel_friction_torque``
(cpp/src/wheels.cpp), bitwise equal (tests/test_wheels.py).

The conventions follow Basilisk's reaction wheel state effector (the C++ of
its ConfigureRWRequests and updateContributions), so that a run can be compared with a Basilisk run of
the same wheel number for number (docs/MODEL.md, "Flight-like wheels"):

- the command is a motor torque u [N m]; in this order: the torque limit
  (|u| <= u_max, u_max <= 0: none), the deadband (|u| < u_min -> 0), the
  power limit (|u Omega| >= P_max -> P_max / |Omega| with u's sign,
  P_max <= 0: none) and the speed limit (|Omega| >= Omega_max and u would
  spin the wheel further up, u Omega >= 0 -> 0; a torque that slows it
  passes; Omega_max <= 0: none);
- friction opposes the speed: Coulomb f_c sign(Omega) + viscous c Omega; with
  the static (Stribeck) part on (beta > 0 and the wheel starting from near
  rest, ``stribeck``), sqrt(2 e) (f_s - f_c) exp(-(Omega/beta)^2 / 2)
  Omega / (beta sqrt 2) + f_c tanh(10 Omega / beta) + c Omega; below the
  limit-cycle speed omega_lc the friction is linear in Omega through its
  value at omega_lc, so that the integration stays smooth near rest;
- the static part is either always on (``stribeck``) or switched per wheel
  by Basilisk's rule at every evaluation of the friction
  (``stribeck_switching``, ``stribeck_switch``): on near rest
  (|Omega| < 0.1 omega_lc), off while the wheel decelerates, a state the run
  carries (sc_rt.model.truth.new_motor).

``TorqueWheels`` gathers the four wheels' limits and friction and the
command interface: a scenario's ``[wheels]`` table (docs/SCENARIOS.md) puts
it in ``ActuatorParams.wheels``, and the plant then integrates the
torque-commanded dynamics (sc_rt.model.torque_plant, sc_rt.model.truth).
With ``command = "acceleration"`` (a law's wheel command in rad/s^2, as the
built-in laws give it) the drive turns the command into a motor torque with
``wheel_torque_command`` (the twin of the core's ``wheel_torque_command``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["WheelLimits", "WheelFriction", "TorqueWheels", "COMMANDS", "applied_torque", "friction_torque",
           "stribeck_switch", "wheel_torque_command", "motor_lag"]

#: the wheel command interfaces: a wheel acceleration [rad/s^2] or a motor torque [N m]
COMMANDS = ("acceleration", "torque")


@dataclass(frozen=True)
class WheelLimits:
    """The limits of one torque-commanded wheel (0 or less: none)."""

    u_max: float = 0.0      #: [N m] motor torque limit
    u_min: float = 0.0      #: [N m] deadband: smaller commands give no torque
    p_max: float = 0.0      #: [W] motor power limit on |u Omega|
    omega_max: float = 0.0  #: [rad/s] speed limit


@dataclass(frozen=True)
class WheelFriction:
    """The friction of one wheel (all zero: none)."""

    coulomb: float = 0.0           #: [N m] f_c
    static: float = 0.0            #: [N m] f_s, the breakaway torque (Stribeck)
    beta: float = 0.0              #: [rad/s] Stribeck speed (0: no static part)
    viscous: float = 0.0           #: [N m s] c
    omega_limit_cycle: float = 0.0  #: [rad/s] below it friction is linear in Omega (0: never)


@dataclass(frozen=True)
class TorqueWheels:
    """The four torque-commanded wheels: limits, friction, command interface."""

    limits: tuple[WheelLimits, ...] = (WheelLimits(),) * 4
    friction: tuple[WheelFriction, ...] = (WheelFriction(),) * 4
    #: the static (Stribeck) part of the friction, always on
    stribeck: bool = False
    #: the static part switched per wheel by Basilisk's rule (``stribeck_switch``),
    #: a state the run carries; exclusive with ``stribeck``
    stribeck_switching: bool = False
    #: what the 4 numbers of a wheel command are: "acceleration" [rad/s^2]
    #: (turned into Jw a by the drive) or "torque" [N m]
    command: str = "acceleration"
    #: [s] first-order motor lag time constant per wheel (0: none, the torque follows at once)
    lag: tuple[float, ...] = (0.0,) * 4

    def __post_init__(self) -> None:
        if len(self.limits) != 4 or len(self.friction) != 4:
            raise ValueError(f"TorqueWheels: 4 limits and 4 frictions, got {len(self.limits)} and "
                             f"{len(self.friction)}")
        if len(self.lag) != 4 or not all(isinstance(v, (int, float)) and math.isfinite(v) and v >= 0.0
                                         for v in self.lag):
            raise ValueError(f"TorqueWheels.lag must be 4 times >= 0 [s], got {self.lag!r}")
        if self.stribeck and self.stribeck_switching:
            raise ValueError("TorqueWheels: stribeck (always on) and stribeck_switching (Basilisk's switch) "
                             "exclude each other")
        if self.command not in COMMANDS:
            raise ValueError(f"TorqueWheels.command must be one of {COMMANDS}, got {self.command!r}")
        for i, (lim, f) in enumerate(zip(self.limits, self.friction)):
            for name, v in (*vars(lim).items(), *vars(f).items()):
                if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0.0):
                    raise ValueError(f"TorqueWheels: wheel {i + 1} {name} must be finite and >= 0, got {v!r}")


def wheel_torque_command(u: float, Jw: float, command: str) -> float:
    """The motor torque [N m] a wheel command ``u`` asks of a wheel of spin
    inertia ``Jw`` [kg m^2]: ``Jw u`` for an acceleration command (the
    torque that gives a free wheel the acceleration u), ``u`` for a torque
    command."""
    return Jw * u if command == "acceleration" else u


def motor_lag(c: float, m: float, tau: float, h: float) -> tuple[float, float]:
    """A first-order motor lag over a step of ``h`` [s] toward the torque
    ``c`` from the motor torque ``m`` [N m], time constant ``tau`` [s]:
    (the torque averaged over the step, the torque at its end). The average
    ``c + (m - c) (tau/h) (1 - exp(-h/tau))``, held over the step, gives the
    wheel the exact impulse of the lag; ``tau`` <= 0: (c, c)."""
    if tau <= 0.0:
        return c, c
    d = m - c
    return c + d * (tau / h) * -math.expm1(-h / tau), c + d * math.exp(-h / tau)


def applied_torque(u: float, omega: float, lim: WheelLimits) -> float:
    """The motor torque [N m] the wheel applies for the command ``u`` at the
    speed ``omega`` [rad/s]: torque limit, deadband, power limit, speed
    limit, in that order."""
    if lim.u_max > 0.0:
        if u > lim.u_max:
            u = lim.u_max
        elif u < -lim.u_max:
            u = -lim.u_max
    if abs(u) < lim.u_min:
        u = 0.0
    if lim.p_max > 0.0 and abs(u * omega) >= lim.p_max:
        u = math.copysign(lim.p_max / abs(omega), u)
    if lim.omega_max > 0.0 and abs(omega) >= lim.omega_max and omega * u >= 0.0:
        u = 0.0
    return u


def _friction(omega: float, f: WheelFriction, stribeck: bool) -> float:
    if stribeck:
        b = f.beta
        return (math.sqrt(2.0 * math.e) * (f.static - f.coulomb) * math.exp(-(omega / b) * (omega / b) / 2.0)
                * omega / (b * math.sqrt(2.0)) + f.coulomb * math.tanh(omega * 10.0 / b) + f.viscous * omega)
    sign = 1.0 if omega > 0.0 else -1.0 if omega < 0.0 else 0.0
    return sign * f.coulomb + f.viscous * omega


def friction_torque(omega: float, f: WheelFriction, stribeck: bool = False) -> float:
    """The friction torque [N m] on the wheel at ``omega`` (opposing it):
    Coulomb and viscous, with the static part when ``stribeck`` (and
    beta > 0), linear below the limit-cycle speed."""
    stribeck = stribeck and f.beta > 0.0
    force = _friction(omega, f, stribeck)
    lc = f.omega_limit_cycle
    if lc > 0.0 and abs(omega) < lc:
        force = _friction(lc, f, stribeck) / lc * omega
    return -force


def stribeck_switch(on: bool, omega: float, omega_start: float, f: WheelFriction) -> bool:
    """Basilisk's switch of the static (Stribeck) friction at one evaluation
    of the friction (updateContributions in Basilisk's
    src/simulation/dynamics/reactionWheels/reactionWheelStateEffector.cpp,
    which runs at every derivative call of the integrator).

    Parameters
    ----------
    on : bool
        The switch before this evaluation (carried from the previous one).
    omega : float
        [rad/s] The wheel speed at this evaluation (an RK4 stage's).
    omega_start : float
        [rad/s] The wheel speed at the step's start (Basilisk's omegaBefore).
    f : WheelFriction
        The wheel's friction: ``beta`` and ``omega_limit_cycle``.

    Returns
    -------
    bool
        On when |omega| < 0.1 omega_limit_cycle (near rest), then off when the
        wheel decelerates, sign(omega) = -sign(omega - omega_start) != 0;
        never on with beta <= 0.
    """
    if not f.beta > 0.0:
        return False
    if abs(omega) < 0.1 * f.omega_limit_cycle:
        on = True
    s = (omega > 0.0) - (omega < 0.0)
    d = omega - omega_start
    return on and abs(s - ((d > 0.0) - (d < 0.0))) < 2
