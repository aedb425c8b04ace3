"""Markley & Crassidis (2014), Example 6.1, re-implemented in numpy: an independent reference for
sc-rt's attitude filter (issue 30, item 4).

F. L. Markley and J. L. Crassidis, *Fundamentals of Spacecraft Attitude Determination and Control*,
Springer, 2014, Example 6.1: a slowly turning spacecraft, a star tracker and three gyros at 1 Hz for
90 minutes; an MEKF estimates attitude and gyro biases (6 states) and, calibrating, the gyros' three
scale factors and six misalignments too (15 states). The author's script is public (repository
dtbinh/satellite); only its published numbers are taken, the rest is written anew, in sc-rt's terms:

- attitude as the body-from-inertial matrix C (sc-rt's R(sigma_BN)); quaternions scalar first with
  ``C(qmul(a, b)) = C(a) C(b)``; MRPs ``sigma = q_v / (1 + q_0)``;
- attitude error ``dtheta`` with ``C_true = exp(-dtheta^) C_est`` (the Example's and sc-rt's),
  bias error ``b_true - b_est``, calibration error ``S_true - S_est``;
- the gyro reads ``omega_m = (I + S) omega + b + n``; the calibration states in the Example's order
  ``[s1 s2 s3 kU1 kU2 kU3 kL1 kL2 kL3]`` with ``S = [[s1, kU1, kU2], [kL1, s2, kU3], [kL2, kL3, s3]]``.

Here: the parameters, the truth and measurements (:func:`simulate`, seeded numpy Generators, not
sc-rt's sensor models), Farrenkopf's steady state, the consistency checks
(:func:`check_calibrating_filter`). The filters, the quaternion helpers and the filters' output
(``FilterRun``): tests/example61_filters.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from example61_filters import FilterRun, cal_matrix, conj, mrp_quat, qmul, quat_mrp, quat_rotvec, rotvec_quat

DEG = math.pi / 180
ARCSEC = DEG / 3600
DEG_H = DEG / 3600  # 1 deg/h in rad/s
MINUTE = 60.0


@dataclass(frozen=True)
class Example61:
    """The Example's published parameters, SI units (rad, s); the source of each is the Example's
    script (dtbinh/satellite, example6_1.m: the variable named in the comment)."""

    dt: float = 1.0  # [s] dt = 1: gyro and star tracker sampled together at 1 Hz
    duration: float = 90 * MINUTE  # [s] tf = 90*60
    # true body rate w(t) = A [sin(f1 t), sin(f2 t), cos(f3 t)]: w = 0.1*pi/180*[sin(0.01t) sin(0.0085t) cos(0.0085t)]
    rate_amplitude: float = 0.1 * DEG  # [rad/s]
    rate_frequencies: tuple = (0.01, 0.0085, 0.0085)  # [rad/s]
    # initial attitude: q(1,:) = [1 0 0 1]/sqrt(2), scalar last (90 deg about x); here scalar first
    q0: tuple = (math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0)
    sigma_u: float = math.sqrt(10) * 1e-10  # [rad/s^(3/2)] bias random walk, sigu (after Reynolds, 2003)
    sigma_v: float = math.sqrt(10) * 1e-7  # [rad/s^(1/2)] angle random walk, sigv
    sigma_star: float = 6 * ARCSEC  # [rad] per axis, sig_tracker = 6/3600*pi/180; R = sig_tracker^2 I
    bias0: float = 0.1 * DEG_H  # [rad/s] true bias at t = 0 on every axis (the bias simulation's initial state)
    p0_attitude: float = 0.1 * DEG  # [rad] 1 sigma per axis, poa = (0.1*pi/180)^2 I
    p0_bias: float = 0.2 * DEG_H  # [rad/s] pog = (0.2*pi/180/3600)^2 I
    p0_calibration: float = 2000e-6 / 3  # [-] pos = poku = pokl = (2000e-6/3)^2 I
    # true scale factors and misalignments: s = 1e-6*[1500 1000 1500; 500 1000 2000; 1000 1500 1500]
    scale_factors: tuple = (1500e-6, 1000e-6, 1500e-6)  # diagonal s1 s2 s3
    misalign_upper: tuple = (1000e-6, 1500e-6, 2000e-6)  # kU1 = S12, kU2 = S13, kU3 = S23
    misalign_lower: tuple = (500e-6, 1000e-6, 1500e-6)  # kL1 = S21, kL2 = S31, kL3 = S32

    @property
    def steps(self) -> int:
        """Number of samples, t = 0, dt, ..., duration."""
        return int(round(self.duration / self.dt)) + 1

    def calibration(self) -> np.ndarray:
        """The true calibration states in the Example's order (9,)."""
        return np.array([*self.scale_factors, *self.misalign_upper, *self.misalign_lower])

    def rate(self, t) -> np.ndarray:
        """True body rate [rad/s] at the times t (..., 3)."""
        t = np.asarray(t, float)[..., None]
        f = np.array(self.rate_frequencies)
        return self.rate_amplitude * np.concatenate([np.sin(f[:2] * t), np.cos(f[2:] * t)], -1)

    def rate_integral(self, t) -> np.ndarray:
        """An antiderivative of :meth:`rate` [rad] (..., 3)."""
        t = np.asarray(t, float)[..., None]
        f = np.array(self.rate_frequencies)
        return self.rate_amplitude * np.concatenate([-np.cos(f[:2] * t) / f[:2], np.sin(f[2:] * t) / f[2:]], -1)


# --------------------------------------------------------------------------- attitude

def attitude_error(q_true, sigma_est) -> np.ndarray:
    """dtheta [rad] with ``C_true = exp(-dtheta^) C_est``."""
    return quat_rotvec(qmul(q_true, conj(mrp_quat(sigma_est))))


def _compose_scan(dq, q0) -> np.ndarray:
    """q_k = dq_{k-1} ... dq_0 q0 for k = 0..n (n + 1, 4), by a Hillis-Steele scan (log2 n
    vectorised passes; the rounding of ~log2 n products, not of n)."""
    acc = dq.copy()
    shift = 1
    while shift < len(acc):
        acc[shift:] = qmul(acc[shift:], acc[:-shift])
        shift *= 2
    q = np.concatenate([q0[None], qmul(acc, q0[None])])
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


# --------------------------------------------------------------------------- truth and measurements

@dataclass
class Example61Data:
    """Seeded runs of the Example: the truth (the runs share it but the bias) and the measurements.

    Attributes
    ----------
    p : Example61
    truth : str
        "held" or "smooth" (:func:`simulate`).
    t : (m,) sample times [s]
    q, sigma : (m, 4), (m, 3) true attitude, quaternion and MRP sigma_BN
    omega : (m, 3) true body rate at t_k [rad/s]
    bias : (N, m, 3) true gyro bias at t_k [rad/s]
    cal : (9,) the truth's calibration states (S of ``omega_m = (I + S) omega + b + n``), or zeros
    gyro : (N, m, 3) the gyro sample at t_k [rad/s]; with the held truth the Example's: the mean
        measured rate over [t_k, t_k+1] (the Example's filter holds it over that interval)
    gyro_mean : (N, m - 1, 3) the mean measured rate over [t_k, t_k+1] (the increment / dt), what an
        integrating gyro delivers at t_k+1; with the held truth the same numbers as gyro[:, :-1]
    star : (N, m, 3) star tracker sigma_BN measured at t_k
    sigma0_est, bias0_est : (N, 3) the filters' initial estimates
    """

    p: Example61
    truth: str
    t: np.ndarray
    q: np.ndarray
    sigma: np.ndarray
    omega: np.ndarray
    bias: np.ndarray
    cal: np.ndarray
    gyro: np.ndarray
    gyro_mean: np.ndarray
    star: np.ndarray
    sigma0_est: np.ndarray
    bias0_est: np.ndarray

    runs = property(lambda self: self.gyro.shape[0], doc="N, the number of runs.")


def simulate(p: Example61 = Example61(), runs: int = 20, seed: int = 61, *, calibration: bool = False,
             truth: str = "held", initial: str = "drawn", n_sub: int = 8) -> Example61Data:
    """The Example's truth and measurements for ``runs`` runs.

    Parameters
    ----------
    p : Example61
    runs : int
    seed : int
        Seeds one numpy Generator per purpose (bias, gyro noise, star noise, initial errors).
    calibration : bool
        The Example's scale factors and misalignments in the gyro (else none, the bias only).
    truth : str
        "held": the Example's truth, w(t_k) held over each sample interval and the attitude turned
        exactly by w(t_k) dt. "smooth": w(t) itself; each of n_sub substeps turns by the exact
        integral of w over it (the coning term left out errs by |w x w'| h^3 / 12 ~ 1e-11 rad per
        substep); gyro samples the rate at t_k, gyro_mean its exact mean over the interval.
    initial : str
        "drawn": initial errors drawn from the filters' prior (attitude estimate = truth rotated by
        N(0, p0_attitude^2 I), true bias N(0, p0_bias^2 I), bias estimate 0), so that the runs are
        consistent from t = 0. "example": the Example's start (estimate = truth, true bias bias0 on
        every axis).
    n_sub : int

    Returns
    -------
    Example61Data
    """
    m, dt = p.steps, p.dt
    t = np.arange(m) * dt
    cal = p.calibration() if calibration else np.zeros(9)
    S = cal_matrix(cal)
    q0 = np.array(p.q0)
    if truth == "held":
        omega = p.rate(t)
        q = _compose_scan(rotvec_quat(omega[:-1] * dt), q0)
        w_mean = omega[:-1]
    elif truth == "smooth":
        ts = np.arange((m - 1) * n_sub + 1) * (dt / n_sub)
        W = p.rate_integral(ts)
        q = _compose_scan(rotvec_quat(np.diff(W, axis=0)), q0)[::n_sub]
        omega = p.rate(t)
        w_mean = np.diff(p.rate_integral(t), axis=0) / dt
    else:
        raise ValueError(f"truth must be 'held' or 'smooth', not {truth!r}")
    rng = [np.random.default_rng([seed, k]) for k in range(6)]
    # bias: a random walk sampled at t_k; a sample over [t_k, t_k+1] reads its mean, (b_k + b_k+1)/2,
    # plus white noise of variance sigma_v^2 / dt + sigma_u^2 dt / 12 (the discrete model of the
    # mean over the interval, Markley & Crassidis ch. 6; the script builds the same statistics with
    # a trapezoidal transfer function)
    if initial == "drawn":
        b0 = p.p0_bias * rng[4].standard_normal((runs, 3))
        sigma0_est = quat_mrp(qmul(rotvec_quat(-p.p0_attitude * rng[4].standard_normal((runs, 3))), q0))
    elif initial == "example":
        b0 = np.full((runs, 3), p.bias0)
        sigma0_est = np.tile(quat_mrp(q0), (runs, 1))
    else:
        raise ValueError(f"initial must be 'drawn' or 'example', not {initial!r}")
    steps = p.sigma_u * math.sqrt(dt) * rng[1].standard_normal((runs, m, 3))
    bias = b0[:, None] + np.concatenate([np.zeros((runs, 1, 3)), np.cumsum(steps, axis=1)], axis=1)  # (N, m+1, 3)
    sd_mean = math.sqrt(p.sigma_v ** 2 / dt + p.sigma_u ** 2 * dt / 12)
    b_mean = 0.5 * (bias[:, :-1] + bias[:, 1:])  # (N, m, 3) over [t_k, t_k+1]
    if truth == "held":
        gyro = omega @ (np.eye(3) + S).T + b_mean + sd_mean * rng[2].standard_normal((runs, m, 3))
        gyro_mean = gyro[:, :-1]
    else:
        gyro = omega @ (np.eye(3) + S).T + bias[:, :-1] + (p.sigma_v / math.sqrt(dt)) * \
            rng[2].standard_normal((runs, m, 3))
        gyro_mean = w_mean @ (np.eye(3) + S).T + b_mean[:, :-1] + sd_mean * rng[5].standard_normal((runs, m - 1, 3))
    v = p.sigma_star * rng[3].standard_normal((runs, m, 3))
    star = quat_mrp(qmul(rotvec_quat(v), q[None]))
    return Example61Data(p=p, truth=truth, t=t, q=q, sigma=quat_mrp(q), omega=omega, bias=bias[:, :-1], cal=cal,
                         gyro=gyro, gyro_mean=gyro_mean, star=star, sigma0_est=sigma0_est,
                         bias0_est=np.zeros((runs, 3)))


# --------------------------------------------------------------------------- Farrenkopf

def farrenkopf(sigma_v: float, sigma_u: float, sigma_n: float, dt: float) -> dict:
    """Steady-state 1-sigma attitude and bias errors of the single-axis gyro + attitude sensor filter.

    The result is Farrenkopf's (R. L. Farrenkopf, "Analytic Steady-State Accuracy Solutions for Two
    Common Spacecraft Attitude Estimators", J. Guidance and Control 1(4), 1978, 282-284), which
    Markley & Crassidis (2014) present in chapter 6; derived here anew, in our notation, from the
    discrete filter (one axis, no rotation): state [theta, b], Phi = [[1, -dt], [0, 1]],
    Q = [[sv^2 dt + su^2 dt^3/3, -su^2 dt^2/2],
    [., su^2 dt]], H = [1, 0], R = sn^2. In steady state the bias row of the update gives
    q^2 = su^2 dt s (q the predicted cross covariance, s the innovation variance), the cross term
    dt c+ = -q p-/s - su^2 dt^2/2, and the attitude row p-^2 = -dt q (2 sn^2 + p-) + s (sv^2 dt - su^2 dt^3/6).
    With s = sn^2 xi^2 this is a palindromic quartic in xi, a quadratic in xi + 1/xi:

        S_u = su dt^(3/2) / sn,   S_v = sv dt^(1/2) / sn
        xi + 1/xi = S_u / 2 + sqrt(4 + S_v^2 + S_u^2 / 12),   xi >= 1
        attitude:  sigma-^2 = sn^2 (xi^2 - 1),     sigma+^2 = sn^2 (1 - xi^-2)
        bias:      sigma-^2 = (sn / dt)^2 [S_u (xi - 1/xi) + S_u^2 / 2]
                   sigma+^2 = (sn / dt)^2 [S_u (xi - 1/xi) - S_u^2 / 2]

    (- before, + after the update). tests/test_example61.py checks it against scipy's discrete
    Riccati solver.

    Parameters
    ----------
    sigma_v : float
        [rad/s^(1/2)] angle random walk.
    sigma_u : float
        [rad/s^(3/2)] bias random walk.
    sigma_n : float
        [rad] attitude measurement noise per axis.
    dt : float
        [s] sample period.

    Returns
    -------
    dict
        att_pre, att_post [rad], bias_pre, bias_post [rad/s]: 1-sigma.
    """
    Su, Sv = sigma_u * dt ** 1.5 / sigma_n, sigma_v * math.sqrt(dt) / sigma_n
    r = math.sqrt(4 + Sv ** 2 + Su ** 2 / 12)
    zm2 = Su / 2 + (Sv ** 2 + Su ** 2 / 12) / (r + 2)  # xi + 1/xi - 2, without cancellation
    xi = (2 + zm2 + math.sqrt(zm2 * (4 + zm2))) / 2
    d = xi - 1 / xi
    return dict(att_pre=sigma_n * math.sqrt(xi ** 2 - 1), att_post=sigma_n * math.sqrt(1 - xi ** -2),
                bias_pre=sigma_n / dt * math.sqrt(Su * d + Su ** 2 / 2),
                bias_post=sigma_n / dt * math.sqrt(Su * d - Su ** 2 / 2))


# --------------------------------------------------------------------------- consistency

@dataclass
class Consistency:
    """The errors of a :class:`FilterRun` against the truth and their statistics.

    Attributes
    ----------
    t : (E,) epochs [s]
    nees : (E,) mean over the runs of the NEES of attitude and bias (6 dof)
    nees_all : (E,) the same over every state of the run (6 or 15 dof)
    band, band_all : (2,) two-sided chi-square band of those means (level ``level``)
    inside : fraction of the error components within 3 sigma (every run, state and epoch)
    sigma3_att, sigma3_bias : 3-sigma [rad], [rad/s] at the last epoch (mean over runs and axes)
    rms_att, rms_bias : RMS error at the last epoch over runs and axes [rad], [rad/s]
    """

    t: np.ndarray
    nees: np.ndarray
    nees_all: np.ndarray
    band: np.ndarray
    band_all: np.ndarray
    inside: float
    sigma3_att: float
    sigma3_bias: float
    rms_att: float
    rms_bias: float


def consistency(data: Example61Data, run: FilterRun, level: float = 0.99) -> Consistency:
    """Errors of ``run`` against ``data``'s truth, NEES and the fraction inside 3 sigma.

    With N independent runs of a consistent filter, N times the mean NEES of n states at an epoch
    is chi-square with n N degrees of freedom: its two-sided ``level`` band from scipy.stats.chi2.

    Parameters
    ----------
    data : Example61Data
    run : FilterRun
    level : float

    Returns
    -------
    Consistency
    """
    k = np.asarray(run.k)
    N, n = run.sigma.shape[0], run.P.shape[-1]
    e = [attitude_error(data.q[k][None], run.sigma), data.bias[:, k] - run.bias]
    if n == 15:
        e.append(data.cal - run.cal)
    e = np.concatenate(e, -1)
    P = run.P
    nees6 = np.einsum("nei,nei->ne", e[..., :6], np.linalg.solve(P[..., :6, :6], e[..., :6, None])[..., 0])
    nees = np.einsum("nei,nei->ne", e, np.linalg.solve(P, e[..., None])[..., 0])
    sd = np.sqrt(np.diagonal(P, axis1=-2, axis2=-1))
    a = (1 - level) / 2
    return Consistency(
        t=data.t[k], nees=nees6.mean(0), nees_all=nees.mean(0),
        band=stats.chi2.ppf([a, 1 - a], 6 * N) / N, band_all=stats.chi2.ppf([a, 1 - a], n * N) / N,
        inside=float(np.mean(np.abs(e) <= 3 * sd)),
        sigma3_att=float(3 * sd[:, -1, :3].mean()), sigma3_bias=float(3 * sd[:, -1, 3:6].mean()),
        rms_att=float(np.sqrt(np.mean(e[:, -1, :3] ** 2))), rms_bias=float(np.sqrt(np.mean(e[:, -1, 3:6] ** 2))))


#: Epochs at which the mean NEES is held to its band: 30, 60 and 90 min (each at a 99 % level,
#: so that three epochs and two NEES leave ~6 % to chance in a consistent filter).
NEES_EPOCHS = (30 * MINUTE, 60 * MINUTE, 90 * MINUTE)


def check_consistency(data: Example61Data, run: FilterRun, min_inside: float = 0.99) -> Consistency:
    """Assert that ``run`` is consistent with ``data``: the mean NEES (attitude and bias, and every
    state) inside its chi-square band at :data:`NEES_EPOCHS`, and at least ``min_inside`` of the
    error components within 3 sigma (0.9973 expected).

    Parameters
    ----------
    data : Example61Data
    run : FilterRun
    min_inside : float

    Returns
    -------
    Consistency
        When consistent (else AssertionError, the numbers in its message).
    """
    c = consistency(data, run)
    at = [int(np.argmin(np.abs(c.t - te))) for te in NEES_EPOCHS]
    bad = [f"t = {c.t[i]:.0f} s: mean NEES {v[i]:.3g} outside [{b[0]:.3g}, {b[1]:.3g}] ({name})"
           for i in at for v, b, name in ((c.nees, c.band, "attitude+bias"), (c.nees_all, c.band_all, "all states"))
           if not b[0] <= v[i] <= b[1]]
    if c.inside < min_inside:
        bad.append(f"{c.inside:.4f} of the errors within 3 sigma (< {min_inside})")
    assert not bad, "inconsistent filter: " + "; ".join(bad)
    return c


def check_calibrating_filter(run_filter, runs: int = 20, seed: int = 61, stride: int = 10, **options) -> Consistency:
    """The Example's calibrating case for any filter: the truth with the Example's scale factors and
    misalignments, ``runs`` seeded runs fed to ``run_filter``, its errors held to its covariance
    (:func:`check_consistency`). A filter that does not estimate the calibration fails it.

    Parameters
    ----------
    run_filter : callable
        ``run_filter(data, k) -> FilterRun``: runs the filter on every run of ``data`` (an
        :class:`Example61Data`, the held truth: ``data.gyro[:, j]`` is the measured rate over
        [t_j, t_j+1], equally ``data.gyro_mean[:, j]``, an increment delivered at t_j+1) from
        ``data.sigma0_est``, ``data.bias0_est``, the calibration estimate 0 and the prior of
        ``data.p`` (p0_attitude, p0_bias, p0_calibration), updating with ``data.star[:, j]`` at each
        t_j, and records the state after the update at the indices ``k``.
    runs : int
    seed : int
    stride : int
        Record every stride-th sample.
    **options
        Passed to :func:`simulate` (``truth="smooth"``: a smooth rate, for a filter of increments).

    Returns
    -------
    Consistency
    """
    data = simulate(Example61(), runs, seed, calibration=True, **options)
    k = np.arange(0, data.p.steps, stride)
    return check_consistency(data, run_filter(data, k))

