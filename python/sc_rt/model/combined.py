"""Combined-spacecraft builder (docs/MODEL.md section 9; paper section 2.1, Remark 1).

After capture, the service spacecraft and the target are one rigid body. Its
inertia about the new mass centre follows from the two bodies by the
parallel-axis theorem, and its wheel matrix is ``Cbar = R_CS C``: a wheel's
spin momentum is a free vector, so the shift of the mass centre changes the
inertia but not the spin axes (erratum 3).

Frames
------
S
    Service body frame, origin at the service's mass centre O_s. The wheel
    matrix ``C_S`` (3x4, one unit spin axis per column) is given in S.
T
    Target body frame, origin at the target's mass centre O_t.
C
    Combined body frame, origin at the combined mass centre O_c. Its axes are
    those of S (``frame="service"``, the usual case: then ``Cbar = C``), the
    principal axes of the combined inertia (``frame="principal"``), or any
    given rotation of S.

Direction cosine matrices follow ``sc_rt._core.mrp_to_dcm`` (docs/MODEL.md (10)):
``R_XY`` maps the components of a vector in Y to its components in X,
``v_X = R_XY v_Y``, and the MRP ``sigma_XY`` of X relative to Y gives
``R_XY = R(sigma_XY)``. The paper's ``R_sc`` is ``R_CS`` here.

Equations (m = m_S + m_T, P(d) = |d|^2 I3 - d d')::

    r_c_S = m_T r_T_S / m                                   mass centre, from O_s, in S
    J_S   = J_s + m_S P(-r_c_S)
          + R_TS' J_t R_TS + m_T P(r_T_S - r_c_S)           about O_c, in S
    J_C   = R_CS J_S R_CS'                                  about O_c, in C
    Cbar  = R_CS C_S                                        spin axes in C
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

__all__ = [
    "CbarWarning",
    "CombinedBody",
    "RigidBody",
    "RotationFit",
    "check_cbar_is_rotation",
    "combine",
    "fit_rotation",
    "parallel_axis",
    "principal_axes",
]


@dataclass(frozen=True)
class RigidBody:
    """One body before capture.

    Attributes
    ----------
    mass : float
        [kg] > 0.
    inertia : ndarray (3, 3)
        [kg m^2] about the body's own mass centre, in the body's own frame.
    """

    mass: float  # [kg]
    inertia: np.ndarray  # [kg m^2] about its own mass centre, own frame


@dataclass(frozen=True)
class CombinedBody:
    """The combined spacecraft after capture (conventions: module docstring)."""

    mass: float  # [kg] m_S + m_T
    r_c_S: np.ndarray  # [m] combined mass centre O_c relative to O_s, in S
    J_C: np.ndarray  # [kg m^2] inertia about O_c, in C (symmetric positive definite)
    R_CS: np.ndarray  # [-] DCM from S components to C components (proper rotation)
    Cbar: np.ndarray  # [-] 3x4 wheel spin axes in C, R_CS C_S


class RotationFit(NamedTuple):
    """Result of :func:`check_cbar_is_rotation`; unpacks as a 3-tuple."""

    is_rotation: bool  # residual <= tol
    R_best: np.ndarray  # best proper rotation (det +1) with Cbar ~ R_best C
    residual: float  # max over wheels of |Cbar_i - R_best C_i| (unit axes: ~ angle [rad])


class CbarWarning(UserWarning):
    """A given Cbar is not R C for any proper rotation R."""


def parallel_axis(J_cm: np.ndarray, mass: float, d: np.ndarray) -> np.ndarray:
    """Inertia about a point displaced by ``d`` from the mass centre [kg m^2].

    ``J = J_cm + mass (|d|^2 I3 - d d')`` (parallel-axis theorem), all in one
    frame; ``d`` [m] is the mass centre relative to the new point (the sign of
    ``d`` does not matter).

    >>> parallel_axis(np.zeros((3, 3)), 2.0, np.array([0.0, 0.0, 3.0])).diagonal()
    array([18., 18.,  0.])
    """
    d = np.asarray(d, dtype=float)
    return np.asarray(J_cm, dtype=float) + mass * (d @ d * np.eye(3) - np.outer(d, d))


def principal_axes(J: np.ndarray) -> np.ndarray:
    """DCM ``R_PX`` from frame X to the principal axes P of inertia ``J`` (in X).

    ``R_PX J R_PX'`` is diagonal with ascending moments. Each axis is signed
    so that its largest component in X is positive, and the last axis is
    flipped if needed so that ``det R_PX = +1``. With repeated moments the
    axes within the repeated plane are arbitrary.
    """
    _, V = np.linalg.eigh(J)  # columns: principal axes in X, ascending moments
    V = V * np.sign(V[np.argmax(np.abs(V), axis=0), range(3)])
    if np.linalg.det(V) < 0:
        V[:, 2] = -V[:, 2]
    return V.T


def _check_rotation(R: np.ndarray, name: str) -> np.ndarray:
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3):
        raise ValueError(f"{name} must be 3x3, got shape {R.shape}")
    if not (np.allclose(R @ R.T, np.eye(3), atol=1e-9) and np.linalg.det(R) > 0):
        raise ValueError(f"{name} must be a proper rotation (R R' = I, det R = +1), got\n{R}")
    return R


def combine(
    service: RigidBody,
    C_S: np.ndarray,
    target: RigidBody,
    r_T_S: np.ndarray,
    R_TS: np.ndarray,
    frame: str | np.ndarray = "service",
) -> CombinedBody:
    """Mass, mass centre, inertia and wheel matrix of the combined spacecraft.

    Parameters
    ----------
    service : RigidBody
        The service spacecraft; its inertia is about O_s, in S.
    C_S : ndarray (3, 4)
        [-] wheel spin axes in S (columns).
    target : RigidBody
        The captured target; its inertia is about O_t, in T.
    r_T_S : ndarray (3,)
        [m] position of O_t relative to O_s, in S.
    R_TS : ndarray (3, 3)
        [-] attitude of T relative to S (DCM, S components -> T components);
        from an MRP: ``sc_rt._core.mrp_to_dcm(sigma_TS)``.
    frame : {"service", "principal"} or ndarray (3, 3)
        Axes of the combined frame C: those of S, the principal axes of the
        combined inertia, or a given DCM ``R_CS``.

    Returns
    -------
    CombinedBody
        See the module docstring for the equations.

    Examples
    --------
    Two 1 kg bodies 2 m apart on the x axis, no inertia of their own: the
    mass centre is halfway, and each sits 1 m from it.

    >>> zero = np.zeros((3, 3))
    >>> c = combine(RigidBody(1.0, zero), np.eye(3, 4), RigidBody(1.0, zero),
    ...             np.array([2.0, 0.0, 0.0]), np.eye(3))
    >>> c.r_c_S, c.J_C.diagonal()
    (array([1., 0., 0.]), array([0., 2., 2.]))
    """
    for name, body in (("service", service), ("target", target)):
        if not (np.isfinite(body.mass) and body.mass > 0):
            raise ValueError(f"{name}.mass must be > 0 [kg], got {body.mass}")
        if np.shape(body.inertia) != (3, 3):
            raise ValueError(f"{name}.inertia must be 3x3, got shape {np.shape(body.inertia)}")
    C_S = np.asarray(C_S, dtype=float)
    if C_S.shape != (3, 4):
        raise ValueError(f"C_S must be 3x4, got shape {C_S.shape}")
    r_T_S = np.asarray(r_T_S, dtype=float)
    if r_T_S.shape != (3,) or not np.all(np.isfinite(r_T_S)):
        raise ValueError(f"r_T_S must be a finite 3-vector [m], got {r_T_S}")
    R_TS = _check_rotation(R_TS, "R_TS")

    m = service.mass + target.mass
    r_c_S = target.mass * r_T_S / m  # O_s is the origin of S
    J_S = parallel_axis(service.inertia, service.mass, -r_c_S) + parallel_axis(
        R_TS.T @ np.asarray(target.inertia, dtype=float) @ R_TS, target.mass, r_T_S - r_c_S
    )
    J_S = 0.5 * (J_S + J_S.T)  # exact symmetry against rounding
    if isinstance(frame, str):
        if frame == "service":
            R_CS = np.eye(3)
        elif frame == "principal":
            R_CS = principal_axes(J_S)
        else:
            raise ValueError(f'frame must be "service", "principal" or a DCM, got {frame!r}')
    else:
        R_CS = _check_rotation(frame, "frame (R_CS)")
    J_C = R_CS @ J_S @ R_CS.T
    return CombinedBody(
        mass=m, r_c_S=r_c_S, J_C=0.5 * (J_C + J_C.T), R_CS=R_CS, Cbar=R_CS @ C_S
    )


def fit_rotation(A: np.ndarray, B: np.ndarray, proper: bool = True) -> tuple[np.ndarray, float]:
    """Orthogonal R minimising ``||R B - A||_F`` (Kabsch), and its residual.

    ``proper=True`` fits a rotation (det +1), ``proper=False`` a reflection
    (det -1). The residual is the largest column error ``max_i |A_i - R B_i|``.
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    U, _, Vt = np.linalg.svd(A @ B.T)
    d = np.sign(np.linalg.det(U @ Vt)) * (1.0 if proper else -1.0)
    R = U @ np.diag([1.0, 1.0, d]) @ Vt
    return R, float(np.linalg.norm(A - R @ B, axis=0).max())


def check_cbar_is_rotation(
    Cbar: np.ndarray, C: np.ndarray, tol: float = 1e-3, warn: bool = True
) -> RotationFit:
    """Is ``Cbar = R C`` for a proper rotation R (docs/MODEL.md section 9)?

    Fits the best proper rotation (Kabsch, with the determinant corrected to
    +1) and compares the largest wheel-axis error to ``tol``. The default
    tolerance 1e-3 covers a matrix printed to 4 decimals (each element off
    by up to 5e-5, a column by up to 1e-4) with a margin of 10. When the
    fit fails and ``warn`` is true, a :class:`CbarWarning` says so, and says
    whether a reflection (det -1) fits instead: the given Cbar is still used
    as it is.

    The paper's printed Cbar is such a case: its first three columns have
    determinant -0.99993, so it is a mirrored, not a rotated, copy of
    C = [e1, e2, e3, (1,1,1)/sqrt(3)] (tests/test_combined.py).
    """
    R, residual = fit_rotation(Cbar, C, proper=True)
    ok = residual <= tol
    if not ok and warn:
        _, residual_mirror = fit_rotation(Cbar, C, proper=False)
        why = (
            f"a reflection (det R = -1) fits it to {residual_mirror:.3g}: Cbar's frame is "
            "mirrored relative to C's (left-handed)"
            if residual_mirror <= tol
            else "no reflection fits it either"
        )
        warnings.warn(
            f"Cbar is not R C for any proper rotation R: the best rotation leaves a wheel-axis "
            f"error of {residual:.3g} (tolerance {tol:g}); {why}. Cbar is used as given.",
            CbarWarning,
            stacklevel=2,
        )
    return RotationFit(ok, R, residual)
