"""When the linearised sampled loop loses stability, and what a simulation shows (docs/DESIGN.md, section 4).

:func:`stability_limit`: the predicted loss of stability (first crossing of
1 by the spectral radius of :func:`sc_rt.studies.design.sampled.sampled_closed_loop`),
the critical PPC gain per axis and the smallest stable chiinf;
:func:`critical_r_estimate`: the half-sample rule of thumb;
:func:`simulated_loss_of_stability`: the same measured in a simulation;
:func:`compare_loss_of_stability`: the two side by side, with why they differ.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import scipy.optimize

from sc_rt.scenario.model import Scenario
from sc_rt.studies.lawparams import dsc_gains
from sc_rt.studies.design.linear import AXES
from sc_rt.studies.design.sampled import SAMPLED_STATES, SampledLoop, ppc_gain

__all__ = [
    "StabilityLimit",
    "critical_r_estimate",
    "stability_limit",
    "simulated_loss_of_stability",
    "without_wheel_limits",
    "compare_loss_of_stability",
]

_X1 = slice(SAMPLED_STATES.index("x1[0]"), SAMPLED_STATES.index("x1[0]") + 3)


def critical_r_estimate(scn: Scenario, rate: float) -> float:
    """Rule of thumb for the critical PPC gain: r_crit = 4 sqrt(2 k2 f).

    At the origin the stiffness G' r e1 = r^2/4 x1 and the damping k2 make a
    mode x1'' + k2 x1' + (r/4)^2 x1 = 0 (omega = r/4, damping k2). A delay tau
    in the stiffness path removes omega^2 tau of damping; the ZOH is a delay
    of T/2, so the mode loses its damping when (r/4)^2 T/2 = k2. Within 1 %
    of the exact spectral-radius crossing for the paper (docs/DESIGN.md).
    """
    return 4.0 * math.sqrt(2.0 * dsc_gains(scn).k2 * rate)



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

    loop = SampledLoop(scn, law, rate, **kw)
    rho_of = loop.rho

    t_loss = _first_crossing(lambda t: rho_of(t) - 1.0, 0.0, horizon, grid)
    axis = mode_hz = None
    if t_loss is not None:
        Phi = loop.phi(t_loss)
        ev, V = np.linalg.eig(Phi)
        k = int(np.argmax(np.abs(ev)))
        mode_hz = abs(float(np.angle(ev[k]))) * rate / (2 * math.pi)
        axis = AXES[int(np.argmax(np.abs(V[_X1, k])))]
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

    Two measures: ``first_bound_violation_s`` (the metric of metrics.json) and,
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
                           "duration_s": float(t[-1]), "first_bound_violation_s": tb,
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



def without_wheel_limits(scn: Scenario, limit: float = 1e6) -> Scenario:
    """The scenario with the wheels' acceleration limits at +-``limit`` rad/s^2 (never saturated)."""
    act = dataclasses.replace(scn.actuators, umin=np.full(4, -limit), umax=np.full(4, limit))
    return dataclasses.replace(scn, actuators=act)


def compare_loss_of_stability(pred: StabilityLimit | dict[str, Any], sim: dict[str, Any],
                              unlimited: dict[str, Any] | None = None) -> dict[str, Any]:
    """The predicted loss of stability next to a run's, and one sentence on why they differ.

    ``pred``: a dsc-ppc :func:`stability_limit` (or its ``as_dict``); ``sim``:
    :func:`simulated_loss_of_stability` of the same scenario and rate;
    ``unlimited``: optionally the same run :func:`without_wheel_limits`, which
    shows whether saturation is what broke the bound first. The
    explanation is chosen from the run's numbers: a bound violation before
    the predicted loss with the wheels saturated is a large-signal failure
    the linearisation does not model; one after it is the unstable mode
    growing from the error floor to the bound (docs/DESIGN.md, "Against
    simulation").
    """
    p = pred.as_dict() if isinstance(pred, StabilityLimit) else pred
    tl, ax = p["t_loss_s"], p["axis"]
    tb, axb = sim["first_bound_violation_s"], sim["first_bound_violation_axis"]
    if isinstance(axb, (int, np.integer)):  # the metric's axis is 1-based
        axb = AXES[int(axb) - 1]
    i = AXES.index(ax) if ax else None
    onset = sim["onset_s"][i] if i is not None else None
    lam = sim["lam_at_onset"][i] if i is not None else None
    sat_on = sim["saturated_at_onset"][i] if i is not None else None
    floor = sim["min_error"][i] if i is not None else None
    sat = sim.get("saturated_fraction_before_violation")
    small = lam is not None and lam < 1e-2 and sat_on == 0.0
    dur = sim["duration_s"]
    if tb is None and tl is None:
        why = (f"the run keeps its bound for all {dur:g} s and the linearised loop stays stable "
               f"to its horizon: they agree")
    elif tb is None:
        why = (f"the linearised loop loses stability at {tl:.2f} s, but the unstable mode, "
               f"starting from the error floor"
               + (f" ({floor:.1e})" if floor is not None else "")
               + f", does not reach the bound within the run's {dur:g} s")
    elif tl is None or tb < tl:
        first = ("the linearised loop stays stable to its horizon" if tl is None else
                 f"{tl - tb:.1f} s before the linearised loop loses stability at {tl:.2f} s")
        if sat is not None and sat >= 0.5:
            why = (f"the run leaves its bound at {tb:.2f} s (axis {axb}), {first}, with "
                   f"{sat:.0%} of the control steps of the second before saturated: the wheels "
                   f"cannot follow the envelope, a large-signal failure that the small-signal, "
                   f"saturation-free linearisation does not model")
            if unlimited is not None:
                tf = unlimited["first_bound_violation_s"]
                of = unlimited["onset_s"][i] if i is not None else None
                why += (" (with the wheel limits removed the same run keeps its bound "
                        + ("to the end" if tf is None else f"until {tf:.2f} s")
                        + (f" and its error starts to grow at {of:.2f} s" if of is not None else "")
                        + ")")
        else:
            why = (f"the run leaves its bound at {tb:.2f} s (axis {axb}), {first}, with only "
                   f"{(sat or 0.0):.0%} of the steps of the second before saturated: it runs far "
                   f"from lambda = 0, where r is larger than the linearisation's")
    elif small:
        why = (f"the linearised loop loses stability at {tl:.2f} s and the run's error on axis "
               f"{ax} starts to grow at {onset:.2f} s ({(onset - tl) / tl:+.1%}, small signal: "
               f"lambda {lam:.1e}, no saturation); the bound breaks {tb - tl:.1f} s later because "
               f"the unstable mode needs that long to grow from the error floor {floor:.1e} "
               f"to the bound")
    else:
        why = (f"the linearised loop loses stability at {tl:.2f} s and the run breaks its bound "
               f"{tb - tl:.1f} s later, at {tb:.2f} s (axis {axb}), without having reached the "
               f"small-signal regime (at the growth onset of axis {ax}: lambda "
               f"{_fmt(lam)}, {_fmt_pct(sat_on)} of the steps saturated): the break is "
               f"that of a saturated, linearly unstable loop")
    free = None if unlimited is None else {
        "first_bound_violation_s": unlimited["first_bound_violation_s"],
        "onset_s": unlimited["onset_s"][i] if i is not None else None}
    return {"rate_hz": p["rate_hz"], "duration_s": dur, "t_loss_s": tl, "axis": ax,
            "first_bound_violation_s": tb, "first_bound_violation_axis": axb,
            "onset_s": onset, "lam_at_onset": lam, "saturated_at_onset": sat_on,
            "min_error": floor, "saturated_fraction_before_violation": sat,
            "without_wheel_limits": free, "explanation": why[0].upper() + why[1:] + "."}


def _fmt(v) -> str:
    return "-" if v is None else f"{v:.2g}"


def _fmt_pct(v) -> str:
    return "-" if v is None else f"{v:.0%}"
