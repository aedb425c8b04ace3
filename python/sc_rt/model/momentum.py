"""The spacecraft's total angular momentum in N, the record's ``H_N``
(docs/MODEL.md section 1, (3)); its C++ twin is ``total_momentum_N`` in
cpp/src/plant.cpp, the same scalar operations (bitwise equal)."""

from __future__ import annotations

from sc_rt.model.orbit import rotate_to_B

__all__ = ["total_momentum_N"]


def total_momentum_N(p, x) -> tuple[float, float, float]:
    """``H_N = C_NB(sigma) (J omega + Cbar Jw Omega_w)`` [N m s] of (3).

    Parameters
    ----------
    p : sc_rt.model.plant_params.PlantParams
        The plant: the true inertia ``J = J0 + dJ`` [kg m^2], ``Cbar`` [-]
        and ``Jw`` [kg m^2].
    x : sequence of 10 floats
        The state: MRP sigma_BN [-], omega_BN_B [rad/s], wheel speeds [rad/s].

    Returns
    -------
    tuple of 3 floats
        [N m s] the body's and the wheels' angular momentum in N.
    """
    s1, s2, s3, w1, w2, w3, O1, O2, O3, O4 = (float(v) for v in x)
    J0, dJ, C, Jw = p.J0, p.dJ, p.Cbar, p.Jw
    hb = []
    for r in range(3):  # row by row, left to right (the C++ loop's order)
        v = (float(J0[r][0]) + float(dJ[r][0])) * w1
        v += (float(J0[r][1]) + float(dJ[r][1])) * w2
        v += (float(J0[r][2]) + float(dJ[r][2])) * w3
        for c, Om in enumerate((O1, O2, O3, O4)):
            v += (float(C[r][c]) * float(Jw[c])) * Om
        hb.append(v)
    return rotate_to_B(-s1, -s2, -s3, hb[0], hb[1], hb[2])  # C_NB(sigma) = C_BN(-sigma)
