"""The pure plant of the combined spacecraft (docs/MODEL.md section 1): its
dynamics; its parameters, validated, are sc_rt.model.plant_params's.

State ``x`` (10,): ``sigma_BN`` (3), ``omega_BN_B`` (3, rad/s), wheel speeds
``Omega_w`` (4, rad/s relative to the body). The plant integrates the TRUE
inertia ``J0 + dJ``; the controller knows only ``J0`` (12).

This is the Python reference; ``sc_rt._core`` holds the same plant in C++
(``plant_derivative``, ``plant_rk4_step``, ...) for batch speed. The C++ twin
repeats this module's scalar operations in the same order (cpp/src/plant.cpp),
and the tests hold the two BIT-IDENTICAL: change an expression here only
together with its C++ twin. The hot path (``rk4_step``) works on plain Python
floats: numpy costs about 1 us per operation on 3-vectors, which would make a
step cost hundreds of microseconds.

Examples
--------
>>> import numpy as np
>>> from sc_rt.model.plant import rk4_step
>>> from sc_rt.model.plant_params import PlantParams
>>> from sc_rt.model.actuators import ActuatorParams
>>> p = PlantParams(J0=np.diag([10.0, 15, 20]), dJ=np.diag([2.0, -1, 2]),
...                 Cbar=np.c_[np.eye(3), np.ones(3) / np.sqrt(3)],
...                 Jw=np.full(4, 0.338), w0=0.0011)
>>> act = ActuatorParams(umin=np.full(4, -7.0), umax=np.full(4, 10.0))
>>> x = np.zeros(10)
>>> x = rk4_step(p, act, 0.0, x, 0.1, [1.0, 0, 0, 0])
>>> round(float(x[6]), 12)  # wheel 1 spun up by 1 rad/s^2 * 0.1 s
0.1
"""

from __future__ import annotations

import numpy as np

from sc_rt.model.actuators import ActuatorParams, accel4, floats, sat4
from sc_rt.model.kernels import mrp_to_dcm
from sc_rt.model.magnetic import held_dipole
from sc_rt.model.plant_params import PlantParams
from sc_rt.model.rods import rods_dipole_B, rods_to_cpp
from sc_rt.model.orbit import orbit_params_to_cpp, rotate_to_B

__all__ = [
    "disturbance",
    "derivative",
    "omega_dot",
    "rk4_step",
    "lumped_disturbance",
    "total_angular_momentum_N",
    "field_B",
    "plant_params_to_cpp",
]

_NX = 10


def disturbance(p: PlantParams, t: float) -> np.ndarray:
    """External disturbance torque d(t) = bias + amp cos(freq t) [N m], in B.

    Parameters
    ----------
    p : PlantParams
    t : float
        Time [s].

    Returns
    -------
    ndarray, shape (3,)
    """
    return np.array(p._fast.dist(float(t)))


def _stage_mb(fp, m, t: float):
    """(m_B, B_N(t)) for the right-hand side, or None without a dipole or a field."""
    if m is None or fp.field is None:
        return None
    return m + fp.field(t)


def derivative(t: float, x, wheel_accel, p: PlantParams, dipole_B=None) -> np.ndarray:
    """State derivative of the plant, python-control style ``f(t, x, u, params)``.

    Parameters
    ----------
    t : float
        Time [s] (for the disturbance d(t)).
    x : array_like, shape (10,)
        ``[sigma_BN (3) [-], omega_BN_B (3) [rad/s], Omega_w (4) [rad/s]]``.
    wheel_accel : array_like, shape (4,)
        ACTUAL wheel accelerations Omega_w_dot [rad/s^2] (after saturation and
        faults, see ``sc_rt.model.actuators.wheel_accel``).
    p : PlantParams
    dipole_B : array_like, shape (3,), optional
        The magnetorquers' body dipole [A m^2] (added to the residual dipole).

    Returns
    -------
    ndarray, shape (10,)
        ``[sigma_dot (1),(2) [1/s], omega_dot (7) [rad/s^2], Omega_w_dot [rad/s^2]]``.
    """
    fp = p._fast
    s1, s2, s3, w1, w2, w3, O1, O2, O3, O4 = floats(x, _NX, "x")
    acc = floats(wheel_accel, 4, "wheel_accel")
    out = fp.f(
        s1, s2, s3, w1, w2, w3, *fp.wheel(O1, O2, O3, O4), *fp.wheel(*acc), *fp.dist(float(t)),
        fp.gg(float(t)), _stage_mb(fp, held_dipole(fp.res, dipole_B), float(t)),
    )
    return np.array(out + tuple(acc))


def omega_dot(t: float, x, wheel_accel, p: PlantParams) -> np.ndarray:
    """Body angular acceleration of (7) with the true inertia [rad/s^2], shape (3,).

    Same arguments as :func:`derivative`.
    """
    return derivative(t, x, wheel_accel, p)[3:6]


def rk4_step(p: PlantParams, act: ActuatorParams, t: float, x, h: float, u_cmd,
             dipole_B=None) -> np.ndarray:
    """One classical RK4 step of the plant from t to t + h.

    The command is held over the step (zero-order hold); the actual wheel
    acceleration is re-evaluated at every stage by the fault model
    ``wheel_accel(act, t_stage, u_cmd, Omega_stage)`` (15),(16), and the
    disturbance at every stage time. After the step the attitude is mapped to
    the MRP short set (|sigma| > 1 -> -sigma/|sigma|^2, docs/MODEL.md section 1).

    Parameters
    ----------
    p : PlantParams
    act : ActuatorParams
    t : float
        Start time [s].
    x : array_like, shape (10,)
        State at t (see :func:`derivative`).
    h : float
        Step [s].
    u_cmd : array_like, shape (4,)
        Wheel commands before saturation [rad/s^2], held over the step.
    dipole_B : array_like, shape (3,), optional
        The magnetorquers' body dipole ``m_B = G d`` [A m^2], held over the
        step; with the residual dipole it acts through the field
        (``PlantParams.field_model``) at every stage's time and attitude.
        None: the rods' dipole for a zero command (``PlantParams.magnetorquers``,
        sc_rt.model.rods.rods_dipole_B at t), none without rods.

    Returns
    -------
    ndarray, shape (10,)
        State at t + h.

    Notes
    -----
    Written out on plain floats for speed (15-20 us a step in CPython 3.11
    on the development VM, against hundreds with numpy 3-vectors). The wheel states enter (7)
    only through ``hw = Cbar Jw Omega_w`` and ``tw = Cbar Jw Omega_w_dot``;
    a stage's wheel speeds are ``Omega_0 + c a_prev``, so its ``hw`` is
    ``hw_0 + c tw_prev`` by linearity.
    """
    fp = p._fast
    fa = act._fast
    f = fp.f
    wheel = fp.wheel
    dist = fp.dist
    t = float(t)
    h = float(h)
    s1, s2, s3, w1, w2, w3, O1, O2, O3, O4 = floats(x, _NX, "x")
    sat = sat4(fa, floats(u_cmd, 4, "u_cmd"))
    hh = 0.5 * h
    tm = t + hh
    te = t + h
    dm1, dm2, dm3 = dist(tm)
    gg = fp.gg  # the orbit's gravity-gradient terms at the three stage times (None: none)
    g1, gm, ge = gg(t), gg(tm), gg(te)
    if dipole_B is None and p.magnetorquers is not None:
        dipole_B = rods_dipole_B(p.magnetorquers, t)  # the rods' own dipole (a stuck rod's)
    m = held_dipole(fp.res, dipole_B)  # the body dipole over the step (None: none)
    mb1, mbm, mbe = _stage_mb(fp, m, t), _stage_mb(fp, m, tm), _stage_mb(fp, m, te)
    limit = fa.any_limit
    timed = fa.any_fault or limit
    hw1, hw2, hw3 = wheel(O1, O2, O3, O4)
    # Stage accelerations a, b, c, e depend on the stage time (faults) and,
    # with a finite wheel-speed limit, on the stage's wheel speeds.
    # stage 1 at (t, x0)
    a1, a2, a3, a4 = accel4(fa, t, sat, (O1, O2, O3, O4)) if timed else sat
    ta1, ta2, ta3 = wheel(a1, a2, a3, a4)
    p1, p2, p3, q1, q2, q3 = f(s1, s2, s3, w1, w2, w3, hw1, hw2, hw3, ta1, ta2, ta3, *dist(t), g1, mb1)
    # stage 2 at (t + h/2, x0 + h/2 k1)
    if limit:
        b1, b2, b3, b4 = accel4(
            fa, tm, sat, (O1 + hh * a1, O2 + hh * a2, O3 + hh * a3, O4 + hh * a4)
        )
        tb1, tb2, tb3 = wheel(b1, b2, b3, b4)
    elif timed:
        b1, b2, b3, b4 = accel4(fa, tm, sat, None)
        tb1, tb2, tb3 = wheel(b1, b2, b3, b4)
    else:
        b1, b2, b3, b4, tb1, tb2, tb3 = a1, a2, a3, a4, ta1, ta2, ta3
    P1, P2, P3, Q1, Q2, Q3 = f(
        s1 + hh * p1, s2 + hh * p2, s3 + hh * p3, w1 + hh * q1, w2 + hh * q2, w3 + hh * q3,
        hw1 + hh * ta1, hw2 + hh * ta2, hw3 + hh * ta3, tb1, tb2, tb3, dm1, dm2, dm3, gm, mbm,
    )  # fmt: skip
    # stage 3 at (t + h/2, x0 + h/2 k2)
    if limit:
        c1, c2, c3, c4 = accel4(
            fa, tm, sat, (O1 + hh * b1, O2 + hh * b2, O3 + hh * b3, O4 + hh * b4)
        )
        tc1, tc2, tc3 = wheel(c1, c2, c3, c4)
    else:  # same time and acceleration as stage 2
        c1, c2, c3, c4, tc1, tc2, tc3 = b1, b2, b3, b4, tb1, tb2, tb3
    u1, u2, u3, v1, v2, v3 = f(
        s1 + hh * P1, s2 + hh * P2, s3 + hh * P3, w1 + hh * Q1, w2 + hh * Q2, w3 + hh * Q3,
        hw1 + hh * tb1, hw2 + hh * tb2, hw3 + hh * tb3, tc1, tc2, tc3, dm1, dm2, dm3, gm, mbm,
    )  # fmt: skip
    # stage 4 at (t + h, x0 + h k3)
    if timed:
        e1, e2, e3, e4 = accel4(fa, te, sat, (O1 + h * c1, O2 + h * c2, O3 + h * c3, O4 + h * c4))
        te1, te2, te3 = wheel(e1, e2, e3, e4)
    else:
        e1, e2, e3, e4, te1, te2, te3 = a1, a2, a3, a4, ta1, ta2, ta3
    U1, U2, U3, V1, V2, V3 = f(
        s1 + h * u1, s2 + h * u2, s3 + h * u3, w1 + h * v1, w2 + h * v2, w3 + h * v3,
        hw1 + h * tc1, hw2 + h * tc2, hw3 + h * tc3, te1, te2, te3, *dist(te), ge, mbe,
    )  # fmt: skip
    # x(t + h) = x0 + h/6 (k1 + 2 k2 + 2 k3 + k4)
    h6 = h / 6.0
    s1 += h6 * (p1 + 2.0 * (P1 + u1) + U1)
    s2 += h6 * (p2 + 2.0 * (P2 + u2) + U2)
    s3 += h6 * (p3 + 2.0 * (P3 + u3) + U3)
    ss = s1 * s1 + s2 * s2 + s3 * s3
    if ss > 1.0:  # MRP shadow set: same attitude, |sigma| <= 1
        s1, s2, s3 = -s1 / ss, -s2 / ss, -s3 / ss
    return np.array((
        s1, s2, s3,
        w1 + h6 * (q1 + 2.0 * (Q1 + v1) + V1),
        w2 + h6 * (q2 + 2.0 * (Q2 + v2) + V2),
        w3 + h6 * (q3 + 2.0 * (Q3 + v3) + V3),
        O1 + h6 * (a1 + 2.0 * (b1 + c1) + e1),
        O2 + h6 * (a2 + 2.0 * (b2 + c2) + e2),
        O3 + h6 * (a3 + 2.0 * (b3 + c3) + e3),
        O4 + h6 * (a4 + 2.0 * (b4 + c4) + e4),
    ))  # fmt: skip


def lumped_disturbance(p: PlantParams, t: float, x, u_sat, accel) -> np.ndarray:
    """The true lumped disturbance delta_2 of (20),(21) [rad/s^2], shape (3,).

    ``delta_2 = omega_dot_true - J0^-1 [-W^ (J0 W + Cbar Jw Omega_w) + u_g0] - B u_sat``
    with ``W = omega_BN_B``, ``u_g0 = 3 w0^2 R3^ J0 R3`` and
    ``B = -J0^-1 Cbar Jw`` (docs/MODEL.md section 4). The terms of A that involve
    omega_d cancel against d/dt (R omega_d), so delta_2 does not depend on the
    desired trajectory. It collects the inertia error dJ, the faults
    (``accel - u_sat``), d(t) and the residual dipole's torque (not the
    magnetorquers').

    Parameters
    ----------
    p : PlantParams
    t : float
        Time [s].
    x : array_like, shape (10,)
        Plant state.
    u_sat : array_like, shape (4,)
        Saturated commands [rad/s^2] (what the controller's model applies).
    accel : array_like, shape (4,)
        Actual wheel accelerations [rad/s^2] (what the plant applies).

    Returns
    -------
    ndarray, shape (3,)
    """
    fp = p._fast
    s1, s2, s3, w1, w2, w3, O1, O2, O3, O4 = floats(x, _NX, "x")
    hw = fp.wheel(O1, O2, O3, O4)
    # omega_dot of (7) with the true J, the actual accelerations and d(t) ...
    _, _, _, a1, a2, a3 = fp.f(
        s1, s2, s3, w1, w2, w3, *hw, *fp.wheel(*floats(accel, 4, "accel")), *fp.dist(float(t)),
        fp.gg(float(t)), _stage_mb(fp, held_dipole(fp.res, None), float(t)),
    )
    # ... minus the model of (21): the same right-hand side with J0 (u_g0 too),
    # the saturated commands and no d: J0^-1 [-W^ (J0 W + hw) + u_g0 - Cbar Jw u_sat]
    _, _, _, m1, m2, m3 = fp.f0(
        s1, s2, s3, w1, w2, w3, *hw, *fp.wheel(*floats(u_sat, 4, "u_sat")), 0.0, 0.0, 0.0
    )
    return np.array((a1 - m1, a2 - m2, a3 - m3))


def field_B(p: PlantParams, t: float, sigma_BN) -> tuple[float, float, float] | None:
    """The plant's field in B, ``C_BN(sigma) B_N(t)`` [T], at ``t`` [s] for the attitude
    ``sigma_BN`` (None without a field): what the engines give the controller on a run
    without a magnetometer. The twin of ``plant_field_B`` in cpp/src/plant.cpp."""
    fN = p._fast.field
    if fN is None:
        return None
    n1, n2, n3 = fN(float(t))
    return rotate_to_B(float(sigma_BN[0]), float(sigma_BN[1]), float(sigma_BN[2]), n1, n2, n3)


def total_angular_momentum_N(x, p: PlantParams) -> np.ndarray:
    """Total angular momentum (body + wheels) in N [N m s], shape (3,).

    ``H_N = R(sigma)' (J omega + Cbar Jw Omega_w)``: the quantity (7) conserves
    without external torque.
    """
    xs = np.asarray(x, dtype=float)
    H_B = p.J @ xs[3:6] + (p.Cbar * p.Jw) @ xs[6:10]
    return mrp_to_dcm(xs[0:3]).T @ H_B


def plant_params_to_cpp(p: PlantParams):
    """The C++ engine's ``sc_rt._core.PlantParams`` built from ``p``.

    The single conversion point between the Python dataclass and the C++
    struct (the C++ constructor validates again).
    """
    from sc_rt import _core

    d = p.disturbance
    return _core.PlantParams(
        J0=np.array(p.J0),
        dJ=np.array(p.dJ),
        Cbar=np.array(p.Cbar),
        Jw=np.array(p.Jw),
        w0=float(p.w0),
        dist_amp=np.array(d.amp),
        dist_freq=np.array(d.freq),
        dist_bias=np.array(d.bias),
        orbit=orbit_params_to_cpp(p.orbit),
        field_model=p.field_model,
        residual_dipole=np.array(p.residual_dipole),
        orbit_gravity_gradient=p.orbit_gravity_gradient,
        rods=rods_to_cpp(p.magnetorquers),
    )
