"""PD baseline design (docs/DESIGN.md, section 2).

``u = -B+ (beta1 x1 + beta2 x2)`` closes each axis as
``x1'' + beta2 x1' + beta1/4 x1 = 0``, so ``beta1 = 4 wn^2`` and
``beta2 = 2 zeta wn`` (:func:`design_pd`). Default spec
(:func:`default_pd_design`): critically damped (zeta = 1) with the 2 %
settling time of the slowest prescribed envelope,
``Ts = ln(1/0.02) / min(gamma)`` (48.9 s for the paper's gamma).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from sc_rt.scenario.model import Scenario

__all__ = ["SETTLING_TOL", "PdDesign", "settling_time_factor", "design_pd", "default_pd_design"]

#: 2 % settling.
SETTLING_TOL = 0.02


@dataclass(frozen=True)
class PdDesign:
    """PD gains and the spec they come from (per axis x1'' + beta2 x1' + beta1/4 x1 = 0)."""

    beta1: float  # [1/s^2]
    beta2: float  # [1/s]
    wn: float  # [rad/s] closed-loop natural frequency
    zeta: float  # [-] damping ratio
    settling_time: float  # [s] 2 % settling time of the free response from rest
    rule: str = ""


def settling_time_factor(zeta: float, tol: float = SETTLING_TOL) -> float:
    """wn * Ts of x'' + 2 zeta wn x' + wn^2 x = 0 from x(0) = 1, x'(0) = 0.

    Ts is the last time |x(t)| = tol (the same as the step response's
    settling time). zeta = 1 solves (1 + y) exp(-y) = tol (5.8335 for 2 %).
    """
    if not (zeta > 0 and 0 < tol < 1):
        raise ValueError(f"need zeta > 0 and 0 < tol < 1, got zeta={zeta!r}, tol={tol!r}")
    if zeta == 1.0:
        return scipy.optimize.brentq(lambda y: (1 + y) * math.exp(-y) - tol, 1e-9, 200.0,
                                     xtol=1e-14)
    if zeta < 1.0:
        wd = math.sqrt(1.0 - zeta * zeta)

        def x(y):
            return np.exp(-zeta * y) * (np.cos(wd * y) + zeta / wd * np.sin(wd * y))
        slow = zeta
    else:
        q = math.sqrt(zeta * zeta - 1.0)
        s1, s2 = -zeta + q, -zeta - q

        def x(y):
            return (s2 * np.exp(s1 * y) - s1 * np.exp(s2 * y)) / (s2 - s1)
        slow = -s1
    grid = np.linspace(0.0, (math.log(1 / tol) + 10) / slow, 200001)
    k = np.nonzero(np.abs(x(grid)) > tol)[0][-1]
    return scipy.optimize.brentq(lambda y: abs(x(y)) - tol, grid[k], grid[k + 1], xtol=1e-14)


def design_pd(*, wn: float | None = None, zeta: float = 1.0, settling_time: float | None = None,
              tol: float = SETTLING_TOL, rule: str = "") -> PdDesign:
    """PD gains from (wn, zeta) or (settling_time, zeta).

    Per axis the loop is ``x1'' + beta2 x1' + beta1/4 x1 = 0`` (x1' = x2/4,
    x2' = -(beta1 x1 + beta2 x2)), so ``beta1 = 4 wn^2``,
    ``beta2 = 2 zeta wn``; a settling time gives
    ``wn = settling_time_factor(zeta, tol) / Ts``.
    """
    if (wn is None) == (settling_time is None):
        raise ValueError("give exactly one of wn and settling_time")
    f = settling_time_factor(zeta, tol)
    if wn is None:
        if not settling_time > 0:
            raise ValueError(f"settling_time must be > 0, got {settling_time!r}")
        wn = f / settling_time
    if not wn > 0:
        raise ValueError(f"wn must be > 0, got {wn!r}")
    return PdDesign(beta1=4.0 * wn * wn, beta2=2.0 * zeta * wn, wn=wn, zeta=zeta,
                    settling_time=f / wn, rule=rule)


def default_pd_design(scn: Scenario, zeta: float = 1.0, tol: float = SETTLING_TOL) -> PdDesign:
    """The default spec: match the DSC+PPC convergence of the scenario.

    Rule: the prescribed envelope chi_i(t) decays as exp(-gamma_i t); its
    slowest axis reaches 2 % of its start after ``Ts = ln(1/0.02)/min(gamma)``
    (48.9 s for gamma = [0.12, 0.12, 0.08] 1/s). The PD loop is critically
    damped (zeta = 1: no overshoot, which matters for the asymmetric bound
    dmax = 0.3) and its free response from rest settles to 2 % in the same Ts.
    """
    g = float(np.min(scn.controller.ppc.gamma))
    if not g > 0:
        raise ValueError("the scenario's PPC gamma has a zero entry: no envelope settling time")
    Ts = math.log(1.0 / tol) / g
    rule = (f"zeta = {zeta:g}; 2% settling time = ln(1/{tol:g})/min(gamma) = "
            f"ln({1 / tol:g})/{g:g} = {Ts:.4g} s (the slowest prescribed envelope)")
    return design_pd(settling_time=Ts, zeta=zeta, tol=tol, rule=rule)

