"""Stability margins of the PD baseline loop, one axis at a time (docs/DESIGN.md, section 3).

The loop is broken at the axis acceleration command ``v`` (``u = B+ v``):
continuous, sampled with a zero-order hold, sampled with a one-sample
computation delay, and continuous with a Pade latency; nominal ``J0`` and
true ``J0 + dJ`` (:func:`pd_margins`). :func:`closed_form_pd_margins` gives
the same numbers in closed form for a diagonal M.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import control
import numpy as np
import scipy.optimize

from sc_rt.scenario.model import Scenario
from sc_rt.studies.design.linear import AXES, INERTIAS, error_state_space, input_matrices
from sc_rt.studies.design.pd import PdDesign

__all__ = [
    "CASES",
    "DEFAULT_LATENCY_S",
    "axis_loop",
    "Margins",
    "frequency_response",
    "loop_margins",
    "closed_form_pd_margins",
    "coupling",
    "pd_margins",
]

#: Loop cases of :func:`pd_margins`.
CASES = ("continuous", "zoh", "zoh+delay", "pade")
#: [s] default latency of the Pade case: the p99 state-to-command latency of a
#: 1 kHz real-time HIL run on the development VM (1.19 ms, out/hil_rt/timing.json).
DEFAULT_LATENCY_S = 1.2e-3


def _pade_ss(latency: float, order: int) -> control.StateSpace:
    num, den = control.pade(latency, order)  # a (num, den) tuple
    return control.ss(control.tf(num, den))


def axis_loop(scn: Scenario, beta1: float, beta2: float, axis: int, *, case: str = "continuous",
              rate: float | None = None, inertia: str = "nominal", latency: float = 0.0,
              pade_order: int = 5) -> control.StateSpace:
    """The loop transfer of one axis, loop at a time, broken at ``v_axis``.

    The PD law is ``u = B+ v``, ``v = -(beta1 x1 + beta2 x2)``; the plant
    applies ``M v`` (``M = B_plant B+``, :class:`InputMatrices`). The loop of
    axis i is opened at ``v_i`` with the two other axes closed:
    ``L_i`` is the transfer from an input injected at ``v_i`` to
    ``-v_i``. With ``M = I`` (nominal) it is ``(beta2 s + beta1/4)/s^2``.

    case: ``continuous``; ``zoh`` (``control.c2d(..., 'zoh')`` at ``rate``,
    the command computed and applied at the sample, as ``sc-rt sim`` does);
    ``zoh+delay`` (the same plus one sample of computation delay, the command
    of sample k applied at k + 1); ``pade`` (continuous, each channel
    through a Pade approximation of ``latency`` seconds).
    """
    P = error_state_space(input_matrices(scn, inertia).M)
    if case == "continuous":
        G = P
    elif case == "pade":
        if not latency > 0:
            raise ValueError(f"the pade case needs latency > 0, got {latency!r}")
        D = control.append(*[_pade_ss(latency, pade_order) for _ in range(3)])
        G = control.series(D, P)
    elif case in ("zoh", "zoh+delay"):
        if rate is None or not rate > 0:
            raise ValueError(f"case {case!r} needs a rate > 0, got {rate!r}")
        T = 1.0 / rate
        G = control.c2d(P, T, method="zoh")
        if case == "zoh+delay":
            Z = control.ss(np.zeros((3, 3)), np.eye(3), np.eye(3), np.zeros((3, 3)), T)
            G = control.series(Z, G)
    else:
        raise ValueError(f"case must be one of {CASES}, got {case!r}")
    Ag, Bg, Cg, Dg = (np.asarray(m) for m in (G.A, G.B, G.C, G.D))
    assert np.all(Dg == 0.0), "plant with feedthrough"
    K = np.hstack([beta1 * np.eye(3), beta2 * np.eye(3)])
    E = np.eye(3)
    E[axis, axis] = 0.0  # the other two channels closed
    Ai = Ag - Bg @ E @ K @ Cg
    return control.ss(Ai, Bg[:, [axis]], K[[axis]] @ Cg, [[0.0]], G.dt,
                      name=f"L_{AXES[axis]}_{case}_{inertia}")


@dataclass(frozen=True)
class Margins:
    """Stability margins of one SISO loop L (negative feedback u = -L y)."""

    gm: float  # [-] gain margin: the factor of gain increase to instability (inf: none)
    gm_lower: float  # [-] gain decrease margin (0: none)
    wpc: float | None  # [rad/s] phase crossover of gm
    pm: float  # [deg] phase margin
    wgc: float | None  # [rad/s] gain crossover
    delay_margin: float  # [s] pm [rad] / wgc (continuous seconds, also for sampled loops)
    ms: float  # [-] peak sensitivity max |1/(1 + L)|
    wms: float  # [rad/s] where
    stable: bool  # the closed loop 1/(1 + L) is stable

    @property
    def gm_db(self) -> float:
        return 20 * math.log10(self.gm) if self.gm > 0 else -math.inf

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["gm_db"] = self.gm_db
        return d


def frequency_response(L: control.StateSpace, w: np.ndarray) -> np.ndarray:
    """L at s = jw (or z = exp(jwT)) for a SISO state space, one batched solve.

    (``control``'s own evaluation solves one system per frequency in Python.)
    """
    w = np.atleast_1d(np.asarray(w, float))
    x = np.exp(1j * w * L.dt) if L.isdtime(strict=True) else 1j * w
    A, B, C = np.asarray(L.A), np.asarray(L.B), np.asarray(L.C)
    D = complex(np.asarray(L.D)[0, 0])
    if A.shape[0] == 0:
        return np.full(w.shape, D)
    M = x[:, None, None] * np.eye(A.shape[0]) - A
    X = np.linalg.solve(M, np.broadcast_to(B.astype(complex), (len(w), *B.shape)))
    return (C @ X)[:, 0, 0] + D


def loop_margins(L: control.StateSpace, w_range: tuple[float, float] = (1e-6, 1e6),
                 per_decade: int = 400) -> Margins:
    """Gain, phase and delay margins and the peak sensitivity of a SISO loop.

    Computed here rather than by ``control.stability_margins`` (0.10.2),
    which was compared on every loop of the shipped scenarios (5 scenarios,
    10 / 100 / 1000 Hz, 4 cases, 2 inertias, 3 axes):

    - continuous and Pade loops: the same pm, wgc, gm, wpc to 2e-10, but no
      peak sensitivity for the continuous loops (it returns sm = inf, where
      Ms = 1.0000) and wms only to 3e-6 (a flat peak);
    - ZOH and ZOH + delay loops: wrong. Its polynomial crossing search on
      the double pole at z = 1 finds spurious crossings near w = 0 and
      misses the one at the Nyquist frequency, where L is real
      (``L(-1) = -m beta2 T/2``, so gm = 2/(m beta2 T) exactly): for
      ``paper_faults`` at 10 Hz, axis x, nominal, zoh it gives gm = 2.28 at
      0.48 rad/s and pm = 53.4 deg at 0.76 rad/s against gm = 83.82 at
      pi/T = 31.4 rad/s and pm = 75.64 deg at 0.2455 rad/s here (and the
      closed forms); at 1 kHz gm = 0.96 and pm = -0.48 deg, i.e. "unstable",
      for a loop whose closed-loop eigenvalues are all inside the unit circle.
      ``method="frd"`` does not fix it (gm 0.0058 at 10 Hz).

    tests/test_design.py checks these margins against the closed forms and
    the continuous and Pade ones against ``control.stability_margins``.
    Method: L on a
    logarithmic grid (up to pi/T for a sampled loop), crossings refined with
    Brent's method; gm is the smallest 1/|L| > 1 where L is real negative,
    gm_lower the largest 1/|L| < 1 there; pm the smallest
    180 deg + arg L at |L| = 1; delay margin pm/wgc at that crossover (the
    smallest over crossovers); Ms the maximum of |1/(1 + L)|, refined.
    """
    lo, hi = w_range
    if L.isdtime(strict=True):
        hi = math.pi / L.dt
    n = int(per_decade * math.log10(hi / lo)) + 1
    w = np.logspace(math.log10(lo), math.log10(hi), n)
    w[-1] = hi
    Lw = frequency_response(L, w)

    def at(x):
        return frequency_response(L, np.array([x]))[0]

    def refine(f, a, b):
        return math.exp(scipy.optimize.brentq(lambda lw: f(math.exp(lw)), math.log(a), math.log(b),
                                              xtol=1e-13))

    # gain crossovers
    mag = np.log(np.abs(Lw))
    wg = [refine(lambda x: math.log(abs(at(x))), w[k], w[k + 1])
          for k in np.nonzero(np.sign(mag[:-1]) != np.sign(mag[1:]))[0]]
    pm, wgc, dm = math.inf, None, math.inf
    for x in wg:
        m = math.degrees(np.angle(at(x))) + 180.0
        m = (m + 180.0) % 360.0 - 180.0
        if m < pm:
            pm, wgc = m, x
        if m > 0:
            dm = min(dm, math.radians(m) / x)
    # phase crossovers: L real and negative
    im = Lw.imag
    wp = [refine(lambda x: at(x).imag, w[k], w[k + 1])
          for k in np.nonzero((np.sign(im[:-1]) != np.sign(im[1:])))[0]
          if Lw[k].real < 0 or Lw[k + 1].real < 0]
    if L.isdtime(strict=True) and abs(Lw[-1].imag) <= 1e-9 * abs(Lw[-1]) and Lw[-1].real < 0:
        wp.append(hi)  # Nyquist frequency: L is real there
    gm, wpc, gml = math.inf, None, 0.0
    for x in wp:
        v = at(x)
        if v.real >= 0:
            continue
        g = 1.0 / abs(v)
        if g > 1 and g < gm:
            gm, wpc = g, x
        elif g < 1:
            gml = max(gml, g)
    # peak sensitivity
    S = np.abs(1.0 / (1.0 + Lw))
    k = int(np.argmax(S))
    a, b = w[max(k - 1, 0)], w[min(k + 1, len(w) - 1)]
    ms, wms = float(S[k]), float(w[k])
    if b > a:
        r = scipy.optimize.minimize_scalar(lambda lw: -abs(1 / (1 + at(math.exp(lw)))),
                                           bounds=(math.log(a), math.log(b)), method="bounded",
                                           options={"xatol": 1e-12})
        if -r.fun > ms:
            ms, wms = float(-r.fun), float(math.exp(r.x))
    # closed-loop stability of 1/(1 + L)
    Acl = np.asarray(L.A) - np.asarray(L.B) @ np.asarray(L.C) / (1.0 + float(np.asarray(L.D)[0, 0]))
    ev = np.linalg.eigvals(Acl)
    stable = bool(np.all(np.abs(ev) < 1.0)) if L.isdtime(strict=True) else bool(np.all(ev.real < 0))
    return Margins(gm=gm, gm_lower=gml, wpc=wpc, pm=pm, wgc=wgc, delay_margin=dm, ms=ms, wms=wms,
                   stable=stable)


def closed_form_pd_margins(beta1: float, beta2: float, m: float = 1.0,
                           rate: float | None = None) -> dict[str, float]:
    """Closed forms for L = m (beta2 s + beta1/4)/s^2 (one axis, M_ii = m).

    Continuous: ``wgc^2 = (m^2 beta2^2 + sqrt(m^4 beta2^4 + m^2 beta1^2/4))/2``,
    ``pm = atan(4 beta2 wgc / beta1)``, gm infinite, delay margin pm/wgc.
    Sampled with ZOH at T = 1/rate: the loop is real at the Nyquist frequency,
    ``L(-1) = -m beta2 T/2``, so ``gm = 2/(m beta2 T)`` exactly; the ZOH
    is a half-sample lag, ``pm_zoh = pm - wgc T/2`` to O((wgc T)^2), and the
    computation delay one more sample, ``pm_zoh+delay = pm - 3 wgc T/2``.
    """
    wgc = math.sqrt((m * m * beta2 * beta2 + math.sqrt(m**4 * beta2**4 + m * m * beta1 * beta1 / 4))
                    / 2)
    pm = math.atan(4 * beta2 * wgc / beta1)
    out = {"wgc": wgc, "pm": math.degrees(pm), "delay_margin": pm / wgc, "gm": math.inf}
    if rate is not None:
        T = 1.0 / rate
        out["gm_zoh"] = 2.0 / (m * beta2 * T)
        out["pm_zoh"] = math.degrees(pm - wgc * T / 2)
        out["pm_zoh+delay"] = math.degrees(pm - 1.5 * wgc * T)
    return out


def coupling(scn: Scenario, inertia: str = "true", t: float | None = None) -> dict[str, Any]:
    """M = B_plant B+ and its coupling: max_j!=i |M_ij| / |M_ii| per row.

    Zero for the paper (diagonal J0 and dJ): the loop-at-a-time loops are then
    exactly the per-axis SISO loops with gain M_ii = (J0 + dJ)_ii^-1 J0_ii.
    """
    M = input_matrices(scn, inertia, t).M
    off = np.abs(M - np.diag(np.diag(M)))
    return {"M": M.tolist(), "diag": np.diag(M).tolist(),
            "coupling": (off.max(axis=1) / np.abs(np.diag(M))).tolist()}


def pd_margins(scn: Scenario, pd: PdDesign | tuple[float, float], *, rate: float | None = None,
               latency: float = DEFAULT_LATENCY_S, cases=CASES, inertias=INERTIAS,
               pade_order: int = 5) -> list[dict[str, Any]]:
    """Margins of each axis loop for every case and inertia: one dict per (case, inertia, axis)."""
    b1, b2 = (pd.beta1, pd.beta2) if isinstance(pd, PdDesign) else pd
    rate = scn.run.control_rate_hz if rate is None else float(rate)
    rows = []
    for inertia in inertias:
        for case in cases:
            for i in range(3):
                L = axis_loop(scn, b1, b2, i, case=case, rate=rate, inertia=inertia,
                              latency=latency, pade_order=pade_order)
                row = {"case": case, "inertia": inertia, "axis": AXES[i], "rate_hz": rate,
                       "latency_s": latency if case == "pade" else None}
                row.update(loop_margins(L).as_dict())
                rows.append(row)
    return rows

