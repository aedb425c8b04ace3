"""The filters of Markley & Crassidis (2014), Example 6.1, on the data of tests/example61.py: the
Example's MEKF in numpy (6 states, attitude and bias, and 15, with the gyros' scale factors and
misalignments), its covariance recursion alone, and sc-rt's filter (``_core.Mekf``) through its API,
each as a ``run_filter(data, k) -> FilterRun`` (example61.check_calibrating_filter's contract);
and the helpers they share with tests/example61.py (quaternions, MRPs, the calibration matrix).

The Example's filter, per sample t_k (re-implemented from the published script, in our words):

- update with the star tracker fix: residual z = the rotation vector of C_m C_est', H = [I 0],
  R = sigma_star^2 I, K = P H' (H P H' + R)^-1, Joseph form, C_est <- exp(-dx_theta^) C_est and the
  other states added;
- propagate over [t_k, t_k+1] with the sample of t_k held: w~ = omega_m - b_est, w^ = (I - S_est) w~
  (15 states; w^ = w~ with 6), C_est <- exp(-(w^ dt)^) C_est, P <- Phi P Phi' + Gamma Q Gamma' with,
  to first order in dt as the script has it (its exact matrix exponential is commented out),
  Phi = I + F dt, Gamma Q Gamma' = dt G diag(sigma_v^2 I, sigma_u^2 I) G', and

      F = [[-w^x, -(I - S_est), -diag(w~), -U(w~), -L(w~)], [0 ...]],   G = [[-(I - S_est), 0], [0, I], [0, 0]]
      U(w) = [[w2, w3, 0], [0, 0, w3], [0, 0, 0]],   L(w) = [[0, 0, 0], [w1, 0, 0], [0, w1, w2]]

  (U, L: the derivatives of S w by the upper and lower misalignments). ``discretisation="closed"``
  (6 states) uses instead the closed forms of Markley & Crassidis ch. 6: Phi11 = exp(-(w^ dt)^),
  Phi12 = w^x (1 - cos a) / w^2 - I dt - (w^x)^2 (a - sin a) / w^3 (a = |w^| dt), and
  Q = [[sv^2 dt + su^2 dt^3/3, -su^2 dt^2/2], [., su^2 dt]] (Farrenkopf's model).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from example61 import Example61, Example61Data


# --------------------------------------------------------------------------- the Example's terms

def cal_matrix(x) -> np.ndarray:
    """S (..., 3, 3) from the calibration states (..., 9) in the Example's order."""
    x = np.asarray(x, float)
    S = np.zeros((*x.shape[:-1], 9))
    S[..., [0, 4, 8, 1, 2, 5, 3, 6, 7]] = x  # s1 s2 s3 on the diagonal, kU above it, kL below, row by row
    return S.reshape(*x.shape[:-1], 3, 3)


def cal_states(S) -> np.ndarray:
    """Inverse of :func:`cal_matrix`."""
    S = np.asarray(S, float)
    return S.reshape(*S.shape[:-2], 9)[..., [0, 4, 8, 1, 2, 5, 3, 6, 7]]


def qmul(a, b) -> np.ndarray:
    """Quaternion product (scalar first) with ``C(qmul(a, b)) = C(a) C(b)``, batched over leading axes."""
    a0, (a1, a2, a3), b0, (b1, b2, b3) = a[..., 0], np.moveaxis(a[..., 1:], -1, 0), b[..., 0], \
        np.moveaxis(b[..., 1:], -1, 0)
    return np.stack([a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3, a0 * b1 + b0 * a1 - (a2 * b3 - a3 * b2),
                     a0 * b2 + b0 * a2 - (a3 * b1 - a1 * b3), a0 * b3 + b0 * a3 - (a1 * b2 - a2 * b1)], -1)


def conj(q) -> np.ndarray:
    """The inverse rotation of a unit quaternion."""
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def rotvec_quat(phi) -> np.ndarray:
    """The quaternion of ``exp(-phi^)``, a rotation by |phi| about phi (..., 3) -> (..., 4)."""
    a = np.linalg.norm(phi, axis=-1, keepdims=True)
    return np.concatenate([np.cos(0.5 * a), 0.5 * np.sinc(a / (2 * np.pi)) * phi], -1)


def quat_rotvec(q) -> np.ndarray:
    """Inverse of :func:`rotvec_quat` (the short rotation)."""
    q = np.where(q[..., :1] < 0, -q, q)
    s = np.linalg.norm(q[..., 1:], axis=-1, keepdims=True)
    f = np.where(s > 1e-12, 2 * np.arctan2(s, q[..., :1]) / np.maximum(s, 1e-300), 2 / q[..., :1])
    return f * q[..., 1:]


def quat_mrp(q) -> np.ndarray:
    """Quaternion -> MRP sigma_BN (the short set)."""
    q = np.where(q[..., :1] < 0, -q, q)
    return q[..., 1:] / (1 + q[..., :1])


def mrp_quat(s) -> np.ndarray:
    """MRP -> unit quaternion (scalar first)."""
    s = np.asarray(s, float)
    ss = np.sum(s * s, -1, keepdims=True)
    return np.concatenate([(1 - ss) / (1 + ss), 2 * s / (1 + ss)], -1)


@dataclass
class FilterRun:
    """What a filter gives back for the runs of an :class:`Example61Data` (the contract of
    :func:`check_calibrating_filter`'s ``run_filter``), after the update at each recorded t_k.

    Attributes
    ----------
    k : (E,) indices into data.t of the recorded epochs
    sigma : (N, E, 3) estimated sigma_BN
    bias : (N, E, 3) [rad/s]
    P : (N, E, n, n) covariance, n = 6 or 15, in the Example's order
        [dtheta (3), db (3), s1 s2 s3, kU1 kU2 kU3, kL1 kL2 kL3]
    cal : (N, E, 9) or None, estimated S of ``omega_m = (I + S) omega + b + n`` in that order (15
        states). A filter of another model converts: the Example's ``omega = (I - S_f)(omega_m - b)``
        has S = (I - S_f)^-1 - I = S_f + S_f^2 + ... (its covariance, of Jacobian I + O(S), kept).
    """

    k: np.ndarray
    sigma: np.ndarray
    bias: np.ndarray
    P: np.ndarray
    cal: np.ndarray | None = None


# --------------------------------------------------------------------------- filters

def _place(v, at, signs=1.0) -> np.ndarray:
    """A (..., 3, 3) matrix of zeros with the components v[..., i] * signs[i] at the flat positions at[i]."""
    M = np.zeros((*v.shape[:-1], 9))
    M[..., at] = v * signs
    return M.reshape(*v.shape[:-1], 3, 3)


def _skew(w) -> np.ndarray:
    return _place(w[..., [2, 1, 2, 0, 1, 0]], [1, 2, 3, 5, 6, 7], np.array([-1.0, 1, 1, -1, -1, 1]))


def interval_rates(data: Example61Data, rule: str = "hold") -> np.ndarray:
    """The measured rate each filter uses over [t_k, t_k+1] (N, m - 1, 3).

    Parameters
    ----------
    data : Example61Data
    rule : str
        "hold": the sample of t_k (the Example's); "mean": the mean of the two samples bounding the
        interval (sc-rt's rule for instantaneous samples); "integrated": data.gyro_mean.

    Returns
    -------
    np.ndarray
    """
    if rule == "hold":
        return data.gyro[:, :-1]
    if rule == "mean":
        return 0.5 * (data.gyro[:, :-1] + data.gyro[:, 1:])
    if rule == "integrated":
        return data.gyro_mean
    raise ValueError(f"rule must be 'hold', 'mean' or 'integrated', not {rule!r}")


def prior(p: Example61, n: int) -> np.ndarray:
    """The Example's initial covariance (n, n), n = 6 or 15."""
    d = [p.p0_attitude ** 2] * 3 + [p.p0_bias ** 2] * 3 + [p.p0_calibration ** 2] * 9
    return np.diag(d[:n])


def _update(P, R):
    """Joseph-form update with H = [I 0]: (P, K), batched."""
    n = P.shape[-1]
    K = np.linalg.solve(P[..., :3, :3] + R, P[..., :3, :]).swapaxes(-1, -2)  # P H' S^-1 (S symmetric)
    IKH = np.broadcast_to(np.eye(n), P.shape).copy()
    IKH[..., :, :3] -= K
    P = IKH @ P @ IKH.swapaxes(-1, -2) + K @ R @ K.swapaxes(-1, -2)
    return 0.5 * (P + P.swapaxes(-1, -2)), K


def _transition(p: Example61, wt, cal, n: int, discretisation: str):
    """(Phi, Q, w^) over one interval, batched: wt = omega_m - b_est (..., 3), cal the calibration
    estimate (..., 9) or None."""
    dt, lead = p.dt, wt.shape[:-1]
    IS = np.eye(3) - (cal_matrix(cal) if n == 15 else 0.0)
    wh = np.einsum("...ij,...j->...i", IS, wt) if n == 15 else wt
    Wx = _skew(wh)
    Phi = np.broadcast_to(np.eye(n), (*lead, n, n)).copy()
    if discretisation == "example":
        Phi[..., :3, :3] -= dt * Wx
        Phi[..., :3, 3:6] = -dt * IS
        if n == 15:
            Phi[..., :3, 6:9] = -dt * _place(wt, [0, 4, 8])  # diag(w~)
            Phi[..., :3, 9:12] = -dt * _place(wt[..., [1, 2, 2]], [0, 1, 5])  # U(w~)
            Phi[..., :3, 12:15] = -dt * _place(wt[..., [0, 0, 1]], [3, 7, 8])  # L(w~)
        Q = np.zeros((*lead, n, n))  # dt G diag(sv^2 I, su^2 I) G'
        Q[..., :3, :3] = dt * p.sigma_v ** 2 * (IS @ IS.swapaxes(-1, -2) if n == 15 else np.eye(3))
        Q[..., 3:6, 3:6] = dt * p.sigma_u ** 2 * np.eye(3)
        return Phi, Q, wh
    if discretisation != "closed" or n != 6:
        raise ValueError("discretisation 'closed' is for 6 states; else 'example'")
    w = np.linalg.norm(wh, axis=-1)[..., None, None]
    a = w * dt
    small = a < 1e-6
    ws = np.where(small, 1.0, w)
    c1 = np.where(small, dt, np.sin(a) / ws)
    c2 = np.where(small, dt ** 2 / 2, (1 - np.cos(a)) / ws ** 2)
    c3 = np.where(small, dt ** 3 / 6, (a - np.sin(a)) / ws ** 3)
    WW = Wx @ Wx
    Phi[..., :3, :3] = np.eye(3) - c1 * Wx + c2 * WW
    Phi[..., :3, 3:6] = c2 * Wx - dt * np.eye(3) - c3 * WW
    su2, sv2 = p.sigma_u ** 2, p.sigma_v ** 2
    Q = np.zeros((*lead, 6, 6))
    Q[..., :3, :3] = (sv2 * dt + su2 * dt ** 3 / 3) * np.eye(3)
    Q[..., :3, 3:] = Q[..., 3:, :3] = -su2 * dt ** 2 / 2 * np.eye(3)
    Q[..., 3:, 3:] = su2 * dt * np.eye(3)
    return Phi, Q, wh


def covariance(p: Example61, rates, n: int = 6, discretisation: str = "example", steps: int | None = None):
    """The Example's covariance recursion alone, with the estimated rates given (the true ones,
    say): the covariance after the update at each t_k (steps, n, n).

    Parameters
    ----------
    p : Example61
    rates : (m - 1, 3) w~ over each interval (the calibration estimate taken as 0)
    n : int
    discretisation : str
    steps : int or None
        Samples (default len(rates) + 1).

    Returns
    -------
    np.ndarray
    """
    steps = len(rates) + 1 if steps is None else steps
    Phi, Q, _ = _transition(p, np.asarray(rates)[: steps - 1], np.zeros((steps - 1, 9)), n, discretisation)
    R = p.sigma_star ** 2 * np.eye(3)
    P = prior(p, n)
    out = np.empty((steps, n, n))
    for k in range(steps):
        P, _ = _update(P, R)
        out[k] = P
        if k < steps - 1:
            P = Phi[k] @ P @ Phi[k].T + Q[k]
    return out


def mekf(data: Example61Data, k, n: int = 6, rule: str = "hold", discretisation: str = "example") -> FilterRun:
    """The Example's MEKF on every run of ``data`` at once (batched over the runs).

    Parameters
    ----------
    data : Example61Data
    k : (E,) indices of the samples to record (after their update)
    n : int
        6 (attitude, bias) or 15 (and the calibration).
    rule : str
        The rate over each interval (:func:`interval_rates`).
    discretisation : str
        "example" (the script's first order) or "closed" (6 states).

    Returns
    -------
    FilterRun
    """
    p, N, m = data.p, data.runs, data.p.steps
    rates = interval_rates(data, rule)
    R = p.sigma_star ** 2 * np.eye(3)
    q = mrp_quat(data.sigma0_est)
    x = np.zeros((N, n - 3))  # bias and calibration estimates
    x[:, :3] = data.bias0_est
    P = np.broadcast_to(prior(p, n), (N, n, n)).copy()
    qm = mrp_quat(data.star)
    k = np.asarray(k)
    rec = np.full(m, -1)
    rec[k] = np.arange(len(k))
    E = len(k)
    sig, bias, PP = np.empty((N, E, 3)), np.empty((N, E, 3)), np.empty((N, E, n, n))
    cal = np.empty((N, E, 9)) if n == 15 else None
    for j in range(m):
        z = quat_rotvec(qmul(qm[:, j], conj(q)))
        P, K = _update(P, R)
        dx = np.einsum("nij,nj->ni", K, z)
        q = qmul(rotvec_quat(dx[:, :3]), q)
        q /= np.linalg.norm(q, axis=-1, keepdims=True)
        x += dx[:, 3:]
        if rec[j] >= 0:
            e = rec[j]
            sig[:, e], bias[:, e], PP[:, e] = quat_mrp(q), x[:, :3], P
            if cal is not None:  # the truth's S of (I - S_est)^-1 = I + S (P unchanged: its Jacobian is I + O(S))
                cal[:, e] = cal_states(np.linalg.inv(np.eye(3) - cal_matrix(x[:, 3:])) - np.eye(3))
        if j == m - 1:
            break
        wt = rates[:, j] - x[:, :3]
        Phi, Q, wh = _transition(p, wt, x[:, 3:] if n == 15 else None, n, discretisation)
        q = qmul(rotvec_quat(wh * p.dt), q)
        P = Phi @ P @ Phi.swapaxes(-1, -2) + Q
    return FilterRun(k=k, sigma=sig, bias=bias, P=PP, cal=cal)


def numpy_filter(n: int = 6, rule: str = "hold", discretisation: str = "example"):
    """:func:`mekf` as a ``run_filter(data, k)``.

    Parameters
    ----------
    n : int
    rule : str
    discretisation : str

    Returns
    -------
    callable
    """
    return lambda data, k: mekf(data, k, n, rule, discretisation)


def scrt_params(p: Example61):
    """sc-rt's MekfParams for the Example: its noise in sc-rt's units (arw = sigma_v, rrw = sigma_u,
    no Gauss-Markov bias, no quantisation, an isotropic star tracker) and its prior."""
    from sc_rt import _core

    m = _core.MekfParams()
    m.arw, m.rrw, m.bias_sigma, m.quantization = p.sigma_v, p.sigma_u, 0.0, 0.0
    m.sigma_cross = m.sigma_boresight = p.sigma_star
    m.initial_attitude_sigma, m.initial_bias_sigma = p.p0_attitude, p.p0_bias
    m.history = 8
    return m


def scrt_filter(feed: str = "pairs", configure=None, calibrating: bool = False, output: int | None = None):
    """sc-rt's MEKF (``_core.Mekf``) as a ``run_filter(data, k)``, one run after the other.

    sc-rt propagates over the interval between two rate samples with the mean of the two. The
    Example holds the sample of t_k over [t_k, t_k+1] (its truth is built that way, so holding is
    exact for its data). ``feed`` says how the samples reach the filter:

    - "pairs" (the Example's terms): the sample of t_k is given at t_k and again at t_k+1, before
      the sample of t_k+1 at the same time: the mean over each interval is then the held sample,
      and the zero-length interval at t_k+1 propagates nothing;
    - "samples": each sample once at its time (right for instantaneous samples of a smooth rate,
      the "smooth" truth; on the held truth the filter runs half a sample ahead);
    - "increments": data.gyro_mean[:, k] delivered at t_k+1 (an integrating gyro's output; taken
      for rate samples and averaged, half a sample behind).

    A star fix is given at its time after the gyro samples of that time.

    Parameters
    ----------
    feed : str
    configure : callable or None
        ``configure(params)`` changes the MekfParams before the filter is built.
    calibrating : bool
        The calibrating filter, ``_core.MekfCal`` (15 states; its prior the Example's).
    output : int or None
        The samples' kind, passed to ``gyro()`` when given (``_core.GYRO_MEAN_RATE`` for
        "increments": the mean rate over the interval since the previous sample).

    Returns
    -------
    callable
    """
    from sc_rt import _core

    if feed not in ("pairs", "samples", "increments"):
        raise ValueError(f"feed must be 'pairs', 'samples' or 'increments', not {feed!r}")
    extra = () if output is None else (output,)
    n = 15 if calibrating else 6

    def run(data: Example61Data, k) -> FilterRun:
        params = scrt_params(data.p)
        if calibrating:
            params.initial_scale_factor_sigma = params.initial_misalignment_sigma = data.p.p0_calibration
        if configure is not None:
            configure(params)
        k = np.asarray(k)
        N, E, t = data.runs, len(k), data.t
        rec = np.full(len(t), -1)
        rec[k] = np.arange(E)
        sig, bias, PP = np.empty((N, E, 3)), np.empty((N, E, 3)), np.empty((N, E, n, n))
        cal = np.empty((N, E, 9)) if calibrating else None
        for r in range(N):
            f = _core.MekfCal(params) if calibrating else _core.Mekf(params)
            f.reset(float(t[0]), data.sigma0_est[r], data.bias0_est[r])
            g, gm, star = data.gyro[r], data.gyro_mean[r], data.star[r]
            for j in range(len(t)):
                tj = float(t[j])
                if feed == "pairs":
                    if j > 0:
                        f.gyro(tj, g[j - 1], *extra)
                    f.gyro(tj, g[j], *extra)
                elif feed == "samples":
                    f.gyro(tj, g[j], *extra)
                elif j > 0:
                    f.gyro(tj, gm[j - 1], *extra)
                f.star(tj, star[j])
                if rec[j] >= 0:
                    s = f.state
                    e = rec[j]
                    sig[r, e], bias[r, e], PP[r, e] = s.sigma, s.bias, s.P  # copied out of the views
                    if calibrating:
                        cal[r, e] = s.cal
        return FilterRun(k=k, sigma=sig, bias=bias, P=PP, cal=cal)

    return run
