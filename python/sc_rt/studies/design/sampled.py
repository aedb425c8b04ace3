"""The sampled-data closed loop of DSC+PPC and DSC, linearised (docs/DESIGN.md, section 4).

One control period of plant (ZOH), law, filter, anti-windup and observer as a
28x28 map (:func:`sampled_closed_loop`), the controller's step alone
(:func:`controller_step`) and the spectral radius over t
(:func:`spectral_radius`). What comes from where:

- observer (22): the C++ core's own ``Neso.update`` (``_core.Neso``),
  evaluated on unit inputs: with alpha = 1 its right-hand side is linear, so
  the superposition is exact and the map is the core's RK4, not a copy;
- PPC gain at the origin: the core's ``ppc_transform`` at x1 = 0 (29), (35);
- the law (36), (37), (41), (42) linearised at the origin: written out here,
  in the order of ``DscLaw::step`` (cpp/src/law_dsc.cpp). It
  cannot be taken from ``_core.Controller`` by finite differences: the
  binding does not expose the controller's internal states (x2d, x2bar,
  vs, z1, z2, the held x2 and B u) to set, and sig^alpha has an infinite
  slope at 0. tests/test_design.py checks it against ``_core.Controller.step``
  (central differences, alpha = 1, random states) to 1e-12.
"""

from __future__ import annotations

import math

import control
import numpy as np

from sc_rt import _core
from sc_rt.studies.lawparams import dsc_gains, neso_params
from sc_rt.scenario.model import Scenario
from sc_rt.studies.design.linear import error_state_space, input_matrices, wheel_effectiveness

__all__ = [
    "SAMPLED_STATES",
    "CONTROLLER_OUTPUTS",
    "ppc_gain",
    "observer_gains",
    "observer_map",
    "SampledLoop",
    "controller_step",
    "sampled_closed_loop",
    "spectral_radius",
]

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
#: Rows of :func:`controller_step`: what the controller's step k computes
#: (``u_cmd``, and the values of x2d, vs, z1, z2 that its Command reports).
CONTROLLER_OUTPUTS = (
    [f"u[{i}]" for i in range(4)]
    + [f"x2d[{i}]" for i in range(3)]
    + [f"x2bar[{i}]" for i in range(3)]
    + [f"vs[{i}]" for i in range(4)]
    + [f"z1[{i}]" for i in range(3)]
    + [f"z2[{i}]" for i in range(3)]
)
_S = {name: i for i, name in enumerate(SAMPLED_STATES)}


def _blk(name: str, n: int) -> slice:
    i = _S[f"{name}[0]"]
    return slice(i, i + n)


def ppc_gain(scn: Scenario, t: float, ppc=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(chi(t), r at x1 = 0, rho = -chi_dot/chi) per axis.

    From the core's ``ppc_transform`` at x1 = 0: chi (29) and
    ``r_i = 1/(2 chi_i) [1/dmin_i + 1/dmax_i]`` (35) at lambda = 0;
    ``rho_i = gamma_i (chi_i - chiinf_i)/chi_i``. ``ppc``: the core's
    ``PpcParams`` if already built (default: the scenario's).
    """
    p = scn.core_config().ppc if ppc is None else ppc
    res = _core.ppc_transform(p, np.zeros(3), float(t))
    chi = np.array(res.chi, float)
    return chi, np.array(res.r, float), -np.array(res.chi_dot, float) / chi


def observer_gains(scn: Scenario, observer: str, amplitude: float,
                   law: str = "dsc-ppc") -> tuple[np.ndarray, np.ndarray]:
    """The observer's linear gains (K1, K2) on e = z1 - x2 of ``law``'s table:
    "linear-part" or "local-gain"."""
    n = neso_params(scn, law)
    if observer == "linear-part":
        return np.array(n.k2, float), np.array(n.k4, float)
    if observer == "local-gain":
        a = float(n.alpha)
        g1 = a * amplitude ** (a - 1.0)
        g2 = (2 * a - 1) * amplitude ** (2 * a - 2.0)
        return n.k2 + n.k1 * g1, n.k4 + n.k3 * g2
    raise ValueError(f"observer must be 'linear-part' or 'local-gain', got {observer!r}")


def observer_map(K1, K2, T: float, substeps: int) -> np.ndarray:
    """(6 x 15): [z1; z2] at t_k from [z1, z2, x2_prev, x2, Bu_prev], the core's Neso.update.

    The observer z1' = Bu + z2 - K1 e, z2' = -K2 e (e = z1 - x2) of (22)
    without A (left out, module docstring) is the core's (22) with alpha = 1
    and k1 = k2 = K1/2, k3 = k4 = K2/2 (sig^1(e) = e). ``Neso.update`` over
    one period T (``substeps`` RK4 steps, B u held, x2 linear between the
    samples) is then linear: its value on the 15 unit inputs is the map.
    """
    K1, K2 = np.asarray(K1, float).reshape(3), np.asarray(K2, float).reshape(3)
    p = _core.NesoParams()
    p.alpha = 1.0
    p.k1, p.k2, p.k3, p.k4 = 0.5 * K1, 0.5 * K1, 0.5 * K2, 0.5 * K2
    p.substeps = int(substeps)
    neso = _core.Neso(p)
    zero = np.zeros(3)
    obs_map = np.empty((6, 15))
    for j in range(15):
        e = np.zeros(15)
        e[j] = 1.0
        neso.reset(e[0:3], e[3:6])
        neso.update(T, zero, zero, e[6:9], e[9:12], e[12:15])
        obs_map[0:3, j], obs_map[3:6, j] = neso.z1, neso.z2
    return obs_map


class SampledLoop:
    """The parts of :func:`sampled_closed_loop` that do not depend on t (built once).

    ``phi(t, r, rho)`` is :func:`sampled_closed_loop`, ``law(t, r, rho)`` is
    :func:`controller_step`, ``rho(t, r, rho)`` the spectral radius.
    """

    def __init__(self, scn: Scenario, law: str, rate: float | None, *, inertia: str = "true",
                 faults: bool = True, observer: str = "linear-part",
                 observer_amplitude: float = 1e-5):
        if law not in ("dsc-ppc", "dsc"):
            raise ValueError(f"law must be 'dsc-ppc' or 'dsc', got {law!r}")
        self.scn, self.law_name, self.inertia, self.faults = scn, law, inertia, faults
        self.rate = scn.run.control_rate_hz if rate is None else float(rate)
        T = 1.0 / self.rate
        self.T = T
        im = input_matrices(scn, inertia)
        self.B, self.Bp = im.B, im.B_pinv
        self.Bpl_healthy = im.B_plant
        # the gains of the law studied, from its own table ([laws.dsc-ppc] or [laws.dsc])
        self.O = observer_map(*observer_gains(scn, observer, observer_amplitude, law), T,
                              neso_params(scn, law).substeps)
        self.g = dsc_gains(scn, law)
        self.ppc = scn.core_config().ppc
        # plant x1' = x2/4, x2' = w (axis acceleration), ZOH over one period
        Pd = control.c2d(error_state_space(np.eye(3)), T, method="zoh")
        self.Phi, self.Gw = np.asarray(Pd.A), np.asarray(Pd.B)
        self.a = math.exp(-T / self.g.tau)
        self.b = math.exp(-self.g.k4 * T)
        self.has_faults = faults and bool(scn.actuators.faults)

    def gains(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        if self.law_name == "dsc":
            return np.ones(3), np.zeros(3)
        _, r, rho = ppc_gain(self.scn, t, self.ppc)
        return r, rho

    def law(self, t: float, r=None, rho=None) -> np.ndarray:
        """The controller's step k: :data:`CONTROLLER_OUTPUTS` from :data:`SAMPLED_STATES`."""
        r_t, rho_t = self.gains(t)
        r = r_t if r is None else np.asarray(r, float)
        rho = rho_t if rho is None else np.asarray(rho, float)
        g, B, Bp, a, b = self.g, self.B, self.Bp, self.a, self.b
        r_, rho_ = r.reshape(-1, 1), rho.reshape(-1, 1)
        S = np.eye(len(SAMPLED_STATES))
        # The C++ step order of DscLaw::step (law_dsc.cpp), on the columns of S.
        x1, x2, x2d, xb = S[_blk("x1", 3)], S[_blk("x2", 3)], S[_blk("x2d", 3)], S[_blk("x2bar_prev", 3)]
        vs = S[_blk("vs", 4)]
        Z = self.O @ np.vstack([S[_blk("z1", 3)], S[_blk("z2", 3)], S[_blk("x2_prev", 3)], x2,
                                S[_blk("Bu_prev", 3)]])  # Neso::update over the period
        z1, z2 = Z[0:3], Z[3:6]
        x2d = a * x2d + (1 - a) * xb          # (37), exact with x2bar held
        vs = b * vs                           # (42), exact; du = 0 without saturation
        xbar = -4.0 * (g.k1 + rho_) * x1      # (36) at the origin
        x2d_dot = (xbar - x2d) / g.tau        # (37) at t_k
        e2 = x2 - x2d                         # (27)
        v = -g.k2 * e2 - 0.25 * r_ * r_ * x1 - g.k3 * (B @ vs) - z2 + x2d_dot  # (41)
        u = Bp @ v
        return np.vstack([u, x2d, xbar, vs, z1, z2])

    def phi(self, t: float, r=None, rho=None) -> np.ndarray:
        C = self.law(t, r, rho)
        u = C[0:4]
        Bpl = self.Bpl_healthy * wheel_effectiveness(self.scn, t) if self.has_faults else self.Bpl_healthy
        Gam = self.Gw @ Bpl  # ZOH input matrix of the wheel commands u
        S = np.eye(len(SAMPLED_STATES))
        xn = self.Phi @ S[0:6] + Gam @ u  # plant, ZOH over [t_k, t_k+1]
        return np.vstack([xn, C[4:], S[_blk("x2", 3)], self.B @ u])

    def rho(self, t: float, r=None, rho=None) -> float:
        return float(np.max(np.abs(np.linalg.eigvals(self.phi(t, r, rho)))))


def controller_step(scn: Scenario, law: str = "dsc-ppc", rate: float | None = None,
                    t: float = 0.0, *, observer: str = "linear-part",
                    observer_amplitude: float = 1e-5, r: np.ndarray | None = None,
                    rho: np.ndarray | None = None) -> np.ndarray:
    """The controller's step k alone, linearised: (20 x 28), rows :data:`CONTROLLER_OUTPUTS`.

    From the sampled state s_k (:data:`SAMPLED_STATES`) to what
    ``DscLaw::step`` computes at step k: u_cmd, the filter x2d and compensator vs
    after their update, the new x2bar, and the observer's z1, z2 at t_k. The
    part of :func:`sampled_closed_loop` that repeats the C++ law.
    """
    return SampledLoop(scn, law, rate, observer=observer,
                       observer_amplitude=observer_amplitude).law(t, r, rho)


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
      linearly between the two samples, the core's ``Neso.update``
      (:func:`observer_map`). sig^alpha is not differentiable at 0:
      "linear-part" keeps only the linear k2, k4 terms (default);
      "local-gain" replaces sig^a(e) by its slope a |e|^(a-1) at
      |e| = observer_amplitude (exact for alpha = 1);
    - filter (37) and compensator (42): the exact updates of controllers.cpp
      (x2d uses x2bar of the previous step, x2d_dot = (x2bar - x2d)/tau at
      the sample);
    - plant: x1' = x2/4, x2' = B_plant u (true inertia, and with ``faults`` the
      wheels' effectiveness at t), held over the period: exact ZOH
      (``control.c2d``).
    """
    return SampledLoop(scn, law, rate, inertia=inertia, faults=faults, observer=observer,
                       observer_amplitude=observer_amplitude).phi(t, r, rho)


def spectral_radius(scn: Scenario, law: str = "dsc-ppc", rate: float | None = None,
                    times=None, **kw) -> np.ndarray:
    """max |eig(Phi(t))| of :func:`sampled_closed_loop` at each of ``times`` [s]."""
    times = np.atleast_1d(np.asarray(0.0 if times is None else times, float))
    loop = SampledLoop(scn, law, rate, **kw)
    return np.array([loop.rho(t) for t in times])
