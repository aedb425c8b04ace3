"""The orbit and its environment (docs/MODEL.md section 11), the Python twin
of cpp/src/orbit.cpp.

A Keplerian orbit from elements and an epoch, with optional J2 secular
drift; Earth rotation (GMST, IAU-1982 expression as in Meeus (12.4)); the Sun
direction (the Astronomical Almanac's low-precision formulae, about 0.01 deg)
and a cylindrical Earth shadow; the gravity-gradient torque of the orbit's
actual radius and nadir.

Frames: N = ECI, the mean equator and equinox of date (the frame GMST and
the almanac's Sun refer to; precession over a run is ignored); E = ECEF
(N rotated by GMST about z); B = body. Units: m, s, rad; Julian dates in
days (UTC, taken as UT1).

Every scalar operation is the C++ one in the same order, with ``math``
(glibc's sin, cos, atan2, fmod, sqrt): the two give the same bits
(tests/test_orbit.py compares them with ``==``). The cost of an evaluation
does not grow with t: the mean anomaly is reduced modulo 2 pi before a
Kepler solve of at most ``KEPLER_ITERATIONS`` Newton steps.

Examples
--------
>>> from sc_rt.model.orbit import OrbitParams, orbit_state
>>> o = OrbitParams(a=7000e3)
>>> r, v = orbit_state(o, 0.0)
>>> r[0], round(v[1], 3)
(7000000.0, 7546.053)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "MU_EARTH",
    "R_EARTH",
    "J2_EARTH",
    "JD_J2000",
    "KEPLER_ITERATIONS",
    "rotate_to_B",
    "OrbitParams",
    "OrbitRates",
    "orbit_rates",
    "mean_anomaly_from_true",
    "orbit_position",
    "orbit_state",
    "gmst",
    "eci_to_ecef",
    "sun_direction_N",
    "sun_distance_au",
    "in_eclipse",
    "gg_terms",
    "gg_torque",
    "gravity_gradient_orbit",
    "orbit_params_to_cpp",
]

MU_EARTH = 3.986004418e14  # [m^3/s^2] GM of the Earth (WGS-84 / EGM-96)
R_EARTH = 6378137.0  # [m] equatorial radius (WGS-84), J2's reference
J2_EARTH = 1.08262668e-3  # [-] J2 (EGM-96, unnormalised)
JD_J2000 = 2451545.0  # [day] Julian date of J2000.0
KEPLER_ITERATIONS = 30  # Newton steps at most (e < 0.99)

_PI = 3.141592653589793
_TWO_PI = 2.0 * _PI
_DEG = _PI / 180.0  # [rad/deg]
_sin, _cos, _sqrt, _fmod = math.sin, math.cos, math.sqrt, math.fmod


@dataclass(frozen=True)
class OrbitParams:
    """A Keplerian orbit (defaults: 400 km circular, equatorial, 2026-01-01 00:00 UTC).

    Validated on construction (ValueError naming the field and the value).
    """

    a: float = 6778137.0  # [m] semi-major axis
    e: float = 0.0  # [-] eccentricity, 0 <= e < 0.99
    i: float = 0.0  # [rad] inclination
    raan: float = 0.0  # [rad] right ascension of the ascending node at epoch
    argp: float = 0.0  # [rad] argument of perigee at epoch
    M0: float = 0.0  # [rad] mean anomaly at epoch
    jd_epoch: float = 2461041.5  # [day] UTC Julian date at t = 0
    j2: bool = False  # J2 secular drift of raan, argp and the mean anomaly
    mu: float = MU_EARTH  # [m^3/s^2]
    R_eq: float = R_EARTH  # [m]
    J2: float = J2_EARTH  # [-]

    def __post_init__(self) -> None:
        errs: list[str] = []
        for name in ("a", "e", "i", "raan", "argp", "M0", "jd_epoch", "mu", "R_eq", "J2"):
            v = getattr(self, name)
            try:
                v = float(v)
            except (TypeError, ValueError):
                v = math.nan
            if not math.isfinite(v):
                errs.append(f"OrbitParams.{name} must be finite, got {getattr(self, name)!r}")
            object.__setattr__(self, name, v)
        object.__setattr__(self, "j2", bool(self.j2))
        if not (self.mu > 0.0):
            errs.append(f"OrbitParams.mu must be > 0, got {self.mu!r}")
        if not (self.R_eq > 0.0):
            errs.append(f"OrbitParams.R_eq must be > 0, got {self.R_eq!r}")
        if not (self.J2 >= 0.0):
            errs.append(f"OrbitParams.J2 must be >= 0, got {self.J2!r}")
        if not (0.0 <= self.e < 0.99):
            errs.append(f"OrbitParams.e must be in [0, 0.99), got {self.e!r}")
        if not (self.a > 0.0):
            errs.append(f"OrbitParams.a must be > 0, got {self.a!r}")
        elif math.isfinite(self.e) and not (self.a * (1.0 - self.e) > self.R_eq):
            errs.append(
                f"OrbitParams: the perigee radius a (1 - e) = {self.a * (1.0 - self.e)!r} m "
                f"must be above R_eq = {self.R_eq!r} m"
            )
        if not (2415020.5 < self.jd_epoch < 2488069.5):
            errs.append(f"OrbitParams.jd_epoch must be a Julian date in 1900-2100, got {self.jd_epoch!r}")
        if errs:
            raise ValueError("invalid OrbitParams: " + "; ".join(errs))


@dataclass(frozen=True)
class OrbitRates:
    """The orbit's constants derived once (orbit_rates)."""

    n: float  # [rad/s] Keplerian mean motion
    raan_dot: float  # [rad/s] J2 node regression (0 without J2)
    argp_dot: float  # [rad/s] J2 apsidal rotation (0 without J2)
    M_dot: float  # [rad/s] mean-anomaly rate
    b: float  # [m] semi-minor axis


def orbit_rates(p: OrbitParams) -> OrbitRates:
    """Mean motion, J2 secular rates (Vallado (9-41)) and the semi-minor axis."""
    n = _sqrt(p.mu / (p.a * p.a * p.a))
    b = p.a * _sqrt(1.0 - p.e * p.e)
    raan_dot = 0.0
    argp_dot = 0.0
    M_dot = n
    if p.j2:
        ps = p.a * (1.0 - p.e * p.e)
        Rp = p.R_eq / ps
        K = 1.5 * n * p.J2 * (Rp * Rp)
        si = _sin(p.i)
        s2 = si * si
        raan_dot = -K * _cos(p.i)
        argp_dot = K * (2.0 - 2.5 * s2)
        M_dot = n + K * _sqrt(1.0 - p.e * p.e) * (1.0 - 1.5 * s2)
    return OrbitRates(n, raan_dot, argp_dot, M_dot, b)


def _wrap(x: float, m: float) -> float:
    y = _fmod(x, m)
    if y < 0.0:
        y = y + m
    return y


def _eccentric_anomaly(M: float, e: float) -> float:
    """Kepler's equation by Newton (Vallado, Algorithm 2), M in [0, 2 pi)."""
    E = M if e < 0.8 else _PI
    for _ in range(KEPLER_ITERATIONS):
        dE = (E - e * _sin(E) - M) / (1.0 - e * _cos(E))
        E = E - dE
        if abs(dE) < 1e-15:
            break
    return E


def _elements_at(p: OrbitParams, k: OrbitRates, t: float) -> tuple[float, float, float]:
    M = _wrap(p.M0 + k.M_dot * t, _TWO_PI)
    return _eccentric_anomaly(M, p.e), p.raan + k.raan_dot * t, p.argp + k.argp_dot * t


def _pq_axes(raan: float, argp: float, inc: float):
    cO, sO = _cos(raan), _sin(raan)
    cw, sw = _cos(argp), _sin(argp)
    ci, si = _cos(inc), _sin(inc)
    P = (cO * cw - sO * sw * ci, sO * cw + cO * sw * ci, sw * si)
    Q = (-cO * sw - sO * cw * ci, -sO * sw + cO * cw * ci, cw * si)
    return P, Q


def mean_anomaly_from_true(nu: float, e: float) -> float:
    """Mean anomaly [rad] of the true anomaly ``nu`` [rad] (Vallado (2-9), (2-4))."""
    E = 2.0 * math.atan2(_sqrt(1.0 - e) * _sin(0.5 * nu), _sqrt(1.0 + e) * _cos(0.5 * nu))
    return E - e * _sin(E)


def orbit_position(p: OrbitParams, k: OrbitRates, t: float) -> tuple[float, float, float]:
    """Position in N [m] at ``t`` [s] after the epoch, as a tuple (the plant's kernel)."""
    E, raan, argp = _elements_at(p, k, float(t))
    P, Q = _pq_axes(raan, argp, p.i)
    xp = p.a * (_cos(E) - p.e)
    yp = k.b * _sin(E)
    return (xp * P[0] + yp * Q[0], xp * P[1] + yp * Q[1], xp * P[2] + yp * Q[2])


def orbit_state(p: OrbitParams, t: float) -> tuple[np.ndarray, np.ndarray]:
    """Position [m] and velocity [m/s] in N at ``t`` [s] after the epoch.

    The velocity is the osculating Keplerian ellipse's (the J2 drift of the
    node and perigee, of order J2 n r, is not in it).
    """
    k = orbit_rates(p)
    E, raan, argp = _elements_at(p, k, float(t))
    P, Q = _pq_axes(raan, argp, p.i)
    cE, sE = _cos(E), _sin(E)
    xp = p.a * (cE - p.e)
    yp = k.b * sE
    f = _sqrt(p.mu * p.a) / (p.a * (1.0 - p.e * cE))
    vxp = -f * sE
    vyp = f * _sqrt(1.0 - p.e * p.e) * cE
    r = np.array([xp * P[j] + yp * Q[j] for j in range(3)])
    v = np.array([vxp * P[j] + vyp * Q[j] for j in range(3)])
    return r, v


def gmst(jd_day: float, t: float = 0.0) -> float:
    """Greenwich mean sidereal time [rad] in [0, 2 pi) at jd_day + t / 86400 (UT1).

    Meeus (12.4): 280.46061837 + 360.98564736629 D + 0.000387933 T^2 - T^3 / 38710000 [deg].
    """
    Dd = float(jd_day) - JD_J2000
    f = float(t) / 86400.0
    D = Dd + f
    T = D / 36525.0
    deg = (280.46061837 + 360.0 * (_fmod(Dd, 1.0) + f) + 0.98564736629 * D
           + 0.000387933 * (T * T) - (T * T * T) / 38710000.0)  # fmt: skip
    return _wrap(deg, 360.0) * _DEG


def eci_to_ecef(jd_day: float, t: float = 0.0) -> np.ndarray:
    """C_EN (3, 3): ECI (mean of date) -> ECEF, a rotation by gmst about z."""
    th = gmst(jd_day, t)
    c, s = _cos(th), _sin(th)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def _sun_angles(jd_day: float, t: float) -> tuple[float, float, float]:
    n = (float(jd_day) - JD_J2000) + float(t) / 86400.0
    L = _wrap(280.460 + 0.9856474 * n, 360.0)
    g = _wrap(357.528 + 0.9856003 * n, 360.0) * _DEG
    lam = (L + 1.915 * _sin(g) + 0.020 * _sin(2.0 * g)) * _DEG
    eps = (23.439 - 0.0000004 * n) * _DEG
    return g, lam, eps


def sun_direction_N(jd_day: float, t: float = 0.0) -> np.ndarray:
    """Unit vector Earth -> Sun in N (Astronomical Almanac, low precision, ~0.01 deg)."""
    _, lam, eps = _sun_angles(jd_day, t)
    cl, sl = _cos(lam), _sin(lam)
    return np.array([cl, _cos(eps) * sl, _sin(eps) * sl])


def sun_distance_au(jd_day: float, t: float = 0.0) -> float:
    """Earth-Sun distance [AU] (the same almanac formula)."""
    g, _, _ = _sun_angles(jd_day, t)
    return 1.00014 - 0.01671 * _cos(g) - 0.00014 * _cos(2.0 * g)


def in_eclipse(r_N, s_N, R_eq: float = R_EARTH) -> bool:
    """True in the cylindrical shadow: r.s < 0 and |r - (r.s) s| < R_eq [m]."""
    r1, r2, r3 = (float(v) for v in r_N)
    s1, s2, s3 = (float(v) for v in s_N)
    rs = r1 * s1 + r2 * s2 + r3 * s3
    if not rs < 0.0:
        return False
    rr = r1 * r1 + r2 * r2 + r3 * r3
    return rr - rs * rs < R_eq * R_eq


def gg_terms(mu: float, r1: float, r2: float, r3: float) -> tuple[float, float, float, float]:
    """``(3 mu / |r|^3, r / |r|)`` of a position [m]: the plant's gravity-gradient terms."""
    rr = r1 * r1 + r2 * r2 + r3 * r3
    rn = _sqrt(rr)
    return (3.0 * mu / (rr * rn), r1 / rn, r2 / rn, r3 / rn)


def rotate_to_B(s1: float, s2: float, s3: float, n1: float, n2: float, n3: float) -> tuple[float, float, float]:
    """``C_BN(sigma) n`` on scalars (its C++ twin is rotate_to_B in cpp/include/sc_rt/orbit.hpp, the same operations):
    ``n + [8 (s (s.n) - |s|^2 n) - 4 (1 - |s|^2) (s x n)] / (1 + |s|^2)^2`` (Schaub & Junkins (3.153))."""
    ss = s1 * s1 + s2 * s2 + s3 * s3
    q = 1.0 / ((1.0 + ss) * (1.0 + ss))
    m4 = 4.0 * (1.0 - ss)
    sn = s1 * n1 + s2 * n2 + s3 * n3
    c1 = s2 * n3 - s3 * n2
    c2 = s3 * n1 - s1 * n3
    c3 = s1 * n2 - s2 * n1
    return (n1 + (8.0 * (s1 * sn - ss * n1) - m4 * c1) * q,
            n2 + (8.0 * (s2 * sn - ss * n2) - m4 * c2) * q,
            n3 + (8.0 * (s3 * sn - ss * n3) - m4 * c3) * q)


def gg_torque(J, s1: float, s2: float, s3: float, g) -> tuple[float, float, float]:
    """``u_g = g0 (r x J r)``, ``r = C_BN(sigma) n`` (``rotate_to_B``) for ``g = (g0, n)`` [N m];
    ``J`` a 3x3 nested sequence of floats."""
    (J11, J12, J13), (J21, J22, J23), (J31, J32, J33) = J
    g0, n1, n2, n3 = g
    r1, r2, r3 = rotate_to_B(s1, s2, s3, n1, n2, n3)
    j1 = J11 * r1 + J12 * r2 + J13 * r3
    j2 = J21 * r1 + J22 * r2 + J23 * r3
    j3 = J31 * r1 + J32 * r2 + J33 * r3
    return (g0 * (r2 * j3 - r3 * j2), g0 * (r3 * j1 - r1 * j3), g0 * (r1 * j2 - r2 * j1))


def gravity_gradient_orbit(J, sigma_BN, r_N, mu: float = MU_EARTH) -> np.ndarray:
    """Gravity-gradient torque [N m] in B: ``3 mu / r^5 (r_B x J r_B)``, ``r_B = C_BN r_N``.

    Parameters
    ----------
    J : array_like, shape (3, 3)
        Inertia [kg m^2].
    sigma_BN : array_like, shape (3,)
        MRP of B relative to N.
    r_N : array_like, shape (3,)
        Position in N [m].
    mu : float
        Gravitational parameter [m^3/s^2].
    """
    Jl = np.asarray(J, dtype=float).tolist()
    s1, s2, s3 = (float(v) for v in sigma_BN)
    r1, r2, r3 = (float(v) for v in r_N)
    return np.array(gg_torque(Jl, s1, s2, s3, gg_terms(float(mu), r1, r2, r3)))


def orbit_params_to_cpp(p: OrbitParams | None):
    """The C++ ``sc_rt._core.OrbitParams`` of ``p`` (None: a disabled one)."""
    from sc_rt import _core

    o = _core.OrbitParams()
    if p is None:
        return o
    o.enabled = True
    for name in ("a", "e", "i", "raan", "argp", "M0", "jd_epoch", "j2", "mu", "R_eq", "J2"):
        setattr(o, name, getattr(p, name))
    return o
