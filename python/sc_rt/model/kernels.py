"""The plant's scalar kernels (docs/MODEL.md section 1): the right-hand
side of (1),(2),(7) on plain floats, the wheels' momentum map, the
disturbance, the orbit's gravity-gradient terms, a 3x3 inverse by cofactors
and R(sigma). Shared by the paper's plant (sc_rt.model.plant) and the
torque-commanded one (sc_rt.model.torque_plant); their C++ twin is
cpp/src/plant_kernels.hpp, the same scalar operations in the same order
(the tests hold the two bit-identical: change an expression here only
together with it).
"""

from __future__ import annotations

import math

import numpy as np

from sc_rt.model.magnetic import mag_torque
from sc_rt.model.orbit import OrbitParams, gg_terms, gg_torque, orbit_position, orbit_rates

__all__ = ["inv3", "make_disturbance", "make_wheel_map", "make_rhs", "make_orbit_gg", "mrp_to_dcm"]


def make_orbit_gg(o: OrbitParams | None):
    """gg(t) -> the orbit's gravity-gradient terms ``(3 mu / r^3, r_N / r)`` at
    ``t`` [s], or None without an orbit (cpp/src/plant_kernels.hpp OrbitGG)."""
    if o is None:
        return lambda t: None
    k = orbit_rates(o)
    mu = o.mu

    def gg(t: float):
        return gg_terms(mu, *orbit_position(o, k, t))

    return gg


def inv3(M: np.ndarray) -> np.ndarray:
    """Inverse of a 3x3 matrix by cofactors, adj(M) / det(M).

    Written out (not ``np.linalg.inv``, whose LAPACK rounding C++ cannot
    repeat) with the same operations in the same order as ``inv3`` in
    cpp/src/plant.cpp, so that both engines use the same bits.
    """
    (a, b, c), (d, e, f), (g, h, i) = np.asarray(M, dtype=float).tolist()
    A = e * i - f * h
    B = f * g - d * i
    C = d * h - e * g
    det = a * A + b * B + c * C
    return np.array([
        [A / det, (c * h - b * i) / det, (b * f - c * e) / det],
        [B / det, (a * i - c * g) / det, (c * d - a * f) / det],
        [C / det, (b * g - a * h) / det, (a * e - b * d) / det],
    ])  # fmt: skip


def make_disturbance(d):
    """dist(t) -> (3,) tuple: d(t) = bias + amp cos(freq t) [N m]."""
    b1, b2, b3 = d.bias.tolist()
    A1, A2, A3 = d.amp.tolist()
    f1, f2, f3 = d.freq.tolist()
    cos = math.cos
    if A1 == 0.0 and A2 == 0.0 and A3 == 0.0:
        const = (b1, b2, b3)

        def dist(t: float) -> tuple[float, float, float]:
            return const

    else:

        def dist(t: float) -> tuple[float, float, float]:
            return (b1 + A1 * cos(f1 * t), b2 + A2 * cos(f2 * t), b3 + A3 * cos(f3 * t))

    return dist


def make_wheel_map(CJ: np.ndarray):
    """wheel(v1, v2, v3, v4) -> Cbar Jw v as a (3,) tuple.

    Of wheel speeds: the wheels' momentum in B [N m s]; of wheel
    accelerations: the wheels' reaction torque with its sign flipped [N m].
    """
    (C11, C12, C13, C14), (C21, C22, C23, C24), (C31, C32, C33, C34) = CJ.tolist()

    def wheel(v1, v2, v3, v4):
        return (
            C11 * v1 + C12 * v2 + C13 * v3 + C14 * v4,
            C21 * v1 + C22 * v2 + C23 * v3 + C24 * v4,
            C31 * v1 + C32 * v2 + C33 * v3 + C34 * v4,
        )

    return wheel


def make_rhs(J: np.ndarray, Jinv: np.ndarray, k: float):
    """The plant's right-hand side on plain floats (the hot path).

    Returns ``f(s1, s2, s3, w1, w2, w3, hw1, hw2, hw3, tw1, tw2, tw3, d1, d2, d3)
    -> (sigma_dot (3), omega_dot (3))`` of ``sigma_BN``, ``omega_BN_B``, the
    wheels' momentum ``hw = Cbar Jw Omega_w`` [N m s], ``tw = Cbar Jw
    Omega_w_dot`` [N m] and the disturbance ``d`` [N m]. The wheel terms enter
    (7) only through hw and tw, which are linear in the wheel states: an RK4
    stage gets them without a 3x4 product. ``J`` is the true inertia, ``Jinv``
    its inverse, ``k = 3 w0^2``; all are closed over as plain floats. ``g``:
    the orbit's gravity-gradient terms at the stage's time (None: the w0 form);
    ``mb``: the body dipole [A m^2] and the field in N [T] at the stage's time
    (None: no magnetic torque).
    """
    (J11, J12, J13), (J21, J22, J23), (J31, J32, J33) = J.tolist()
    (I11, I12, I13), (I21, I22, I23), (I31, I32, I33) = Jinv.tolist()
    k = float(k)
    Jl = J.tolist()

    def f(s1, s2, s3, w1, w2, w3, hw1, hw2, hw3, tw1, tw2, tw3, d1, d2, d3, g=None, mb=None):
        ss = s1 * s1 + s2 * s2 + s3 * s3
        # (1),(2): sigma_dot = 1/4 [(1 - s's) w + 2 s^ w + 2 s (s'w)]
        c = 0.25 * (1.0 - ss)
        e = 0.5 * (s1 * w1 + s2 * w2 + s3 * w3)
        # (7): H = J omega + Cbar Jw Omega_w (body + wheels, in B)
        H1 = J11 * w1 + J12 * w2 + J13 * w3 + hw1
        H2 = J21 * w1 + J22 * w2 + J23 * w3 + hw2
        H3 = J31 * w1 + J32 * w2 + J33 * w3 + hw3
        # (7): J omega_dot = -omega^ H - Cbar Jw Omega_w_dot + u_g + d
        T1 = (w3 * H2 - w2 * H3) - tw1 + d1
        T2 = (w1 * H3 - w3 * H1) - tw2 + d2
        T3 = (w2 * H1 - w1 * H2) - tw3 + d3
        if g is not None:
            # the orbit's u_g = 3 mu / r^3 (n_B x J n_B), n_B = C_BN(sigma) r_N / r (orbit.py)
            u1, u2, u3 = gg_torque(Jl, s1, s2, s3, g)
            T1 += u1
            T2 += u2
            T3 += u3
        elif k:
            # (5),(6),(10): u_g = 3 w0^2 R3^ J R3, R3 = R(sigma) e3, i.e.
            # R3 = e3 + [8 (s s3 - s's e3) - 4 (1 - s's) (s^ e3)] / (1 + s's)^2
            q = 1.0 / ((1.0 + ss) * (1.0 + ss))
            m4 = 4.0 * (1.0 - ss)
            r1 = (8.0 * s1 * s3 - m4 * s2) * q
            r2 = (8.0 * s2 * s3 + m4 * s1) * q
            r3 = 1.0 + 8.0 * (s3 * s3 - ss) * q
            g1 = J11 * r1 + J12 * r2 + J13 * r3
            g2 = J21 * r1 + J22 * r2 + J23 * r3
            g3 = J31 * r1 + J32 * r2 + J33 * r3
            T1 += k * (r2 * g3 - r3 * g2)
            T2 += k * (r3 * g1 - r1 * g3)
            T3 += k * (r1 * g2 - r2 * g1)
        if mb is not None:
            # the magnetic torque m_B x C_BN(sigma) B_N of mb = (m_B, B_N) (magnetic.py)
            u1, u2, u3 = mag_torque(mb, s1, s2, s3)
            T1 += u1
            T2 += u2
            T3 += u3
        return (
            c * w1 + 0.5 * (s2 * w3 - s3 * w2) + e * s1,
            c * w2 + 0.5 * (s3 * w1 - s1 * w3) + e * s2,
            c * w3 + 0.5 * (s1 * w2 - s2 * w1) + e * s3,
            I11 * T1 + I12 * T2 + I13 * T3,
            I21 * T1 + I22 * T2 + I23 * T3,
            I31 * T1 + I32 * T2 + I33 * T3,
        )

    return f


def mrp_to_dcm(sigma: np.ndarray) -> np.ndarray:
    """R(sigma) of (10), [BN] for sigma_BN."""
    s = np.asarray(sigma, dtype=float)
    ss = s @ s
    S = np.array([[0.0, -s[2], s[1]], [s[2], 0.0, -s[0]], [-s[1], s[0], 0.0]])
    return np.eye(3) + (8.0 * S @ S - 4.0 * (1.0 - ss) * S) / (1.0 + ss) ** 2
