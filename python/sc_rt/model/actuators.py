"""Wheel saturation and faults (docs/MODEL.md section 2, (15), (16)).

Per wheel i, command uc_i [rad/s^2]:
    sat(uc_i)     = min(max(uc_i, umin_i), umax_i)
    Omega_dot_i   = sat(uc_i) + Y_i(t) [ (L_i - 1) sat(uc_i) + ubar_i ]
    Y_i(t)        = 0 before onset, 1 - exp(-a_i (t - T_i)) from onset, 0 after end.

Conventions (shared with the C++ engine ``sc_rt._core.wheel_accel``):

- A fault is active on ``onset <= t < end``: at ``t == end`` it is over and
  ``Y = 0`` (abrupt end). ``end=None`` (or ``inf``) never ends.
- A stuck wheel (``stuck=True``) has zero acceleration while its fault is
  active, whatever the command and ``Y``; ``Y`` is still reported by (16).
- Wheel-speed limit: when ``|Omega_i| >= max_wheel_speed_i`` and the
  acceleration would drive the speed further out (``accel_i * Omega_i > 0``),
  the acceleration is 0. Applied after the fault model.
- A NaN command propagates (``min``/``max`` keep a NaN first argument, as
  ``std::min``/``std::max`` do in C++); rejecting invalid commands is the
  shell's job.

The public functions take array-likes and return numpy arrays; the private
``sat4``/``accel4`` work on plain floats for the plant's hot path
(``sc_rt.model.plant.rk4_step``). Their C++ twins (``sat4``/``accel4`` in
cpp/src/plant.cpp) repeat the same operations in the same order: the two
engines give bit-identical accelerations, so edit them together.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import numpy as np

from sc_rt.model.wheels import TorqueWheels

__all__ = [
    "WheelFault",
    "ActuatorParams",
    "fault_Y",
    "wheel_accel",
    "actuator_params_to_cpp",
    # the scalar fast path the plant's RK4 (plant.py) shares, and the checked
    # conversions the parameter dataclasses of both modules use
    "accel4",
    "sat4",
    "frozen",
    "floats",
]

_NWHEELS = 4


def frozen(value, shape: tuple[int, ...], name: str, errors: list[str], *,
            finite: bool = True) -> np.ndarray | None:
    """A read-only float64 copy of ``value`` with ``shape`` (finite values
    unless ``finite`` is False), or None with the problem added to ``errors``.
    Shared by the parameter dataclasses of actuators.py and plant.py."""
    what = f"a vector of {shape[0]} numbers" if len(shape) == 1 else f"numbers of shape {shape}"
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        errors.append(f"{name} must be {what}, got {value!r}")
        return None
    if a.shape != shape:
        errors.append(f"{name} must have shape {shape}, got shape {a.shape}: {value!r}")
        return None
    if finite and not np.all(np.isfinite(a)):
        errors.append(f"{name} must be finite, got {a.tolist()!r}")
        return None
    a.setflags(write=False)
    return a


def _is_real(x) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


@dataclass(frozen=True)
class WheelFault:
    """One fault of one wheel (wheel index 0..3).

    Validated on construction (ValueError naming the field and the value).
    """

    wheel: int  # 0-based wheel index
    effectiveness: float = 1.0  # [-] L_i in [0, 1]
    bias: float = 0.0  # [rad/s^2] ubar_i
    onset: float = 0.0  # [s] T_i
    end: float | None = None  # [s] abrupt end; None: never ends
    rate: float = 1.0  # [1/s] a_i, evolution rate of Y_i
    stuck: bool = False  # wheel stuck: zero acceleration from onset (until end)
    #: [-] friction multiplier reached as Y -> 1 (torque-commanded wheels only:
    #: a friction rise, 1 + Y (friction - 1) times the wheel's friction)
    friction: float = 1.0

    def __post_init__(self) -> None:
        errors = self.problems()
        if errors:
            raise ValueError("invalid WheelFault: " + "; ".join(errors))

    def problems(self) -> list[str]:
        """Every problem of this fault, each naming the field and the value."""
        errs: list[str] = []
        w = self.wheel
        if not (isinstance(w, numbers.Integral) and not isinstance(w, bool) and 0 <= w < _NWHEELS):
            errs.append(f"WheelFault.wheel must be an integer in 0..3, got {w!r}")
        L = self.effectiveness
        if not (_is_real(L) and 0.0 <= L <= 1.0):
            errs.append(f"WheelFault.effectiveness must be in [0, 1], got {L!r}")
        if not (_is_real(self.bias) and math.isfinite(self.bias)):
            errs.append(f"WheelFault.bias must be finite, got {self.bias!r}")
        onset_ok = _is_real(self.onset) and math.isfinite(self.onset)
        if not onset_ok:
            errs.append(f"WheelFault.onset must be finite, got {self.onset!r}")
        if self.end is not None:
            if not (_is_real(self.end) and not math.isnan(self.end) and self.end > -math.inf):
                errs.append(f"WheelFault.end must be a time > onset or None, got {self.end!r}")
            elif onset_ok and not self.end > self.onset:
                errs.append(f"WheelFault.end must be > onset ({self.onset!r}), got {self.end!r}")
        if not (_is_real(self.rate) and math.isfinite(self.rate) and self.rate > 0.0):
            errs.append(f"WheelFault.rate must be finite and > 0, got {self.rate!r}")
        if not (_is_real(self.friction) and math.isfinite(self.friction) and self.friction >= 0.0):
            errs.append(f"WheelFault.friction must be finite and >= 0, got {self.friction!r}")
        if not isinstance(self.stuck, (bool, np.bool_)):
            errs.append(f"WheelFault.stuck must be a bool, got {self.stuck!r}")
        return errs

    @property
    def end_time(self) -> float:
        """End of the fault [s]; ``inf`` when it never ends."""
        return math.inf if self.end is None else float(self.end)


@dataclass(frozen=True)
class ActuatorParams:
    """Wheel limits and the fault schedule.

    Validated on construction (ValueError naming the field and the value):
    finite ``umin < umax`` per wheel, ``max_wheel_speed > 0`` (``inf``: no
    limit), at most one fault per wheel. The arrays are stored as read-only
    float64 copies.
    """

    umin: np.ndarray  # [rad/s^2] (4,)
    umax: np.ndarray  # [rad/s^2] (4,)
    max_wheel_speed: np.ndarray = field(default_factory=lambda: np.full(4, np.inf))  # [rad/s]
    faults: tuple[WheelFault, ...] = ()
    #: flight-like torque-commanded wheels (None: the paper's, umin/umax/
    #: max_wheel_speed above; set: these replace them in the plant)
    wheels: TorqueWheels | None = None

    def __post_init__(self) -> None:
        errs: list[str] = []
        umin = frozen(self.umin, (_NWHEELS,), "ActuatorParams.umin", errs, finite=False)
        umax = frozen(self.umax, (_NWHEELS,), "ActuatorParams.umax", errs, finite=False)
        wmax = frozen(self.max_wheel_speed, (_NWHEELS,), "ActuatorParams.max_wheel_speed", errs,
                       finite=False)
        if umin is not None and umax is not None:
            for i in range(_NWHEELS):
                lo, hi = float(umin[i]), float(umax[i])
                if not (math.isfinite(lo) and math.isfinite(hi)):
                    errs.append(
                        f"ActuatorParams.umin/umax of wheel {i} must be finite, got {lo!r}, {hi!r}"
                    )
                elif not lo < hi:
                    errs.append(
                        f"ActuatorParams.umin must be < umax for wheel {i}: "
                        f"umin = {lo!r}, umax = {hi!r}"
                    )
        if wmax is not None:
            for i in range(_NWHEELS):
                if not wmax[i] > 0.0:  # NaN fails too; inf is "no limit"
                    errs.append(
                        f"ActuatorParams.max_wheel_speed of wheel {i} must be > 0, "
                        f"got {float(wmax[i])!r}"
                    )
        try:
            faults = tuple(self.faults)
        except TypeError:
            errs.append(
                f"ActuatorParams.faults must be a sequence of WheelFault, got {self.faults!r}"
            )
            faults = ()
        seen: set[int] = set()
        for k, f in enumerate(faults):
            if not isinstance(f, WheelFault):
                errs.append(f"ActuatorParams.faults[{k}] must be a WheelFault, got {f!r}")
                continue
            if f.wheel in seen:
                errs.append(
                    f"ActuatorParams.faults: wheel {f.wheel} has more than one fault "
                    f"(faults[{k}]); at most one fault per wheel"
                )
            seen.add(int(f.wheel))
        if self.wheels is not None and not isinstance(self.wheels, TorqueWheels):
            errs.append(f"ActuatorParams.wheels must be a TorqueWheels or None, got {self.wheels!r}")
        if self.wheels is None:
            for k, f in enumerate(faults):
                if isinstance(f, WheelFault) and f.friction != 1.0:
                    errs.append(f"ActuatorParams.faults[{k}].friction = {f.friction!r} needs torque-commanded "
                                "wheels (ActuatorParams.wheels): the paper's wheels have no friction")
        if errs:
            raise ValueError("invalid ActuatorParams: " + "; ".join(errs))
        object.__setattr__(self, "umin", umin)
        object.__setattr__(self, "umax", umax)
        object.__setattr__(self, "max_wheel_speed", wmax)
        object.__setattr__(self, "faults", faults)
        object.__setattr__(self, "_fast", _ActuatorFast(umin, umax, wmax, faults))

    def __getstate__(self) -> dict:
        # the TorquePlant sc_rt.model.truth caches here holds closures: not pickled
        return {k: v for k, v in self.__dict__.items() if k != "_torque_plant"}

    def fault_of(self, wheel: int) -> WheelFault | None:
        """The fault of wheel ``wheel`` (0..3), or None."""
        for f in self.faults:
            if f.wheel == wheel:
                return f
        return None


class _ActuatorFast:
    """Plain-float copies of ActuatorParams for the hot path (built once)."""

    __slots__ = ("umin", "umax", "faulted", "limited", "any_fault", "any_limit")

    def __init__(self, umin, umax, wmax, faults):
        self.umin = tuple(float(v) for v in umin)
        self.umax = tuple(float(v) for v in umax)
        # (wheel i, onset T_i, end, rate a_i, L_i - 1, bias ubar_i, stuck)
        self.faulted = tuple(
            (
                int(f.wheel),
                float(f.onset),
                f.end_time,
                float(f.rate),
                float(f.effectiveness) - 1.0,
                float(f.bias),
                bool(f.stuck),
            )
            for f in sorted(faults, key=lambda f: int(f.wheel))
        )
        # (wheel i, max |Omega_i|) for the finite limits only
        self.limited = tuple((i, float(v)) for i, v in enumerate(wmax) if math.isfinite(v))
        self.any_fault = bool(self.faulted)
        self.any_limit = bool(self.limited)


def sat4(fa: _ActuatorFast, u) -> tuple[float, float, float, float]:
    """Saturation of (15), min(max(u, umin), umax), on 4 plain floats.

    Written as comparisons (a NaN command stays NaN, as with min/max).
    """
    u1, u2, u3, u4 = u
    l1, l2, l3, l4 = fa.umin
    h1, h2, h3, h4 = fa.umax
    return (
        l1 if u1 < l1 else h1 if u1 > h1 else u1,
        l2 if u2 < l2 else h2 if u2 > h2 else u2,
        l3 if u3 < l3 else h3 if u3 > h3 else u3,
        l4 if u4 < l4 else h4 if u4 > h4 else u4,
    )


def accel4(fa: _ActuatorFast, t: float, sat, omega_w) -> list[float]:
    """Actual wheel accelerations (15),(16), then stuck wheels and the speed limit.

    ``sat`` are the saturated commands, ``omega_w`` the wheel speeds (only read
    when a wheel-speed limit is finite).
    """
    acc = list(sat)
    for i, onset, end, rate, Lm1, ubar, stuck in fa.faulted:
        if onset <= t < end:
            if stuck:
                acc[i] = 0.0
            else:
                Y = -math.expm1(-rate * (t - onset))  # (16)
                s = sat[i]
                acc[i] = s + Y * (Lm1 * s + ubar)  # (15)
    for i, wmax in fa.limited:
        w = omega_w[i]
        # |Omega_i| >= max and the acceleration drives it further out
        if (w >= wmax and acc[i] > 0.0) or (w <= -wmax and acc[i] < 0.0):
            acc[i] = 0.0
    return acc


def fault_Y(fault: WheelFault | None, t: float) -> float:
    """Fault activation Y_i(t) of (16) [-].

    Parameters
    ----------
    fault : WheelFault or None
        The fault (None: a healthy wheel, Y = 0).
    t : float
        Time [s].

    Returns
    -------
    float
        0 before ``onset`` and from ``end`` on, ``1 - exp(-rate (t - onset))``
        in between.
    """
    if fault is None:
        return 0.0
    t = float(t)
    if fault.onset <= t < fault.end_time:
        return -math.expm1(-fault.rate * (t - fault.onset))
    return 0.0


def wheel_accel(
    act: ActuatorParams, t: float, u_cmd, wheel_speed
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Saturation and the fault model, (15),(16) of docs/MODEL.md section 2.

    Parameters
    ----------
    act : ActuatorParams
        Limits and fault schedule.
    t : float
        Time [s].
    u_cmd : array_like, shape (4,)
        Wheel acceleration commands before saturation [rad/s^2].
    wheel_speed : array_like, shape (4,)
        Wheel speeds relative to the body [rad/s] (for the speed limit).

    Returns
    -------
    u_sat : ndarray, shape (4,)
        Saturated commands sat(uc) [rad/s^2].
    accel : ndarray, shape (4,)
        Actual wheel accelerations Omega_w_dot [rad/s^2].
    Y : ndarray, shape (4,)
        Fault activations Y_i(t) of (16) [-].
    """
    fa = act._fast
    t = float(t)
    u = floats(u_cmd, _NWHEELS, "u_cmd")
    w = floats(wheel_speed, _NWHEELS, "wheel_speed")
    sat = sat4(fa, u)
    acc = accel4(fa, t, sat, w)
    Y = [0.0] * _NWHEELS
    for f in act.faults:
        Y[f.wheel] = fault_Y(f, t)
    return np.array(sat), np.array(acc), np.array(Y)


def floats(x, n: int, name: str) -> list[float]:
    """``x`` as a list of n plain floats (fast for 1-D float64 arrays)."""
    if type(x) is np.ndarray and x.dtype == np.float64 and x.shape == (n,):
        return x.tolist()
    a = np.asarray(x, dtype=float)
    if a.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got shape {a.shape}")
    return a.tolist()


def actuator_params_to_cpp(a: ActuatorParams):
    """The C++ engine's ``sc_rt._core.ActuatorParams`` built from ``a``.

    The single conversion point between the Python dataclass and the C++
    struct: ``end=None`` becomes ``+inf``, wheels without a fault get an
    inactive ``WheelFault``.
    """
    from sc_rt import _core

    faults = [_core.WheelFault() for _ in range(_NWHEELS)]
    for f in a.faults:
        faults[f.wheel] = _core.WheelFault(
            active=True,
            effectiveness=float(f.effectiveness),
            bias=float(f.bias),
            onset=float(f.onset),
            end=f.end_time,
            rate=float(f.rate),
            stuck=bool(f.stuck),
            friction=float(f.friction),
        )
    wheels = None
    if a.wheels is not None:
        w = a.wheels
        wheels = _core.TorqueWheels([(v.u_max, v.u_min, v.p_max, v.omega_max) for v in w.limits],
                                    [(f.coulomb, f.static, f.beta, f.viscous, f.omega_limit_cycle)
                                     for f in w.friction], w.stribeck, w.command == "torque")
        wheels.lag = list(w.lag)
        wheels.stribeck_switching = bool(w.stribeck_switching)
    return _core.ActuatorParams(
        umin=np.array(a.umin),
        umax=np.array(a.umax),
        max_wheel_speed=np.array(a.max_wheel_speed),
        faults=faults,
        wheels=wheels,
    )
