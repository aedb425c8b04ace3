"""Control laws written in Python (docs/LAWS.md, "Python laws").

A Python law is a class with ``reset(inp)`` and ``step(inp)`` and the same
inputs and outputs as the C++ interface (cpp/include/sc_rt/law.hpp), numpy
arrays for vectors:

- ``Law(setup)``: ``setup.model`` (``LawModel``: J0, J0_inv, Cbar, Jw, umin,
  umax, wheel_torque_command, wheel_speed_max, w0, B, B_pinv,
  ``wheels_for_torque(tau)``), ``setup.control_rate_hz``, ``setup.params``
  (the law's own table, ``[laws.NAME]`` of the scenario with NAME its
  ``name``, as a dict): the same door as a C++ law's;
- ``inp`` (``LawInput``): ``t``, ``t_engaged`` (since reset), ``dt`` (since
  the previous step; 0 at reset and when time did not advance), ``m`` (the
  measurement: t, sigma_BN, omega_BN_B, wheel_speed), ``ref`` (the guidance:
  sigma_DN, omega_DN_D, omega_dot_DN_D), ``e`` (the core's
  ``_core.tracking_errors``: sigma_BD, omega_BD_B, R_BD, omega_DN_B, A,
  u_g0), ``ppc`` (the core's ``_core.ppc_transform``: chi, chi_dot, lambda_,
  eps, e1, r, violated), ``u_sat_prev``;
- ``step`` returns u_cmd (4,) [rad/s^2], or ``(u_cmd, telemetry)`` with a
  dict of named values: the fixed slots ``TELEMETRY`` (e1, e2, z1, z2, x2d,
  vs, rho_hat) are recorded in the run as the C++ laws' are; other names are
  kept in ``PyController.named_telemetry`` (the newest step's);
- optional ``after(u_cmd, u_sat)`` (anti-windup), and a ``name`` attribute
  (default: the class name) that labels the run.

``PyController`` wraps a law in the common controller parts exactly as
``Controller::step`` (cpp/src/controllers.cpp) does: SAFE zero command on an
invalid state and re-engagement (reset) at the next valid one, the guidance
advanced to each measurement, the time-not-advancing flag, a non-finite
command (or an exception of the law) answered by a SAFE zero command with
FLAG_LAW_INVALID, saturation to the wheel limits with the FLAG_SAT bits, the
PPC bound flags. Its ``step`` returns the packed row of ``_core.step_packed``,
so the offline engine's loop and the LCM controller process are the same for
both kinds of law.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sc_rt import _core
from sc_rt.lawload import is_python_law, law_label, load_law  # noqa: F401  (public here too)

__all__ = ["LawInput", "LawModel", "LawSetup", "Reference", "PyController", "TELEMETRY", "load_law",
           "is_python_law", "law_label", "PACKED_SLICES", "FLAG_LAW_INVALID"]

#: Named telemetry with a slot in the run (the packed fields a C++ law fills).
TELEMETRY = ("e1", "e2", "z1", "z2", "x2d", "vs", "rho_hat")
#: wheel_cmd_t.FLAG_LAW_INVALID: the law gave a non-finite command or failed
FLAG_LAW_INVALID = int(getattr(_core, "FLAG_LAW_INVALID", 1024))

#: Layout of the packed row (name -> slice), from _core.PACKED_FIELDS.
PACKED_SLICES: dict[str, slice] = {}
_o = 0
for _name, _n in _core.PACKED_FIELDS:
    PACKED_SLICES[_name] = slice(_o, _o + _n)
    _o += _n
assert _o == _core.PACKED_SIZE


def _vec(x) -> np.ndarray:
    return np.asarray(x, dtype=float)


@dataclass(frozen=True)
class LawModel:
    """What the controller knows of the spacecraft (the C++ LawModel)."""

    J0: np.ndarray  # (3, 3) [kg m^2]
    J0_inv: np.ndarray  # (3, 3)
    Cbar: np.ndarray  # (3, 4) wheel axes in B
    Jw: np.ndarray  # (4,) [kg m^2]
    umin: np.ndarray  # (4,) [rad/s^2] ([N m] when the wheels take a torque)
    umax: np.ndarray  # (4,) the same unit
    wheel_torque_command: bool  # the wheels take a motor torque [N m], not an acceleration
    wheel_speed_max: np.ndarray  # (4,) [rad/s] the wheels' speed limits (inf: none)
    w0: float  # [rad/s] orbit rate
    B: np.ndarray  # (3, 4) B = -J0^-1 Cbar Jw of (21)
    B_pinv: np.ndarray  # (4, 3) B+ (damped as configured)

    def wheels_for_torque(self, tau) -> np.ndarray:
        """u_cmd [rad/s^2] for a body torque tau [N m]: B+ J0^-1 tau."""
        return self.B_pinv @ (self.J0_inv @ _vec(tau))


@dataclass(frozen=True)
class LawSetup:
    """The constructor's argument."""

    model: LawModel
    control_rate_hz: float
    params: dict[str, Any]  # the law's own table ([laws.NAME]): key -> float or array


@dataclass(frozen=True)
class Reference:
    """The guidance at this step."""

    sigma_DN: np.ndarray  # (3,) desired attitude
    omega_DN_D: np.ndarray  # (3,) [rad/s] desired rate, D frame
    omega_dot_DN_D: np.ndarray  # (3,) [rad/s^2]


@dataclass
class LawInput:
    """One step's inputs (the C++ LawInput by the same names)."""

    t: float  # [s] time of the measurement
    t_engaged: float  # [s] since reset
    dt: float  # [s] since the previous step
    m: Any  # _core.Measurement
    ref: Reference
    e: Any  # _core.TrackingErrors
    ppc: Any  # _core.PpcResult
    u_sat_prev: np.ndarray = field(default_factory=lambda: np.zeros(4))  # (4,) [rad/s^2]


def _params(config) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, values in getattr(config, "law_params", None) or ():
        v = [float(x) for x in values]
        out[key] = v[0] if len(v) == 1 else np.array(v)
    return out


class PyController:
    """A Python law behind the controller's common parts (``Controller::step``)."""

    def __init__(self, config, law_cls: type):
        self.config = config
        core_model = _core.SpacecraftModel(config.spacecraft)
        self._core_model = core_model
        self.guidance = _core.Guidance(config.guidance, 1.0 / config.control_rate_hz)
        sc = config.spacecraft
        J0 = _vec(sc.J0)
        self.model = LawModel(J0=J0, J0_inv=np.linalg.inv(J0), Cbar=_vec(sc.Cbar), Jw=_vec(sc.Jw),
                              umin=_vec(sc.umin), umax=_vec(sc.umax),
                              wheel_torque_command=bool(sc.wheel_torque_command),
                              wheel_speed_max=_vec(sc.wheel_speed_max), w0=float(sc.w0),
                              B=_vec(core_model.B), B_pinv=_vec(core_model.B_pinv))
        self.setup = LawSetup(model=self.model, control_rate_hz=float(config.control_rate_hz),
                              params=_params(config))
        self.law = law_cls(self.setup)
        self.name = law_label(law_cls)
        self._after = getattr(self.law, "after", None)
        self.named_telemetry: dict[str, Any] = {}
        #: the law's contained failures, as ``Controller::law_failures``
        self.law_failures: dict[str, Any] = {"reset": 0, "step": 0, "after": 0, "last": None}
        self._t0 = self._t_prev = 0.0
        self._u_sat_prev = np.zeros(4)
        self._engaged = False
        self._first = True

    # --- the common parts, in Controller::step's order -----------------------
    def _inputs(self, m, t: float, dt: float) -> LawInput:
        gp = self.config.guidance
        ref = Reference(_vec(self.guidance.sigma_DN), _vec(_core.omega_d(gp, t)),
                        _vec(_core.omega_d_dot(gp, t)))
        e = _core.tracking_errors(self._core_model, m, ref.sigma_DN, ref.omega_DN_D, ref.omega_dot_DN_D)
        p = _core.ppc_transform(self.config.ppc, e.sigma_BD, t - self._t0)
        return LawInput(t=t, t_engaged=t - self._t0, dt=dt, m=m, ref=ref, e=e, ppc=p,
                        u_sat_prev=self._u_sat_prev.copy())

    def _failed(self, call: str, t: float, what: str) -> None:
        """A contained failure of the law's ``call`` at t: counted and named,
        the law disengaged (the next valid step re-engages it)."""
        self.law_failures[call] += 1
        self.law_failures["last"] = {"call": call, "t": float(t), "what": what}
        self._engaged = False

    def reset(self, t: float, x: np.ndarray) -> bool:
        """Engage from the state x = [sigma_BN, omega_BN_B, wheel_speed] at t
        (``Controller::reset``); False (counted) when the law's reset raised."""
        m = _core.Measurement(t, x[0:3], x[3:6], x[6:10])
        self._t0 = self._t_prev = t
        self.guidance.reset(t)
        self._u_sat_prev = np.zeros(4)
        try:
            self.law.reset(self._inputs(m, t, 0.0))
        except Exception as e:  # contained, as the core does
            self._failed("reset", t, f"{type(e).__name__}: {e}")
            return False
        self._engaged = True
        self._first = True
        return True

    def _checked(self, res: Any) -> tuple[np.ndarray, dict[str, Any] | None]:
        """The law's step result as (u_cmd (4,), telemetry), or ValueError
        naming what has the wrong shape or type."""
        u_cmd, tel = res if isinstance(res, tuple) and len(res) == 2 else (res, None)
        u_cmd = np.asarray(u_cmd, dtype=float).reshape(-1)
        if u_cmd.shape != (4,):
            raise ValueError(f"u_cmd of shape {u_cmd.shape}, expected (4,)")
        if tel is None:
            return u_cmd, None
        if not isinstance(tel, dict):
            raise ValueError(f"telemetry of type {type(tel).__name__}, expected a dict")
        out = {}
        for k, v in tel.items():
            a = np.asarray(v, dtype=float).reshape(-1)
            want = (PACKED_SLICES[k].stop - PACKED_SLICES[k].start) if k in TELEMETRY else 1
            if a.shape != (want,):
                raise ValueError(f"telemetry {k!r} of shape {a.shape}, expected ({want},)")
            out[k] = a if k in TELEMETRY else float(a[0])
        return u_cmd, out

    def safe_command(self, t: float, flags: int) -> np.ndarray:
        """A SAFE zero command (the law re-engages at the next valid step), as
        ``Controller::safe_command``: the packed row."""
        out = np.zeros(_core.PACKED_SIZE)
        out[PACKED_SLICES["sigma_DN"]] = self.guidance.sigma_DN
        return self._safe(out, flags)

    def _safe(self, out: np.ndarray, flags: int) -> np.ndarray:
        out[PACKED_SLICES["u_cmd"]] = 0.0
        out[PACKED_SLICES["u_sat"]] = 0.0
        out[PACKED_SLICES["mode"]] = _core.MODE_SAFE
        out[PACKED_SLICES["flags"]] = flags
        self._engaged = False
        return out

    def step(self, t: float, x: np.ndarray) -> np.ndarray:
        """One step; the packed row of ``_core.step_packed`` (PACKED_SLICES)."""
        P = PACKED_SLICES
        out = np.zeros(_core.PACKED_SIZE)
        m = _core.Measurement(t, x[0:3], x[3:6], x[6:10])
        if not _core.measurement_valid(m, self.config.safety):
            flags = _core.FLAG_INVALID_STATE
            out[P["sigma_DN"]] = self.guidance.sigma_DN
            # finite but out of range (a tumble past max_rate): the errors are defined
            if math.isfinite(t) and np.all(np.isfinite(x[0:10])) and t >= self.guidance.t:
                flags |= self._observe(m, t, out).ppc.violated
            return self._safe(out, flags)
        if not self._engaged and not self.reset(t, x):  # a reset that raised: SAFE
            out[P["sigma_DN"]] = self.guidance.sigma_DN
            return self._safe(out, FLAG_LAW_INVALID)
        flags = 0
        dt = t - self._t_prev
        if dt < 0.0 or (dt == 0.0 and not self._first):
            flags |= _core.FLAG_TIME_NOT_ADVANCING
            dt = 0.0
        self._first = False
        inp = self._observe(m, t, out, dt)
        flags |= inp.ppc.violated
        try:  # a failing law (raises, wrong shape, non-finite): SAFE, as the core does
            u_cmd, tel = self._checked(self.law.step(inp))
            if not np.all(np.isfinite(u_cmd)):
                raise ValueError("non-finite command")
        except Exception as e:
            self._failed("step", t, f"{type(e).__name__}: {e}" if not isinstance(e, ValueError) else str(e))
            return self._safe(out, flags | FLAG_LAW_INVALID)
        if tel:
            for k, v in tel.items():
                if k in TELEMETRY:
                    out[P[k]] = v
                else:
                    self.named_telemetry[k] = v
        u_sat = _vec(self._core_model.saturate(u_cmd))
        for i in range(4):
            if u_sat[i] != u_cmd[i]:
                flags |= _core.FLAG_SAT_1 << i
        self._u_sat_prev = u_sat
        if self._after is not None:
            try:
                self._after(u_cmd, u_sat)
            except Exception as e:  # the law's state after this command is unknown: SAFE now
                self._failed("after", t, f"{type(e).__name__}: {e}")
                return self._safe(out, flags | FLAG_LAW_INVALID)
        if dt > 0.0:
            self._t_prev = t
        out[P["u_cmd"]] = u_cmd
        out[P["u_sat"]] = u_sat
        out[P["mode"]] = _core.MODE_NORMAL
        out[P["flags"]] = flags
        return out

    def _observe(self, m, t: float, out: np.ndarray, dt: float = 0.0) -> LawInput:
        self.guidance.advance(t)
        inp = self._inputs(m, t, dt)
        P = PACKED_SLICES
        out[P["sigma_DN"]] = inp.ref.sigma_DN
        out[P["sigma_BD"]] = inp.e.sigma_BD
        out[P["omega_BD_B"]] = inp.e.omega_BD_B
        out[P["chi"]] = inp.ppc.chi
        out[P["lam"]] = inp.ppc.lambda_
        return inp
