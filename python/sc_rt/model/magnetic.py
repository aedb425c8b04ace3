"""The magnetic torque in the plant (docs/MODEL.md section 16): the field in
N along the orbit and the torque of a body dipole in it, the Python twin of
the C++ kernels ``MagField`` and ``mag_torque`` (cpp/src/plant_kernels.hpp).

The plant's dipole is the sum of the spacecraft's residual dipole
(``PlantParams.residual_dipole``, a disturbance) and the magnetorquers' body
dipole ``m_B = G d`` held over a step (the plant's ``dipole_B`` input); its
torque is ``tau_B = m_B x B_B`` (Basilisk's MtbEffector convention,
docs/MODEL.md section 13), with ``B_B = C_BN(sigma) B_N`` at every RK4
stage's attitude and ``B_N`` the field at the stage's time: IGRF-14 or the
tilted dipole (sc_rt.model.field) at the orbit's position (sc_rt.model.orbit)
and GMST, in tesla (the evaluators give nT).

Every scalar operation is the C++ one in the same order: the two plants give
the same bits (tests/test_mag_plant_twin.py).

Examples
--------
>>> mag_torque((1.0, 0.0, 0.0, 0.0, 1e-5, 0.0), 0.0, 0.0, 0.0)  # x cross y = z
(0.0, -0.0, 1e-05)
"""

from __future__ import annotations

from sc_rt.model.field import NT, field_for
from sc_rt.model.orbit import OrbitParams, orbit_position, orbit_rates, rotate_to_B

__all__ = ["make_field_N", "mag_torque", "held_dipole"]


def make_field_N(orbit: OrbitParams | None, model: str):
    """field(t) -> ``B_N`` [T] as a (3,) tuple at ``t`` [s] after the orbit's
    epoch, or None when there is no field (``model`` "none" or no orbit).

    ``model`` is the scenario's ``[environment] field`` ("igrf", "dipole",
    "wmm2025", "none"); the coefficients are those of the orbit's epoch
    (sc_rt.model.field.field_for).
    """
    if orbit is None or model == "none":
        return None
    f = field_for(model, orbit.jd_epoch)
    k = orbit_rates(orbit)
    jd = orbit.jd_epoch

    def field(t: float) -> tuple[float, float, float]:
        B = f.B_eci(orbit_position(orbit, k, t), jd, t)  # [nT]
        return (float(B[0]) * NT, float(B[1]) * NT, float(B[2]) * NT)

    return field


def held_dipole(residual, dipole_B) -> tuple[float, float, float] | None:
    """The plant's body dipole over a step [A m^2]: the residual dipole plus
    the magnetorquers' ``dipole_B`` (None: none), or None when it is exactly
    zero (then the plant adds no magnetic term at all: bitwise the plant
    without one)."""
    r1, r2, r3 = residual
    if dipole_B is not None:
        d1, d2, d3 = (float(v) for v in dipole_B)
        r1, r2, r3 = r1 + d1, r2 + d2, r3 + d3
    if r1 == 0.0 and r2 == 0.0 and r3 == 0.0:
        return None
    return (r1, r2, r3)


def mag_torque(mb, s1: float, s2: float, s3: float) -> tuple[float, float, float]:
    """``tau_B = m_B x (C_BN(sigma) B_N)`` [N m] for ``mb = (m_B [A m^2], B_N [T])``, the field
    rotated into B by ``sc_rt.model.orbit.rotate_to_B``."""
    m1, m2, m3, n1, n2, n3 = mb
    b1, b2, b3 = rotate_to_B(s1, s2, s3, n1, n2, n3)
    return (m2 * b3 - m3 * b2, m3 * b1 - m1 * b3, m1 * b2 - m2 * b1)
