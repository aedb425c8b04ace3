"""The sensor noise floor of the linearised sampled loop (docs/DESIGN.md,
section 5; docs/REPRODUCTION.md, "Sensor noise against the envelope").

What RMS attitude error does measurement noise alone produce in the
DSC(+PPC) loop, and is the prescribed bound chiinf above it? An H2 /
discrete-Lyapunov computation on :class:`~sc_rt.studies.design.sampled.SampledLoop`
(the 28-state linearised loop, PPC gain frozen at t, the end of the run by
default, where chi = chiinf) with the law fed x1 + n1 and x2 + n2:

- n1, the estimator's attitude error (MRP, dtheta / 4), is modelled per axis
  as a first-order Gauss-Markov sequence at the control rate: its variance
  the cycle average of the steady-state Kalman filter's a-priori and
  a-posteriori attitude variances, its correlation time -T_st / ln|lambda|
  with lambda the slowest eigenvalue of the filter's error dynamics
  (``control.dlqe``: per axis, states [theta, bias], gyro-propagated over a
  star tracker period T_st, the star tracker's noise about that body axis).
  This is the documented approximation of the MEKF (a low-pass of the star
  tracker's noise with the steady-state gain), not the MEKF itself;
- the observer's sig^alpha terms (alpha < 1) have an unbounded slope at 0: the
  loop is linearised with their local gain at the size of the noise they see,
  |e| = sigma_w (SampledLoop's "local-gain" observer; "linear-part", the
  design tool's default for stability, gives about half the floor at the
  paper's gains);
- n2, the rate error, is the gyro's white noise at its sample rate,
  sigma^2 = ARW^2 / T_gyro + q^2 / (6 T_gyro^2) per axis (the second term:
  the delta-angle quantum q with its remainder carried), taken as white at
  the control rate (the law takes the latest sample); the bias error and
  its transient, the scale factor, the misalignment, the star tracker's
  latency and losses and the tachometer are left out.

The loop's noise input matrix is the part of Phi(t) that acts through the
measured x1, x2 (Phi minus the plant's own propagation of x1, x2), so the
controller's map is SampledLoop's, not a copy. Sigma = A Sigma A' + B W B'
(``scipy.linalg.solve_discrete_lyapunov``); the RMS of the true x1 per axis,
4 sqrt(Sigma_x1x1) rad, is the floor. The wheel command's RMS from the
noise alone comes with it (u = the law's row of the same map): when 3 x it
exceeds the wheel limit the loop saturates on noise and the linear floor
does not describe it. ``sc-rt check`` warns when min(dmin, dmax) chiinf < 3 x
the floor's RMS (a per-sample exceedance of the bound then has a probability
above ~0.3 %), and when the noise saturates the wheels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import control
import numpy as np
import scipy.linalg

from sc_rt.scenario.model import Scenario
from sc_rt.scenario.tables.sensors import ARCSEC, DEG_PER_H, DEG_PER_RT_H, Sensors
from sc_rt.studies.design.sampled import SAMPLED_STATES, SampledLoop

__all__ = ["NoiseFloor", "estimator_gains", "noise_floor", "format_noise_floor", "noise_floor_report",
           "predicted_tightest_chiinf",
           "NOISE_SIGMAS"]

#: The bound must be at least this many RMS of the noise floor (sc-rt check).
NOISE_SIGMAS = 3.0


@dataclass(frozen=True)
class NoiseFloor:
    """The noise floor per axis (x, y, z of the body)."""

    law: str
    rate_hz: float
    t: float  # [s] the PPC gain's time
    rms_arcsec: np.ndarray  # RMS of the true attitude error from noise alone
    rms_mrp: np.ndarray  # the same in MRP (x1)
    est_rms_arcsec: np.ndarray  # the estimator's attitude error at the control instants (the model's)
    est_gain: np.ndarray  # (3, 2) steady-state Kalman gain per axis on [theta, bias]
    rate_noise: np.ndarray  # [rad/s] gyro white noise per sample
    bound_mrp: np.ndarray  # min(dmin, dmax) chiinf
    spectral_radius: float
    u_rms: np.ndarray = None  # [rad/s^2] RMS of the wheel command from noise alone (4 wheels)
    u_limit: np.ndarray = None  # [rad/s^2] min(|umin|, umax) per wheel (torque wheels' limits / Jw)

    @property
    def u_margin(self) -> np.ndarray:
        """u_limit / (NOISE_SIGMAS x u_rms): < 1 means the noise alone saturates the wheels
        (the linear floor is then not what the loop does)."""
        with np.errstate(divide="ignore"):
            return self.u_limit / (NOISE_SIGMAS * self.u_rms)

    @property
    def stable(self) -> bool:
        return self.spectral_radius < 1.0

    @property
    def margin(self) -> np.ndarray:
        """bound / (NOISE_SIGMAS x RMS): < 1 means chiinf is below the noise floor."""
        with np.errstate(divide="ignore"):
            return self.bound_mrp / (NOISE_SIGMAS * self.rms_mrp)


def _axis_star_sigma(sensors: Sensors) -> np.ndarray:
    """[rad] the star tracker's noise about each body axis (diagonal of A diag(sc2, sc2, sb2) A')."""
    st = sensors.star_tracker
    b = np.asarray(st.boresight, float)
    b = b / np.linalg.norm(b)
    sc2, sb2 = (st.sigma_cross * ARCSEC) ** 2, (st.sigma_boresight * ARCSEC) ** 2
    q2 = (sensors.gyro.quantization * ARCSEC) ** 2 / 12.0 if sensors.gyro is not None else 0.0
    return np.sqrt(sc2 * (1 - b * b) + sb2 * b * b + q2)  # + the MEKF's q^2/12 (mekf.hpp)


def _error_model(sensors: Sensors, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(F, Q) of one axis' estimation error [theta, bias] over dt (the MEKF's model)."""
    g = sensors.gyro
    arw, rrw = g.arw * DEG_PER_RT_H, g.rrw * DEG_PER_H / 60.0
    a, bias_q = 1.0, 0.0
    if g.bias_sigma > 0:
        a = math.exp(-dt / g.bias_tau)
        bias_q = (g.bias_sigma * DEG_PER_H) ** 2 * (1 - a * a)
    F = np.array([[1.0, -dt], [0.0, a]])
    Q = np.array([[arw**2 * dt + rrw**2 * dt**3 / 3, -rrw**2 * dt**2 / 2],
                  [-rrw**2 * dt**2 / 2, rrw**2 * dt + bias_q]])
    return F, Q + 1e-30 * np.eye(2)  # a noiseless gyro: keep the Riccati equation well posed


def estimator_gains(sensors: Sensors) -> tuple[np.ndarray, np.ndarray]:
    """(K (3 axes x 2), a-priori attitude variance (3)) of the steady-state Kalman
    filter per body axis at the star tracker's rate (``control.dlqe``)."""
    Ts = 1.0 / sensors.star_tracker.rate_hz
    F, Q = _error_model(sensors, Ts)
    C = np.array([[1.0, 0.0]])
    K, prior = np.empty((3, 2)), np.empty(3)
    for i, r in enumerate(_axis_star_sigma(sensors)):
        R = max(r, 1e-12) ** 2
        _, P, _ = control.dlqe(F, np.eye(2), C, Q, np.array([[R]]))
        P = np.asarray(P)
        K[i] = P[:, 0] / (P[0, 0] + R)  # the update's gain on the a-priori error
        prior[i] = P[0, 0]
    return K, prior


def noise_floor(scn: Scenario, sensors: Sensors | None = None, *, law: str | None = None,
                rate: float | None = None, t: float | None = None,
                observer: str = "local-gain") -> NoiseFloor | None:
    """The noise floor of ``scn``'s loop with ``sensors`` (default: the
    scenario's [sensors]); None without sensors or for a law other than
    dsc-ppc / dsc (no linear model)."""
    sensors = scn.sensors if sensors is None else sensors
    law = scn.run.controller if law is None else law
    if sensors is None or sensors.gyro is None or law not in ("dsc-ppc", "dsc"):
        return None
    t = float(scn.run.duration) if t is None else float(t)
    g = sensors.gyro
    # white: ARW / sqrt(T_g), and the quantisation's rate error (carry_k - carry_k-1) / T_g, variance q^2 / (6 T_g^2)
    sigma_w = np.full(3, math.sqrt((g.arw * DEG_PER_RT_H) ** 2 * g.rate_hz
                                   + (g.quantization * ARCSEC * g.rate_hz) ** 2 / 6.0))
    # the observer's sig^alpha terms at the size of the noise they see (e = z1 - x2 ~ the rate noise)
    loop = SampledLoop(scn, law, rate, observer=observer, observer_amplitude=max(float(sigma_w[0]), 1e-12))
    M = loop.phi(t)
    n = len(SAMPLED_STATES)
    P0 = np.zeros((n, n))
    P0[0:6, 0:6] = loop.Phi  # the plant's own propagation of x1, x2
    Gn = (M - P0)[:, 0:6]  # what acts through the measured x1, x2
    rad = float(np.max(np.abs(np.linalg.eigvals(M))))
    ppc = scn.controller.ppc
    bound = np.minimum(ppc.dmin, ppc.dmax) * ppc.chiinf
    inf = np.full(3, np.inf)
    if sensors.star_tracker is None:
        return NoiseFloor(law, loop.rate, t, inf, inf, inf, np.full((3, 2), np.nan), sigma_w, bound, rad)
    K, prior = estimator_gains(sensors)
    r_axis = _axis_star_sigma(sensors)
    if not rad < 1.0:  # no floor; the estimator's error alone: the cycle average of the filter's variances
        post = prior - prior**2 / (prior + r_axis**2)
        est = np.sqrt(0.5 * (prior + post)) / ARCSEC
        return NoiseFloor(law, loop.rate, t, inf, inf, est, K, sigma_w, bound, rad)
    # the lifted period: control every nc, star fixes every ns base steps of dt
    Tc, Ts = loop.T, 1.0 / sensors.star_tracker.rate_hz
    dt = math.gcd(round(Tc * 1e6), round(Ts * 1e6)) * 1e-6  # [s] on a 1 us grid
    nc, ns = round(Tc / dt), round(Ts / dt)
    period = nc * ns // math.gcd(nc, ns)
    N = n + 6  # [s (28), theta (3), bias (3)]
    th, bi = slice(n, n + 3), slice(n + 3, n + 6)

    def steps():
        """(A, B W B') of each event of one lifted period, and whether x1 is sampled there."""
        last = 0
        for ev in range(period + 1):
            if ev != period and ev % nc and ev % ns:
                continue
            if ev > last:  # the estimation error between events
                F, Q = _error_model(sensors, (ev - last) * dt)
                A, W = np.eye(N), np.zeros((N, N))
                for i in range(3):
                    idx = [n + i, n + 3 + i]
                    A[np.ix_(idx, idx)] = F
                    W[np.ix_(idx, idx)] = Q
                yield A, W, False
            last = ev
            if ev == period:
                return
            if ev % ns == 0:  # star tracker update with the steady-state gain
                A, W = np.eye(N), np.zeros((N, N))
                for i in range(3):
                    idx = [n + i, n + 3 + i]
                    A[np.ix_(idx, idx)] -= np.outer(K[i], [1.0, 0.0])
                    W[np.ix_(idx, idx)] = np.outer(K[i], K[i]) * r_axis[i] ** 2
                yield A, W, False
            if ev % nc == 0:  # the control step: the law sees x1 + theta / 4, x2 + gyro noise
                A, W = np.eye(N), np.zeros((N, N))
                A[:n, :n] = M
                A[:n, th] = Gn[:, 0:3] / 4.0
                Bw = Gn[:, 3:6] * sigma_w
                W[:n, :n] = Bw @ Bw.T
                yield A, W, True

    AL, QL = np.eye(N), np.zeros((N, N))
    events = list(steps())
    for A, W, _ in events:
        AL, QL = A @ AL, A @ QL @ A.T + W
    S = scipy.linalg.solve_discrete_lyapunov(AL, QL)
    # the command of step k: u = Cu s + Cu[x1] theta / 4 + Cu[x2] n2 (the law sees the measured x1, x2)
    Cu = loop.law(t)[0:4]
    Lu = np.zeros((4, N))
    Lu[:, :n] = Cu
    Lu[:, th] = Cu[:, 0:3] / 4.0
    Lw = Cu[:, 3:6] * sigma_w
    x1_var, th_var, u_var = [], [], []
    for A, W, control_step in events:
        if control_step:  # the state at t_k, just before step k
            x1_var.append(np.diag(S)[0:3])
            th_var.append(np.diag(S)[th])
            u_var.append(np.diag(Lu @ S @ Lu.T + Lw @ Lw.T))
        S = A @ S @ A.T + W
    rms_mrp = np.sqrt(np.mean(x1_var, axis=0))
    est = np.sqrt(np.mean(th_var, axis=0))
    del bi
    act = scn.actuators
    limit = np.minimum(np.abs(act.umin), np.abs(act.umax))
    if act.wheels is not None and act.wheels.command == "torque":  # limits in N m: as accelerations, torque / Jw
        limit = limit / np.asarray(scn.plant.Jw, float)
    return NoiseFloor(law, loop.rate, t, 4.0 * rms_mrp / ARCSEC, rms_mrp, est / ARCSEC, K, sigma_w, bound, rad,
                      np.sqrt(np.mean(u_var, axis=0)), limit)


def format_noise_floor(nf: NoiseFloor | None, scn: Scenario) -> str:
    """The report's lines."""
    if nf is None:
        why = ("no [sensors] table (perfect measurements)" if scn.sensors is None
               else f"no linear model of law {scn.run.controller!r}")
        return f"Sensor noise floor: not computed ({why})."
    f = lambda v: ", ".join(f"{x:.3g}" for x in v)  # noqa: E731
    lines = [f"Sensor noise floor ({nf.law} at {nf.rate_hz:g} Hz, PPC gain at t = {nf.t:g} s, "
             f"spectral radius {nf.spectral_radius:.4f}):",
             f"  estimator attitude error (model) RMS [arcsec]: {f(nf.est_rms_arcsec)}, "
             f"steady-state gain on theta: {f(nf.est_gain[:, 0])}",
             f"  gyro rate noise per sample [rad/s]: {f(nf.rate_noise)}",
             f"  attitude error RMS from noise alone [arcsec]: {f(nf.rms_arcsec)} (MRP {f(nf.rms_mrp)})",
             f"  bound min(dmin, dmax) chiinf [MRP]: {f(nf.bound_mrp)}; "
             f"bound / ({NOISE_SIGMAS:g} RMS): {f(nf.margin)}"]
    if nf.u_rms is not None:
        lines.append(f"  wheel command RMS from noise alone [rad/s^2]: {f(nf.u_rms)}; "
                     f"limit / ({NOISE_SIGMAS:g} RMS): {f(nf.u_margin)}")
    if not nf.stable:
        lines.append("  the linearised loop is unstable at this chiinf: no floor (see the stability limit)")
    elif np.any(nf.margin < 1):
        lines.append("  chiinf is BELOW the noise floor on axis "
                     + ", ".join("xyz"[i] for i in np.flatnonzero(nf.margin < 1)))
    if nf.u_rms is not None and np.any(nf.u_margin < 1):
        lines.append("  the noise alone SATURATES the wheels: the loop leaves its linear range "
                     "(the floor above does not hold)")
    return "\n".join(lines)


def noise_floor_report(scn: Scenario, rate: float | None = None) -> dict:
    """The noise floor as the design report's JSON-able entry (with its text)."""
    nf = noise_floor(scn, rate=rate)
    d: dict = {"text": format_noise_floor(nf, scn)}
    if nf is not None:
        d.update(law=nf.law, rate_hz=nf.rate_hz, t_s=nf.t, rms_arcsec=list(nf.rms_arcsec),
                 rms_mrp=list(nf.rms_mrp), estimator_rms_arcsec=list(nf.est_rms_arcsec),
                 bound_mrp=list(nf.bound_mrp), margin=list(nf.margin),
                 spectral_radius=nf.spectral_radius, sigmas=NOISE_SIGMAS,
                 u_rms=None if nf.u_rms is None else list(nf.u_rms),
                 u_margin=None if nf.u_rms is None else list(nf.u_margin))
    return d


def predicted_tightest_chiinf(scn: Scenario, base, *, lo: float = 0.5, hi: float = 64.0,
                              rtol: float = 0.01, u_sigmas: float = 0.0) -> dict:
    """The smallest factor c of chiinf = c * base for which the noise floor's
    conditions hold (linear loop stable, min(dmin, dmax) chiinf >= 3 RMS of the
    attitude error, and ``u_sigmas`` RMS of the wheel command within the
    limits), by bisection; the prediction that docs/REPRODUCTION.md compares
    with the simulated tightest chiinf. ``u_sigmas`` = 0 (default): the
    command is not checked; 1: its RMS within the limits. Neither gives the
    saturated loop's boundary (REPRODUCTION.md section 7: at 100 Hz the loop
    holds with its wheels saturated on 70 % of the steps, at 1 kHz it needs
    1.43 x where the floor says 1.008)."""
    from sc_rt.scenario.variants import with_ppc

    base = np.asarray(base, float)

    def ok(c: float) -> bool:
        nf = noise_floor(with_ppc(scn, chiinf=c * base))
        return bool(nf is not None and nf.stable and np.all(nf.margin >= 1)
                    and (nf.u_rms is None or np.all(nf.u_limit >= u_sigmas * nf.u_rms)))

    if not ok(hi):
        return {"bracket_ok": False, "factor_hi": hi}
    if ok(lo):
        return {"bracket_ok": True, "factor": lo, "chiinf": (lo * base).tolist(), "at_lower_end": True}
    while hi / lo > 1 + rtol:
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return {"bracket_ok": True, "factor": hi, "chiinf": (hi * base).tolist(), "at_lower_end": False}
