"""Linear design and analysis with python-control (docs/DESIGN.md).

What is here, in the order of docs/DESIGN.md:

1. **Error dynamics, linearised** about ``sigma_BD = 0, omega_BD_B = 0``:
   analytically (:func:`error_model`: ``x1' = G(0) x2 = x2/4``,
   ``x2' = B u``) and numerically (:func:`error_system`, a ``control.nlsys``
   around the real plant :func:`sc_rt.model.plant.derivative` and the error
   equations (8)-(11); :func:`linearize_error` calls ``control.linearize``).
2. **PD baseline design** (:func:`design_pd`, :func:`default_pd_design`):
   ``u = -B+ (beta1 x1 + beta2 x2)`` closes each axis as
   ``x1'' + beta2 x1' + beta1/4 x1 = 0``, so ``beta1 = 4 wn^2`` and
   ``beta2 = 2 zeta wn``. Default spec: critically damped (zeta = 1) with the
   2 % settling time of the slowest prescribed envelope,
   ``Ts = ln(1/0.02) / min(gamma)`` (48.9 s for the paper's gamma).
3. **Margins of each axis loop** (:func:`pd_margins`): loop at a time, broken
   at the axis acceleration command ``v`` (``u = B+ v``), continuous, sampled
   with a zero-order hold, sampled with a one-sample computation delay, and
   continuous with a Pade latency; nominal ``J0`` and true ``J0 + dJ``.
4. **Sampled-data stability of DSC+PPC and DSC** (:func:`sampled_closed_loop`,
   :func:`spectral_radius`, :func:`stability_limit`): the closed loop
   linearised at the error origin with the PPC gain ``r`` frozen at ``chi(t)``,
   plant with a ZOH over one period, controller updates exactly as
   ``cpp/src/controllers.cpp`` and ``cpp/src/neso.cpp`` do them; the spectral
   radius over t, the predicted loss of stability, the smallest stable
   ``chiinf``. :func:`simulated_loss_of_stability` measures the same thing
   in a simulation.
5. :func:`design_report` and :func:`write_design` (``sc-rt design``).

Units: SI (rad, rad/s, rad/s^2, s, Hz). Angles of margins in degrees.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import control
import numpy as np
import scipy.optimize

from sc_rt import _core
from sc_rt.model.actuators import fault_Y
from sc_rt.model.plant import PlantParams, derivative
from sc_rt.scenario.model import Scenario

__all__ = [
    "CASES",
    "INERTIAS",
    "DEFAULT_LATENCY_S",
    "SAMPLED_STATES",
    "InputMatrices",
    "input_matrices",
    "error_model",
    "error_system",
    "linearize_error",
    "mrp_add",
    "PdDesign",
    "settling_time_factor",
    "design_pd",
    "default_pd_design",
    "axis_loop",
    "Margins",
    "loop_margins",
    "closed_form_pd_margins",
    "pd_margins",
    "coupling",
    "ppc_gain",
    "sampled_closed_loop",
    "spectral_radius",
    "StabilityLimit",
    "stability_limit",
    "critical_r_estimate",
    "simulated_loss_of_stability",
    "design_report",
    "format_margins_table",
    "format_sampled_table",
    "write_design",
]

#: Loop cases of :func:`pd_margins`.
CASES = ("continuous", "zoh", "zoh+delay", "pade")
#: Inertias: the controller's J0, or the plant's J0 + dJ (model error).
INERTIAS = ("nominal", "true")
#: [s] default latency of the Pade case: the p99 state-to-command latency of a
#: 1 kHz real-time HIL run on the development VM (1.19 ms, out/hil_rt/timing.json).
DEFAULT_LATENCY_S = 1.2e-3
#: 2 % settling.
SETTLING_TOL = 0.02

AXES = ("x", "y", "z")


# --------------------------------------------------------------------------- #
# 1. Error dynamics


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


def _inertia(scn: Scenario, inertia: str) -> np.ndarray:
    if inertia == "nominal":
        return np.array(scn.plant.J0)
    if inertia == "true":
        return np.array(scn.plant.J)
    raise ValueError(f"inertia must be one of {INERTIAS}, got {inertia!r}")


def _effectiveness(scn: Scenario, t: float | None) -> np.ndarray:
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
    eff = _effectiveness(scn, t)
    Bpl = -np.linalg.solve(_inertia(scn, inertia), scn.plant.Cbar * scn.plant.Jw) * eff
    return InputMatrices(B, Bp, Bpl, Bpl @ Bp, eff)


_X_NAMES = [f"sigma_BD[{i}]" for i in range(3)] + [f"omega_BD_B[{i}]" for i in range(3)]
_U_NAMES = [f"wheel_accel[{i}]" for i in range(4)]


def error_model(scn: Scenario, inertia: str = "nominal") -> control.StateSpace:
    """Analytic linearisation of the tracking-error dynamics at the error origin.

    States ``x1 = sigma_BD``, ``x2 = omega_BD_B``; inputs the four wheel
    accelerations; outputs the states. ``x1' = G(0) x2 = x2/4`` (1),(2) and
    ``x2' = B u`` with ``B = -J^-1 Cbar Jw`` (21) (J = J0 for "nominal",
    J0 + dJ for "true"). Neglected: every term of A of (21) whose derivative
    at the origin is O(|omega_d|, |J^-1 h_w|, w0^2), i.e. the gyroscopic and
    transport terms (see :func:`linearize_error` for their size).
    """
    A = np.zeros((6, 6))
    A[0:3, 3:6] = 0.25 * np.eye(3)
    Bm = np.zeros((6, 4))
    Bm[3:6] = input_matrices(scn, inertia).B_plant
    return control.ss(A, Bm, np.eye(6), np.zeros((6, 4)), states=_X_NAMES, inputs=_U_NAMES,
                      outputs=_X_NAMES, name=f"error_model_{inertia}")


def mrp_add(sigma_BD, sigma_DN) -> np.ndarray:
    """sigma_BN from sigma_BD and sigma_DN: the composition that (8) inverts.

    ``mrp_subtract(mrp_add(a, b), b) == a`` (tests/test_design.py).
    """
    a, b = np.asarray(sigma_BD, float), np.asarray(sigma_DN, float)
    aa, bb = a @ a, b @ b
    return ((1 - bb) * a + (1 - aa) * b - 2 * np.cross(a, b)) / (1 + aa * bb - 2 * (a @ b))


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
    J = _inertia(scn, inertia)
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


# --------------------------------------------------------------------------- #
# 2. PD design


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


# --------------------------------------------------------------------------- #
# 3. Margins of the PD loop


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
    M = input_matrices(scn, inertia).M
    A = np.zeros((6, 6))
    A[0:3, 3:6] = 0.25 * np.eye(3)
    Bm = np.zeros((6, 3))
    Bm[3:6] = M
    P = control.ss(A, Bm, np.eye(6), np.zeros((6, 3)))
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


def _response(L: control.StateSpace, w: np.ndarray) -> np.ndarray:
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

    Computed here rather than by ``control.stability_margins``, which misses
    the phase crossover a sampled loop has exactly at the Nyquist frequency
    (there L is real: the ZOH double integrator with PD crosses -180 deg at
    pi/T) and reports a spurious crossover near w = 0 for a sampled double
    integrator. The phase margin and crossover agree with
    ``control.stability_margins`` (tests/test_design.py). Method: L on a
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
    Lw = _response(L, w)

    def at(x):
        return _response(L, np.array([x]))[0]

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


def format_margins_table(rows: list[dict[str, Any]]) -> str:
    """The margins as a fixed-width text table."""

    def f(v, fmt):
        width = int(fmt.split(".")[0])
        if v is None:
            return "-".rjust(width)
        if isinstance(v, float) and math.isinf(v):
            return "inf".rjust(width)
        return format(v, fmt)

    head = (f"{'inertia':<8} {'case':<10} {'axis':<4} {'GM':>9} {'GM[dB]':>7} {'PM[deg]':>8} "
            f"{'wgc[rad/s]':>10} {'DM[s]':>8} {'Ms':>6} {'stable':>6}")
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['inertia']:<8} {r['case']:<10} {r['axis']:<4} {f(r['gm'], '9.4g')} "
                     f"{f(r['gm_db'], '7.1f')} {f(r['pm'], '8.3f')} {f(r['wgc'], '10.5f')} "
                     f"{f(r['delay_margin'], '8.4f')} {f(r['ms'], '6.4f')} {str(r['stable']):>6}")
    return "\n".join(lines)


def format_sampled_table(report: dict[str, Any]) -> str:
    """The sampled-data predictions of a :func:`design_report` as a text table."""

    def f(v, fmt="8.3f"):
        if v is None:
            return "-"
        if isinstance(v, float) and math.isinf(v):
            return "inf"
        return format(v, fmt)

    head = (f"{'law':<8} {'rate[Hz]':>8} {'t_loss[s]':>9} {'axis':>4} {'mode[Hz]':>8} "
            f"{'rho(0)':>9} {'chiinf_min x/y/z (= critical chi)':>36} {'t_crit x/y/z [s]':>24}")
    lines = [head, "-" * len(head)]
    for law, by_rate in report["sampled_data"]["limits"].items():
        for key, lim in sorted(by_rate.items(), key=lambda kv: float(kv[0])):
            cc = " ".join(f(c, "11.3e") for c in lim["chi_crit"]) if lim["chi_crit"] else "-"
            tc = " ".join(f(c, "7.2f") for c in lim["t_crit_s"]) if lim["t_crit_s"] else "-"
            lines.append(f"{law:<8} {float(key):>8g} {f(lim['t_loss_s'], '9.2f'):>9} "
                         f"{lim['axis'] or '-':>4} {f(lim['mode_hz'], '8.3f'):>8} "
                         f"{f(lim['rho_at_0'], '9.6f')} {cc:>36} {tc:>24}")
    return "\n".join(lines)


# --------------------------------------------------------------------------- #
# 4. Sampled-data stability of the nonlinear laws

#: State of the linear sampled loop, at t_k just before the controller's step k.
SAMPLED_STATES = (
    [f"x1[{i}]" for i in range(3)]          # plant sigma_BD at t_k
    + [f"x2[{i}]" for i in range(3)]        # plant omega_BD_B at t_k
    + [f"x2d[{i}]" for i in range(3)]       # filter (37), value of step k-1
    + [f"x2bar_prev[{i}]" for i in range(3)]  # virtual control (36) of step k-1
    + [f"vs[{i}]" for i in range(4)]        # anti-windup (42), step k-1
    + [f"z1[{i}]" for i in range(3)]        # observer (22) at t_{k-1}
    + [f"z2[{i}]" for i in range(3)]
    + [f"x2_prev[{i}]" for i in range(3)]   # measured x2 of step k-1 (observer interpolation)
    + [f"Bu_prev[{i}]" for i in range(3)]   # B sat(u_{k-1}), held by the observer
)
_S = {name: i for i, name in enumerate(SAMPLED_STATES)}


def _blk(name: str, n: int) -> slice:
    i = _S[f"{name}[0]"]
    return slice(i, i + n)


def ppc_gain(scn: Scenario, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(chi(t), r at x1 = 0, rho = -chi_dot/chi) per axis.

    ``r_i = 1/(2 chi_i) [1/dmin_i + 1/dmax_i]`` (35) at lambda = 0;
    ``rho_i = gamma_i (chi_i - chiinf_i)/chi_i``.
    """
    p = scn.controller.ppc
    e = np.exp(-np.asarray(p.gamma) * t)
    chi = (p.chi0 - p.chiinf) * e + p.chiinf
    chi_dot = -p.gamma * (p.chi0 - p.chiinf) * e
    r = 0.5 / chi * (1.0 / p.dmin + 1.0 / p.dmax)
    return chi, r, -chi_dot / chi


def _observer_gains(scn: Scenario, observer: str, amplitude: float) -> tuple[np.ndarray, np.ndarray]:
    n = scn.controller.neso
    if observer == "linear-part":
        return np.array(n.k2, float), np.array(n.k4, float)
    if observer == "local-gain":
        a = float(n.alpha)
        g1 = a * amplitude ** (a - 1.0)
        g2 = (2 * a - 1) * amplitude ** (2 * a - 2.0)
        return n.k2 + n.k1 * g1, n.k4 + n.k3 * g2
    raise ValueError(f"observer must be 'linear-part' or 'local-gain', got {observer!r}")


class _SampledLoop:
    """The parts of :func:`sampled_closed_loop` that do not depend on t (built once)."""

    def __init__(self, scn: Scenario, law: str, rate: float | None, *, inertia: str = "true",
                 faults: bool = True, observer: str = "linear-part",
                 observer_amplitude: float = 1e-5):
        if law not in ("dsc-ppc", "dsc"):
            raise ValueError(f"law must be 'dsc-ppc' or 'dsc', got {law!r}")
        self.scn, self.law, self.inertia, self.faults = scn, law, inertia, faults
        self.rate = scn.run.control_rate_hz if rate is None else float(rate)
        T = 1.0 / self.rate
        self.T = T
        im = input_matrices(scn, inertia)
        self.B, self.Bp = im.B, im.B_pinv
        self.Bpl_healthy = im.B_plant
        self.K1, self.K2 = (v.reshape(-1, 1) for v in _observer_gains(scn, observer,
                                                                        observer_amplitude))
        self.ns = int(scn.controller.neso.substeps)
        self.g = scn.controller.dsc
        # plant x1' = x2/4, x2' = w (axis acceleration), ZOH over one period
        Ac = np.zeros((6, 6))
        Ac[0:3, 3:6] = 0.25 * np.eye(3)
        Bc = np.zeros((6, 3))
        Bc[3:6] = np.eye(3)
        Pd = control.c2d(control.ss(Ac, Bc, np.eye(6), np.zeros((6, 3))), T, method="zoh")
        self.Phi, self.Gw = np.asarray(Pd.A), np.asarray(Pd.B)
        self.a = math.exp(-T / self.g.tau)
        self.b = math.exp(-self.g.k4 * T)
        self.has_faults = faults and bool(scn.actuators.faults)

    def gains(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        if self.law == "dsc":
            return np.ones(3), np.zeros(3)
        _, r, rho = ppc_gain(self.scn, t)
        return r, rho

    def phi(self, t: float, r=None, rho=None) -> np.ndarray:
        r_t, rho_t = self.gains(t)
        r = r_t if r is None else np.asarray(r, float)
        rho = rho_t if rho is None else np.asarray(rho, float)
        Bpl = self.Bpl_healthy * _effectiveness(self.scn, t) if self.has_faults else self.Bpl_healthy
        Gam = self.Gw @ Bpl  # ZOH input matrix of the wheel commands u
        g, T, ns, B, Bp, K1, K2 = self.g, self.T, self.ns, self.B, self.Bp, self.K1, self.K2
        a, b, Phi = self.a, self.b, self.Phi
        r_, rho_ = r.reshape(-1, 1), rho.reshape(-1, 1)
        S = np.eye(len(SAMPLED_STATES))
        # The C++ step order of DscController::law_step, on the columns of S.
        x1, x2, x2d, xb = S[_blk("x1", 3)], S[_blk("x2", 3)], S[_blk("x2d", 3)], S[_blk("x2bar_prev", 3)]
        vs, z1, z2 = S[_blk("vs", 4)], S[_blk("z1", 3)], S[_blk("z2", 3)]
        x2p, bu = S[_blk("x2_prev", 3)], S[_blk("Bu_prev", 3)]

        def f(z1, z2, x):  # (22) linearised, A left out
            e = z1 - x
            return bu + z2 - K1 * e, -K2 * e

        hs = T / ns
        dx = x2 - x2p
        for k in range(ns):  # Neso::update: RK4, B u held, x2 linear in time
            xa, xm, xe = x2p + (k / ns) * dx, x2p + ((k + 0.5) / ns) * dx, x2p + ((k + 1) / ns) * dx
            k1 = f(z1, z2, xa)
            k2 = f(z1 + 0.5 * hs * k1[0], z2 + 0.5 * hs * k1[1], xm)
            k3 = f(z1 + 0.5 * hs * k2[0], z2 + 0.5 * hs * k2[1], xm)
            k4 = f(z1 + hs * k3[0], z2 + hs * k3[1], xe)
            z1 = z1 + (hs / 6) * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            z2 = z2 + (hs / 6) * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        x2d = a * x2d + (1 - a) * xb          # (37), exact with x2bar held
        vs = b * vs                           # (42), exact; du = 0 without saturation
        xbar = -4.0 * (g.k1 + rho_) * x1      # (36) at the origin
        x2d_dot = (xbar - x2d) / g.tau        # (37) at t_k
        e2 = x2 - x2d                         # (27)
        v = -g.k2 * e2 - 0.25 * r_ * r_ * x1 - g.k3 * (B @ vs) - z2 + x2d_dot  # (41)
        u = Bp @ v
        xn = Phi @ np.vstack([x1, x2]) + Gam @ u  # plant, ZOH over [t_k, t_k+1]
        return np.vstack([xn, x2d, xbar, vs, z1, z2, x2, B @ u])

    def rho(self, t: float, r=None, rho=None) -> float:
        return float(np.max(np.abs(np.linalg.eigvals(self.phi(t, r, rho)))))


def sampled_closed_loop(scn: Scenario, law: str = "dsc-ppc", rate: float | None = None,
                        t: float = 0.0, *, inertia: str = "true", faults: bool = True,
                        observer: str = "linear-part", observer_amplitude: float = 1e-5,
                        r: np.ndarray | None = None, rho: np.ndarray | None = None) -> np.ndarray:
    """One control period of the linearised sampled closed loop: s_{k+1} = Phi s_k.

    The state is :data:`SAMPLED_STATES` (28). Linearisation at the error
    origin (x1 = x2 = 0, the controller's states 0, no saturation so du = 0)
    with the PPC gain frozen at time t (``r``, ``rho`` override it):

    - x2bar (36) = -G(0)^-1 (k1 r^-1 e1 - Lambda chi_dot) = -4 (k1 + rho) x1,
      since e1 = r x1 + O(x1^2) and Lambda chi_dot = -rho x1;
    - (41): v = -k2 e2 - G(0)' r e1 - k3 B vs - z2 + x2d_dot with
      G(0)' r e1 = r^2 x1 / 4; u = B+ v; DSC: e1 = x1, r = 1, rho = 0;
    - the model term A of (21) is cancelled by the law and is exogenous to
      first order (its derivative at the origin is O(omega_d)); it is left out
      of the plant, the law and the observer alike;
    - observer (22): ``substeps`` RK4 steps with B u held and x2 interpolated
      linearly between the two samples, as cpp/src/neso.cpp. sig^alpha is not
      differentiable at 0: "linear-part" keeps only the linear k2, k4 terms
      (default); "local-gain" replaces sig^a(e) by its slope a |e|^(a-1) at
      |e| = observer_amplitude (exact for alpha = 1);
    - filter (37) and compensator (42): the exact updates of controllers.cpp
      (x2d uses x2bar of the previous step, x2d_dot = (x2bar - x2d)/tau at
      the sample);
    - plant: x1' = x2/4, x2' = B_plant u (true inertia, and with ``faults`` the
      wheels' effectiveness at t), held over the period: exact ZOH
      (``control.c2d``).
    """
    return _SampledLoop(scn, law, rate, inertia=inertia, faults=faults, observer=observer,
                        observer_amplitude=observer_amplitude).phi(t, r, rho)


def spectral_radius(scn: Scenario, law: str = "dsc-ppc", rate: float | None = None,
                    times=None, **kw) -> np.ndarray:
    """max |eig(Phi(t))| of :func:`sampled_closed_loop` at each of ``times`` [s]."""
    times = np.atleast_1d(np.asarray(0.0 if times is None else times, float))
    loop = _SampledLoop(scn, law, rate, **kw)
    return np.array([loop.rho(t) for t in times])


def critical_r_estimate(scn: Scenario, rate: float) -> float:
    """Rule of thumb for the critical PPC gain: r_crit = 4 sqrt(2 k2 f).

    At the origin the stiffness G' r e1 = r^2/4 x1 and the damping k2 make a
    mode x1'' + k2 x1' + (r/4)^2 x1 = 0 (omega = r/4, damping k2). A delay tau
    in the stiffness path removes omega^2 tau of damping; the ZOH is a delay
    of T/2, so the mode loses its damping when (r/4)^2 T/2 = k2. Within 1 %
    of the exact spectral-radius crossing for the paper (docs/DESIGN.md).
    """
    return 4.0 * math.sqrt(2.0 * scn.controller.dsc.k2 * rate)


@dataclass
class StabilityLimit:
    """Prediction of :func:`stability_limit` (times from the controller's engagement)."""

    law: str
    rate_hz: float
    horizon_s: float
    t_loss_s: float | None  # first t with spectral radius >= 1 (None: stable to the horizon)
    axis: str | None  # the axis whose mode goes unstable
    mode_hz: float | None  # frequency of the unstable eigenvalue at t_loss
    rho_at_0: float  # spectral radius at t = 0
    rho_at_horizon: float
    # per axis (dsc-ppc only): critical r and chi, the time chi_i(t) reaches it, and
    # the smallest chiinf_i that stays stable at this rate (= the critical chi)
    r_crit: list[float] | None = None
    chi_crit: list[float] | None = None
    t_crit_s: list[float | None] | None = None
    chiinf_min: list[float] | None = None
    r_crit_rule_of_thumb: float | None = None
    options: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _first_crossing(f, t0: float, t1: float, dt: float) -> float | None:
    """First t in [t0, t1] with f(t) >= 0 (grid scan, then bisection)."""
    ts = np.arange(t0, t1 + 0.5 * dt, dt)
    prev = t0
    for t in ts:
        if f(t) >= 0:
            if t == t0:
                return t0
            lo, hi = prev, t
            for _ in range(50):
                mid = 0.5 * (lo + hi)
                if f(mid) >= 0:
                    hi = mid
                else:
                    lo = mid
                if hi - lo < 1e-6:
                    break
            return hi
        prev = t
    return None


def stability_limit(scn: Scenario, law: str = "dsc-ppc", rate: float | None = None, *,
                    horizon: float | None = None, grid: float = 0.25, **kw) -> StabilityLimit:
    """Predicted loss of stability of the sampled loop at ``rate``.

    ``t_loss_s``: the first time in [0, horizon] (default: the scenario's
    duration) at which the spectral radius of :func:`sampled_closed_loop`
    reaches 1 (grid scan with step ``grid``, then bisection to 1 us).
    For dsc-ppc, per axis i, with the other axes held at chi0 (stable):
    ``r_crit`` / ``chi_crit`` where axis i alone makes the loop unstable
    (rho = 0, the envelope's final state), ``t_crit_s`` when chi_i(t) reaches
    it, and ``chiinf_min`` = chi_crit: the smallest chiinf_i that stays
    stable at this rate. ``kw`` goes to :func:`sampled_closed_loop`.
    """
    rate = scn.run.control_rate_hz if rate is None else float(rate)
    horizon = scn.run.duration if horizon is None else float(horizon)

    loop = _SampledLoop(scn, law, rate, **kw)
    rho_of = loop.rho

    t_loss = _first_crossing(lambda t: rho_of(t) - 1.0, 0.0, horizon, grid)
    axis = mode_hz = None
    if t_loss is not None:
        Phi = loop.phi(t_loss)
        ev, V = np.linalg.eig(Phi)
        k = int(np.argmax(np.abs(ev)))
        mode_hz = abs(float(np.angle(ev[k]))) * rate / (2 * math.pi)
        axis = AXES[int(np.argmax(np.abs(V[_blk("x1", 3), k])))]
    out = StabilityLimit(law=law, rate_hz=rate, horizon_s=horizon, t_loss_s=t_loss, axis=axis,
                         mode_hz=mode_hz, rho_at_0=rho_of(0.0), rho_at_horizon=rho_of(horizon),
                         options={k: v for k, v in kw.items() if k in ("inertia", "faults", "observer",
                                                                         "observer_amplitude")})
    if law != "dsc-ppc":
        return out
    p = scn.controller.ppc
    _, r0, _ = ppc_gain(scn, 0.0)
    kfac = 0.5 * (1.0 / p.dmin + 1.0 / p.dmax)
    r_crit, chi_crit, t_crit = [], [], []
    for i in range(3):
        def unstable(log_r, i=i):
            r = r0.copy()
            r[i] = math.exp(log_r)
            return rho_of(horizon, r, np.zeros(3)) - 1.0

        lo, hi = math.log(r0[i]), math.log(1e12)
        if unstable(lo) >= 0:
            rc = r0[i]
        elif unstable(hi) < 0:
            rc = math.inf
        else:
            rc = math.exp(scipy.optimize.brentq(unstable, lo, hi, xtol=1e-10))
        r_crit.append(rc)
        cc = kfac[i] / rc
        chi_crit.append(cc)
        # chi_i(t) = cc with the envelope's time-varying rho at that t
        if cc >= p.chi0[i]:
            t_crit.append(0.0)
        elif cc <= p.chiinf[i] or p.gamma[i] == 0:
            t_crit.append(None)
        else:
            t_guess = math.log((p.chi0[i] - p.chiinf[i]) / (cc - p.chiinf[i])) / p.gamma[i]

            def g(t, i=i):
                _, r_t, rho_t = ppc_gain(scn, t)
                r = r0.copy()
                r[i] = r_t[i]
                rh = np.zeros(3)
                rh[i] = rho_t[i]
                return rho_of(t, r, rh) - 1.0

            a_, b_ = max(0.0, t_guess - 5.0), t_guess + 5.0
            t_crit.append(float(scipy.optimize.brentq(g, a_, b_, xtol=1e-6))
                          if g(a_) < 0 <= g(b_) else t_guess)
    out.r_crit, out.chi_crit, out.t_crit_s = r_crit, chi_crit, t_crit
    out.chiinf_min = chi_crit
    out.r_crit_rule_of_thumb = critical_r_estimate(scn, rate)
    return out


def simulated_loss_of_stability(scn: Scenario, law: str = "dsc-ppc", rate: float | None = None, *,
                                duration: float | None = None, window: float = 1.0,
                                engine: str = "cpp", result=None) -> dict[str, Any]:
    """Where a simulation loses stability (``sc_rt.sim.engines.simulate``).

    Two measures: ``first_bound_violation_s`` (the metric of analysis.py) and,
    per axis, the growth onset: the time at which the windowed peak of
    |sigma_BD_i| (windows of ``window`` seconds) is smallest before the first
    bound violation, i.e. when the error stops decreasing and starts to grow.
    For a slowly time-varying linear loop the envelope of a mode obeys
    d ln|x|/dt = f ln rho(t): it is smallest where the spectral radius
    crosses 1, so the onset is the measure to compare with t_loss. It is only
    meaningful when the run has reached the small-signal regime
    (``lam_at_onset`` << 1 and no saturation there).
    """
    from sc_rt.sim.engines import simulate

    res = result if result is not None else simulate(scn, law=law, engine=engine,
                                                     control_rate_hz=rate, duration=duration)
    tr, m = res.trajectory, res.metrics
    t, x1, chi = tr["t"], np.abs(tr["sigma_BD"]), tr["chi"]
    sat = np.any(tr["u_cmd"] != tr["u_sat"], axis=1)
    tb = m["first_bound_violation_s"]
    end = len(t) if tb is None else int(np.searchsorted(t, tb))
    dt = t[1] - t[0]
    n = max(1, int(round(window / dt)))
    nw = end // n
    out: dict[str, Any] = {"law": m["controller"], "rate_hz": m["control_rate_hz"],
                           "first_bound_violation_s": tb,
                           "first_bound_violation_axis": m["first_bound_violation_axis"],
                           "window_s": n * dt, "onset_s": [None] * 3, "min_error": [None] * 3,
                           "lam_at_onset": [None] * 3, "saturated_at_onset": [None] * 3}
    if tb is not None:
        k0 = max(0, end - int(round(1.0 / dt)))
        out["saturated_fraction_before_violation"] = float(np.mean(sat[k0:end + 1]))
    if nw < 2:
        return out
    P = x1[: nw * n].reshape(nw, n, 3).max(axis=1)
    for i in range(3):
        j = int(np.argmin(P[:, i]))
        sl = slice(j * n, (j + 1) * n)
        out["onset_s"][i] = float(t[j * n] + 0.5 * n * dt)
        out["min_error"][i] = float(P[j, i])
        out["lam_at_onset"][i] = float(np.max(x1[sl, i] / chi[sl, i]))
        out["saturated_at_onset"][i] = float(np.mean(sat[sl]))
    return out


# --------------------------------------------------------------------------- #
# 5. Report, design.json, figures


def design_report(scn: Scenario, rate: float | None = None, *, latency: float = DEFAULT_LATENCY_S,
                  pd: PdDesign | None = None, context_rates=(10.0, 100.0, 1000.0),
                  inertia: str = "true", observer: str = "linear-part") -> dict[str, Any]:
    """Everything ``sc-rt design`` prints and writes, as one JSON-able dict."""
    rate = scn.run.control_rate_hz if rate is None else float(rate)
    pd = default_pd_design(scn) if pd is None else pd
    rows = pd_margins(scn, pd, rate=rate, latency=latency)
    rates = sorted({rate, *map(float, context_rates)})
    sampled = {}
    for law in ("dsc-ppc", "dsc"):
        sampled[law] = {f"{f:g}": stability_limit(scn, law, f, inertia=inertia, faults=True,
                                                  observer=observer).as_dict()
                        for f in rates}
    return {
        "scenario": scn.name,
        "scenario_path": str(scn.path),
        "rate_hz": rate,
        "latency_s": latency,
        "pd": asdict(pd),
        "pd_in_scenario": {"beta1": float(scn.controller.pd.beta1),
                           "beta2": float(scn.controller.pd.beta2)},
        "closed_form": {inertia_: [closed_form_pd_margins(pd.beta1, pd.beta2, m, rate)
                                   for m in np.diag(input_matrices(scn, inertia_).M)]
                        for inertia_ in INERTIAS},
        "coupling": {i: coupling(scn, i) for i in INERTIAS},
        "margins": rows,
        "sampled_data": {"inertia": inertia, "faults": True, "observer": observer,
                         "limits": sampled},
    }


def _plot_loops(scn: Scenario, pd: PdDesign, rate: float, latency: float, out: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    styles = {"continuous": "C0", "zoh": "C1", "zoh+delay": "C2", "pade": "C3"}
    loops = {}
    for inertia in INERTIAS:
        for case in CASES:
            for i in range(3):
                loops[inertia, case, i] = axis_loop(scn, pd.beta1, pd.beta2, i, case=case, rate=rate,
                                                    inertia=inertia, latency=latency)
    w = np.logspace(-3, math.log10(math.pi * rate), 800)
    resp = {k: _response(L, w) for k, L in loops.items()}
    paths = []
    fig, axs = plt.subplots(2, 3, figsize=(13, 6.5), sharex=True)
    for (inertia, case, i), H in resp.items():
        ls = "-" if inertia == "nominal" else "--"
        lab = f"{case}, {inertia}" if i == 0 else None
        axs[0, i].semilogx(w, 20 * np.log10(np.abs(H)), ls, color=styles[case], lw=1, label=lab)
        axs[1, i].semilogx(w, np.degrees(np.unwrap(np.angle(H))) - 360 * (np.angle(H[0]) > 0),
                           ls, color=styles[case], lw=1)
    for i in range(3):
        axs[0, i].axhline(0, color="k", lw=0.6)
        axs[1, i].axhline(-180, color="k", lw=0.6)
        axs[0, i].set_title(f"axis {AXES[i]}: L = (beta2 s + beta1/4) M_ii / s^2")
        axs[1, i].set_xlabel("w [rad/s]")
        for ax in axs[:, i]:
            ax.grid(alpha=0.3, which="both")
    axs[0, 0].set_ylabel("|L| [dB]")
    axs[1, 0].set_ylabel("arg L [deg]")
    axs[0, 0].legend(fontsize=7)
    fig.suptitle(f"{scn.name}: PD loop at a time, beta1 = {pd.beta1:.4g}, beta2 = {pd.beta2:.4g}, "
                 f"{rate:g} Hz, latency {latency * 1e3:g} ms (pade)")
    paths.append(_save(fig, out / "bode.png"))

    fig, axs = plt.subplots(1, 3, figsize=(14, 4.8))
    for (inertia, case, i), H in resp.items():
        ls = "-" if inertia == "nominal" else "--"
        ph = np.degrees(np.unwrap(np.angle(H))) - 360 * (np.angle(H[0]) > 0)
        axs[i].plot(ph, 20 * np.log10(np.abs(H)), ls, color=styles[case], lw=1,
                    label=f"{case}, {inertia}" if i == 0 else None)
    for i in range(3):
        axs[i].plot([-180], [0], "rx", ms=9)
        axs[i].set_xlim(-270, -60)
        axs[i].set_ylim(-60, 60)
        axs[i].set_xlabel("arg L [deg]")
        axs[i].set_title(f"Nichols, axis {AXES[i]}")
        axs[i].grid(alpha=0.3)
    axs[0].set_ylabel("|L| [dB]")
    axs[0].legend(fontsize=7)
    paths.append(_save(fig, out / "nichols.png"))
    return paths


def _save(fig, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _plot_spectral(scn: Scenario, report: dict[str, Any], out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sd = report["sampled_data"]
    kw = dict(inertia=sd["inertia"], faults=sd["faults"], observer=sd["observer"])
    rate = report["rate_hz"]
    limits = sd["limits"]["dsc-ppc"]
    horizon = scn.run.duration
    ts = np.linspace(0.0, horizon, 601)
    fig, axs = plt.subplots(2, 1, figsize=(9, 7.5), sharex=True)
    for j, (key, lim) in enumerate(sorted(limits.items(), key=lambda kv: float(kv[0]))):
        f = float(key)
        rho = spectral_radius(scn, "dsc-ppc", f, ts, **kw)
        lw = 2.0 if f == rate else 1.0
        axs[0].semilogy(ts, rho, color=f"C{j}", lw=lw, label=f"DSC+PPC, {f:g} Hz")
        if lim["t_loss_s"] is not None:
            axs[0].axvline(lim["t_loss_s"], color=f"C{j}", ls=":", lw=0.8)
            axs[0].annotate(f"{lim['t_loss_s']:.1f} s", (lim["t_loss_s"], 1.0), xytext=(3, -12 - 10 * j),
                            textcoords="offset points", color=f"C{j}", fontsize=8)
        rho_dsc = sd["limits"]["dsc"][key]["rho_at_0"]
        axs[0].axhline(rho_dsc, color=f"C{j}", ls="--", lw=0.6)
    axs[0].axhline(1.0, color="k", lw=0.8)
    axs[0].set_ylim(0.9, 1e3)
    axs[0].set_ylabel("spectral radius of the sampled loop")
    axs[0].set_title(f"{scn.name}: linearised sampled loop, r frozen at chi(t) "
                     f"(dashed: DSC without PPC)")
    axs[0].legend(fontsize=8)
    axs[0].grid(alpha=0.3, which="both")
    p = scn.controller.ppc
    chi = (p.chi0 - p.chiinf) * np.exp(-np.outer(ts, p.gamma)) + p.chiinf
    lim = limits[f"{rate:g}"]
    for i in range(3):
        axs[1].semilogy(ts, chi[:, i], color=f"C{i}", label=f"chi_{AXES[i]}(t)")
        if lim["chi_crit"] is not None:
            axs[1].axhline(lim["chi_crit"][i], color=f"C{i}", ls="--", lw=0.8,
                           label=f"critical chi_{AXES[i]} at {rate:g} Hz")
    axs[1].set_xlabel("t [s]")
    axs[1].set_ylabel("chi [-]")
    axs[1].legend(fontsize=8, ncol=2)
    axs[1].grid(alpha=0.3, which="both")
    return _save(fig, out / "spectral_radius.png")


def write_design(report: dict[str, Any], scn: Scenario, out: Path, plots: bool = True) -> list[Path]:
    """design.json and the figures (bode.png, nichols.png, spectral_radius.png) into out/."""
    from sc_rt.results.metrics import json_safe

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    if plots:
        pd = PdDesign(**report["pd"])
        paths += _plot_loops(scn, pd, report["rate_hz"], report["latency_s"], out)
        paths.append(_plot_spectral(scn, report, out))
    report = dict(report, figures=[p.name for p in paths])
    path = out / "design.json"
    path.write_text(json.dumps(json_safe(report), indent=2) + "\n")
    return [path, *paths]
