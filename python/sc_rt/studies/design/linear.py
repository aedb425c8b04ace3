"""Tracking-error dynamics linearised at the error origin (docs/DESIGN.md, section 1).

Analytically (:func:`error_model`: ``x1' = G(0) x2 = x2/4``, ``x2' = B u``)
and numerically (:func:`error_system`, a ``control.nlsys`` around the real
plant :func:`sc_rt.model.plant.derivative` and the error equations (8)-(11);
:func:`linearize_error` calls ``control.linearize``), with the wheel-to-axis
matrices they share (:func:`input_matrices`).
"""

from __future__ import annotations

from dataclasses import dataclass

import control
import numpy as np

from sc_rt import _core
from sc_rt.model.actuators import fault_Y
from sc_rt.model.plant import derivative
from sc_rt.model.plant_params import PlantParams
from sc_rt.scenario.model import Scenario

__all__ = [
    "AXES",
    "INERTIAS",
    "InputMatrices",
    "inertia_matrix",
    "wheel_effectiveness",
    "input_matrices",
    "error_state_space",
    "error_model",
    "mrp_add",
    "error_system",
    "linearize_error",
]

AXES = ("x", "y", "z")
#: Inertias: the controller's J0, or the plant's J0 + dJ (model error).
INERTIAS = ("nominal", "true")


@dataclass(frozen=True)
class InputMatrices:
    """The wheel-to-axis matrices of one case.

    ``B`` (3x4) and ``B_pinv`` (4x3) are the controller's (21), from J0 and
    the scenario's ``pinv_damping``, taken from the C++ core so they are the
    very numbers the law uses. ``B_plant`` is what the plant applies
    (``-J^-1 Cbar Jw diag(effectiveness)``) and ``M = B_plant B_pinv`` (3x3)
    maps the law's axis acceleration command ``v`` (``u = B+ v``) to the
    actual axis acceleration: the identity for the nominal, healthy plant.
    """

    B: np.ndarray
    B_pinv: np.ndarray
    B_plant: np.ndarray
    M: np.ndarray
    effectiveness: np.ndarray


def inertia_matrix(scn: Scenario, inertia: str) -> np.ndarray:
    """J0 ("nominal", the controller's) or J0 + dJ ("true", the plant's)."""
    if inertia == "nominal":
        return np.array(scn.plant.J0)
    if inertia == "true":
        return np.array(scn.plant.J)
    raise ValueError(f"inertia must be one of {INERTIAS}, got {inertia!r}")


def wheel_effectiveness(scn: Scenario, t: float | None) -> np.ndarray:
    """Per wheel d(actual acceleration)/d(command) at time t (15),(16); ones for t None."""
    eff = np.ones(4)
    if t is None:
        return eff
    for f in scn.actuators.faults:
        if f.onset <= t < f.end_time:
            eff[f.wheel] = 0.0 if f.stuck else 1.0 + fault_Y(f, t) * (f.effectiveness - 1.0)
    return eff


def input_matrices(scn: Scenario, inertia: str = "nominal", t: float | None = None) -> InputMatrices:
    """B, B+, the plant's B and M = B_plant B+ (see :class:`InputMatrices`).

    ``t`` None: healthy wheels; a time: the faults' effectiveness at t (the
    biases are exogenous and do not enter a linearisation).
    """
    model = _core.SpacecraftModel(scn.core_config().spacecraft)
    B, Bp = np.array(model.B), np.array(model.B_pinv)
    eff = wheel_effectiveness(scn, t)
    Bpl = -np.linalg.solve(inertia_matrix(scn, inertia), scn.plant.Cbar * scn.plant.Jw) * eff
    return InputMatrices(B, Bp, Bpl, Bpl @ Bp, eff)


_X_NAMES = [f"sigma_BD[{i}]" for i in range(3)] + [f"omega_BD_B[{i}]" for i in range(3)]
_U_NAMES = [f"wheel_accel[{i}]" for i in range(4)]


def error_state_space(B_in: np.ndarray, dt=0, **kw) -> control.StateSpace:
    """``x1' = x2/4``, ``x2' = B_in w``, outputs the six states.

    The error dynamics at the origin (1),(2),(21) with the input map
    ``B_in`` (3 x m): the plant's B for the wheel accelerations
    (:func:`error_model`), M for the law's axis command v (the margins'
    loops), the identity for the axis accelerations (the sampled loop).
    """
    B_in = np.asarray(B_in, float)
    A = np.zeros((6, 6))
    A[0:3, 3:6] = 0.25 * np.eye(3)
    Bm = np.zeros((6, B_in.shape[1]))
    Bm[3:6] = B_in
    return control.ss(A, Bm, np.eye(6), np.zeros((6, B_in.shape[1])), dt, **kw)


def error_model(scn: Scenario, inertia: str = "nominal") -> control.StateSpace:
    """Analytic linearisation of the tracking-error dynamics at the error origin.

    States ``x1 = sigma_BD``, ``x2 = omega_BD_B``; inputs the four wheel
    accelerations; outputs the states. ``x1' = G(0) x2 = x2/4`` (1),(2) and
    ``x2' = B u`` with ``B = -J^-1 Cbar Jw`` (21) (J = J0 for "nominal",
    J0 + dJ for "true"). Neglected: every term of A of (21) whose derivative
    at the origin is O(|omega_d|, |J^-1 h_w|, w0^2), i.e. the gyroscopic and
    transport terms (see :func:`linearize_error` for their size).
    """
    return error_state_space(input_matrices(scn, inertia).B_plant, states=_X_NAMES,
                             inputs=_U_NAMES, outputs=_X_NAMES, name=f"error_model_{inertia}")


def mrp_add(sigma_BD, sigma_DN) -> np.ndarray:
    """sigma_BN from sigma_BD and sigma_DN: ``R(sigma_BN) = R(sigma_BD) R(sigma_DN)``.

    The composition that (8) inverts. -sigma_DN is the inverse attitude of
    sigma_DN, so this is the core's (8) ``mrp_subtract(sigma_BD, -sigma_DN)``
    (its numerator and denominator are then exactly the composition's), in
    the core's short set (|sigma| <= 1).
    """
    return np.asarray(_core.mrp_subtract(np.asarray(sigma_BD, float),
                                         -np.asarray(sigma_DN, float))).reshape(3)


def error_system(scn: Scenario, inertia: str = "true", *, desired: bool = True,
                 gravity: bool = True, wheel_speed=None, sigma_DN=None) -> control.NonlinearIOSystem:
    """The real tracking-error dynamics as a ``control.nlsys``.

    State ``[x1, x2]`` = ``[sigma_BD, omega_BD_B]``, input the actual wheel
    accelerations (4). The update function rebuilds the plant state
    (``sigma_BN = x1 (+) sigma_DN``, ``omega = x2 + R(x1) omega_d(t)``), calls
    :func:`sc_rt.model.plant.derivative` (the true plant (7), with J0 or J0 + dJ)
    and returns ``x1' = G(x1) x2`` (1),(2) and
    ``x2' = omega' + x2^ R(x1) omega_d - R(x1) omega_d'`` (the derivative of
    (11)). The wheel speeds are a parameter (they are not error states).

    Parameters
    ----------
    desired : use the scenario's omega_d(t) (False: a fixed desired frame).
    gravity : keep the gravity gradient (False: w0 = 0).
    wheel_speed : (4,) wheel speeds [rad/s] (default: the scenario's initial ones).
    sigma_DN : desired attitude (default: the scenario's sigma_d0).
    """
    p = scn.plant
    J = inertia_matrix(scn, inertia)
    plant = PlantParams(J0=J, dJ=np.zeros((3, 3)), Cbar=p.Cbar, Jw=p.Jw,
                        w0=p.w0 if gravity else 0.0, disturbance=p.disturbance)
    gp = scn.core_config().guidance
    ws = np.array(scn.initial.wheel_speed if wheel_speed is None else wheel_speed, float)
    sd = np.array(scn.guidance.sigma_d0 if sigma_DN is None else sigma_DN, float)

    def update(t, x, u, params):
        x1, x2 = x[0:3], x[3:6]
        wd = np.array(_core.omega_d(gp, t)) if desired else np.zeros(3)
        wdd = np.array(_core.omega_d_dot(gp, t)) if desired else np.zeros(3)
        R = np.array(_core.mrp_to_dcm(x1))
        omega = x2 + R @ wd
        xp = np.concatenate([mrp_add(x1, sd), omega, ws])
        omega_dot = derivative(t, xp, u, plant)[3:6]
        x1_dot = np.array(_core.mrp_G(x1)) @ x2
        x2_dot = omega_dot + np.cross(x2, R @ wd) - R @ wdd
        return np.concatenate([x1_dot, x2_dot])

    return control.nlsys(update, None, inputs=_U_NAMES, states=_X_NAMES, outputs=_X_NAMES,
                         name=f"error_dynamics_{inertia}")


def linearize_error(scn: Scenario, t: float = 0.0, inertia: str = "true", **kw) -> control.StateSpace:
    """``control.linearize`` of :func:`error_system` at x1 = x2 = 0, u = 0, time t.

    With ``desired=False, gravity=False`` and zero wheel speeds this is the
    analytic :func:`error_model` up to the finite-difference error; with the
    scenario's motion the extra terms are the gyroscopic and transport terms
    of (21), of the size of omega_d (tests/test_design.py bounds them).
    """
    return control.linearize(error_system(scn, inertia, **kw), np.zeros(6), np.zeros(4), t=t)
