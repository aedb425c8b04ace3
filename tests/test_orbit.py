"""The orbit, Earth rotation, Sun, eclipse and the orbit's gravity gradient
(sc_rt.model.orbit, cpp/src/orbit.cpp): against closed forms, published
almanac values, sgp4, numpy, and the C++ twin bit for bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.model import orbit as orb
from sc_rt.model.orbit import MU_EARTH, R_EARTH, OrbitParams, orbit_params_to_cpp
from sc_rt.scenario.tables.orbit import julian_date

_ORBITS = {
    "circular_leo": OrbitParams(a=R_EARTH + 400e3),
    "inclined_j2": OrbitParams(a=R_EARTH + 550e3, e=0.001, i=math.radians(97.6), raan=1.0, argp=0.3, M0=2.0,
                               j2=True),
    "molniya": OrbitParams(a=26600e3, e=0.74, i=math.radians(63.4), raan=4.0, argp=math.radians(270.0), M0=0.5),
    "gto_j2": OrbitParams(a=24400e3, e=0.73, i=math.radians(7.0), raan=0.2, argp=3.0, M0=5.9, j2=True),
}
_TIMES = [0.0, 0.1, 1.0, 59.9, 1234.5, 5400.0, 86399.9, 86400.0 * 30 + 0.3]


def _h_and_energy(r, v, mu=MU_EARTH):
    return np.cross(r, v), 0.5 * (v @ v) - mu / np.linalg.norm(r)


# --- the twins, bit for bit -------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(_ORBITS))
def test_orbit_state_python_and_cpp_bit_identical(name):
    p = _ORBITS[name]
    c = orbit_params_to_cpp(p)
    assert _core.orbit_rates(c) == tuple(getattr(orb.orbit_rates(p), k) for k in ("n", "raan_dot", "argp_dot",
                                                                                   "M_dot", "b"))
    for t in _TIMES:
        r_py, v_py = orb.orbit_state(p, t)
        r_c, v_c = _core.orbit_state(c, t)
        assert np.array_equal(r_py, r_c) and np.array_equal(v_py, v_c), (name, t)
        assert tuple(r_py) == orb.orbit_position(p, orb.orbit_rates(p), t)


def test_environment_python_and_cpp_bit_identical():
    rng = np.random.default_rng(3)
    for _ in range(200):
        jd = 2451545.0 + rng.uniform(-9000.0, 20000.0)
        t = float(rng.uniform(0.0, 86400.0))
        assert orb.gmst(jd, t) == _core.gmst(jd, t)
        assert np.array_equal(orb.eci_to_ecef(jd, t), _core.eci_to_ecef(jd, t))
        assert np.array_equal(orb.sun_direction_N(jd, t), _core.sun_direction_N(jd, t))
        assert orb.sun_distance_au(jd, t) == _core.sun_distance_au(jd, t)
        r = rng.normal(size=3) * 7e6
        s = orb.sun_direction_N(jd, t)
        assert orb.in_eclipse(r, s) == _core.in_eclipse(r, s)
        nu, e = float(rng.uniform(-7.0, 7.0)), float(rng.uniform(0.0, 0.95))
        assert orb.mean_anomaly_from_true(nu, e) == _core.mean_anomaly_from_true(nu, e)


def test_gravity_gradient_orbit_python_and_cpp_bit_identical():
    rng = np.random.default_rng(5)
    for _ in range(200):
        A = rng.normal(size=(3, 3))
        J = A @ A.T + 5.0 * np.eye(3)
        s = rng.normal(size=3) * 0.5
        r = rng.normal(size=3) * 7e6
        assert np.array_equal(orb.gravity_gradient_orbit(J, s, r), _core.gravity_gradient_orbit(J, s, r))


def test_cpp_orbit_params_validate_and_name_the_value():
    with pytest.raises(ValueError, match=r"e must be in \[0, 0.99\), got 1.2"):
        _core.OrbitParams(e=1.2)
    with pytest.raises(ValueError, match="perigee radius"):
        _core.OrbitParams(a=7000e3, e=0.5)
    with pytest.raises(ValueError, match="OrbitParams.e must be in"):
        OrbitParams(e=-0.1)
    with pytest.raises(ValueError, match="perigee radius"):
        OrbitParams(a=6000e3)
    assert _core.OrbitParams(a=7e6).enabled and not _core.OrbitParams().enabled


# --- closed forms -------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["circular_leo", "molniya"])
def test_period_energy_and_angular_momentum_of_the_kepler_orbit(name):
    p = _ORBITS[name]
    T = 2.0 * math.pi * math.sqrt(p.a**3 / MU_EARTH)  # Kepler's third law
    r0, v0 = orb.orbit_state(p, 0.0)
    h0, E0 = _h_and_energy(r0, v0)
    # vis-viva energy -mu / 2a and |h| = sqrt(mu a (1 - e^2)), by hand
    assert E0 == pytest.approx(-MU_EARTH / (2.0 * p.a), rel=1e-12)
    assert np.linalg.norm(h0) == pytest.approx(math.sqrt(MU_EARTH * p.a * (1.0 - p.e**2)), rel=1e-12)
    for t in np.linspace(0.0, 3.0 * T, 61):
        r, v = orb.orbit_state(p, t)
        h, E = _h_and_energy(r, v)
        assert E == pytest.approx(E0, rel=1e-11)
        np.testing.assert_allclose(h, h0, rtol=0, atol=1e-11 * np.linalg.norm(h0))
    # after whole periods the same place (the phase error of t n over 10 periods: ~1e-12 rad)
    r10, _ = orb.orbit_state(p, 10.0 * T)
    np.testing.assert_allclose(r10, r0, rtol=0, atol=1e-5 * p.a)
    # the velocity is the derivative of the position (central difference, O(dt^2) ~ 1e-9 relative)
    dt = 0.01
    t = 0.3 * T
    rp, _ = orb.orbit_state(p, t + dt)
    rm, _ = orb.orbit_state(p, t - dt)
    _, v = orb.orbit_state(p, t)
    np.testing.assert_allclose((rp - rm) / (2 * dt), v, rtol=0, atol=1e-6 * np.linalg.norm(v))


def test_kepler_solve_cost_does_not_grow_with_time():
    # the mean anomaly is reduced before Newton: a decade away gives the same
    # position as the same phase a period away (to the rounding of t n)
    p = _ORBITS["molniya"]
    T = 2.0 * math.pi / orb.orbit_rates(p).n
    k = round(10 * 365.25 * 86400.0 / T)
    r1, _ = orb.orbit_state(p, 123.0)
    r2, _ = orb.orbit_state(p, 123.0 + k * T)
    np.testing.assert_allclose(r2, r1, rtol=0, atol=5.0)  # [m]: t n rounds to ~1e-9 rad at 3e8 s


def _node(p, t):
    r, v = orb.orbit_state(p, t)
    h = np.cross(r, v)
    return math.atan2(h[0], -h[1])


def test_j2_node_regression_is_sun_synchronous_where_the_textbook_says():
    # Sun-synchronous: the node turns 360 deg per tropical year (0.9856 deg/day,
    # Vallado, "Sun-synchronous orbits"); at 800 km circular that takes
    # i = 98.6 deg (Wertz, SMAD table). Measured from the orbit's own r x v.
    p = OrbitParams(a=R_EARTH + 800e3, i=math.radians(98.6), j2=True)
    day = 86400.0
    drift = math.degrees(_node(p, day) - _node(p, 0.0))
    assert drift == pytest.approx(360.0 / 365.2422, rel=0.01)
    # and the textbook formula -3/2 n J2 (R/p)^2 cos i, by hand
    n = math.sqrt(MU_EARTH / p.a**3)
    rate = -1.5 * n * 1.08262668e-3 * (R_EARTH / p.a) ** 2 * math.cos(p.i)
    assert math.radians(drift) == pytest.approx(rate * day, rel=1e-9)
    # without J2 the node stays
    assert _node(OrbitParams(a=p.a, i=p.i), day) == pytest.approx(_node(OrbitParams(a=p.a, i=p.i), 0.0), abs=1e-12)


def _rv_to_elements(r, v, mu=MU_EARTH):
    """Classical elements of a state (Vallado, Algorithm 9), written here independently."""
    h = np.cross(r, v)
    nvec = np.cross([0.0, 0.0, 1.0], h)
    rn, vn = np.linalg.norm(r), np.linalg.norm(v)
    evec = ((vn**2 - mu / rn) * r - (r @ v) * v) / mu
    e = np.linalg.norm(evec)
    a = 1.0 / (2.0 / rn - vn**2 / mu)
    i = math.acos(h[2] / np.linalg.norm(h))
    raan = math.atan2(nvec[1], nvec[0])
    argp = math.atan2((np.cross(nvec, evec) @ h) / np.linalg.norm(h), nvec @ evec)
    nu = math.atan2((np.cross(evec, r) @ h) / np.linalg.norm(h), evec @ r)
    return a, e, i, raan, argp, nu


def test_against_sgp4_over_ten_minutes():
    sgp4_api = pytest.importorskip("sgp4.api")
    # the ISS, a published TLE of 2008 (the sgp4 package's own example)
    l1 = "1 25544U 98067A   08264.51782528 -.00002182  00000-0 -11606-4 0  2927"
    l2 = "2 25544  51.6416 247.4627 0006703 130.5360 325.0288 15.72125391563537"
    sat = sgp4_api.Satrec.twoline2rv(l1, l2)
    err, r0, v0 = sat.sgp4_tsince(0.0)
    assert err == 0
    a, e, i, raan, argp, nu = _rv_to_elements(np.array(r0) * 1e3, np.array(v0) * 1e3, mu=sat.mu * 1e9)
    p = OrbitParams(a=a, e=e, i=i, raan=raan, argp=argp, M0=orb.mean_anomaly_from_true(nu, e),
                    jd_epoch=sat.jdsatepoch + sat.jdsatepochF, j2=True, mu=sat.mu * 1e9)
    worst = 0.0
    for minutes in range(0, 11):
        err, r, _ = sgp4_api.Satrec.sgp4_tsince(sat, float(minutes))
        assert err == 0
        ours, _ = orb.orbit_state(p, 60.0 * minutes)
        worst = max(worst, float(np.linalg.norm(ours - np.array(r) * 1e3)))
    # Both start from the same osculating state; SGP4 adds J2's short-period
    # and drag terms our secular-J2 ellipse lacks. Their size: J2 (R/a)^2 a ~ 7 km
    # over an orbit; after ten minutes (a tenth of an orbit) a few km at most.
    assert worst < 5e3  # measured: 2.0 km at ten minutes (0.11 km at one)
    # and the orbits are the same orbit: far closer than after ten minutes of a 10 m/s error (6 km)
    assert worst > 1.0  # not trivially equal: the two models do differ


# --- Earth rotation and the Sun against published values ----------------------------------------


def test_gmst_against_meeus_examples_12a_and_12b():
    # Meeus, Astronomical Algorithms, ex. 12.a: 1987 April 10, 0h UT -> 13h10m46.3668s;
    # ex. 12.b: 19h21m00s UT -> 8h34m57.0896s
    def hms(h, m, s):
        return math.radians(15.0 * (h + m / 60.0 + s / 3600.0))

    assert orb.gmst(2446895.5, 0.0) == pytest.approx(hms(13, 10, 46.3668), abs=1e-8)
    assert orb.gmst(2446895.5, 19 * 3600.0 + 21 * 60.0) == pytest.approx(hms(8, 34, 57.0896), abs=1e-8)
    C = orb.eci_to_ecef(2446895.5, 0.0)
    np.testing.assert_allclose(C @ C.T, np.eye(3), atol=1e-15)


@pytest.mark.parametrize(
    ("when", "lam_deg"),
    [
        # equinoxes and solstices of 2025 (USNO, "Earth's Seasons"): the Sun's
        # apparent ecliptic longitude is 0, 90, 180, 270 deg
        ("2025-03-20T09:01:00Z", 0.0),
        ("2025-06-21T02:42:00Z", 90.0),
        ("2025-09-22T18:19:00Z", 180.0),
        ("2025-12-21T15:03:00Z", 270.0),
    ],
)
def test_sun_direction_at_the_2025_equinoxes_and_solstices(when, lam_deg):
    s = orb.sun_direction_N(julian_date(when))
    eps = math.radians(23.436)  # mean obliquity of 2025
    lam = math.radians(lam_deg)
    ref = np.array([math.cos(lam), math.cos(eps) * math.sin(lam), math.sin(eps) * math.sin(lam)])
    # the almanac's 0.01 deg, plus the minute the published times are rounded to (0.0007 deg)
    assert math.degrees(math.acos(min(1.0, float(s @ ref)))) < 0.012
    assert np.linalg.norm(s) == pytest.approx(1.0, abs=1e-15)


def test_sun_distance_at_perihelion_and_aphelion_2025():
    # USNO: perihelion 2025-01-04 13:28 UTC 0.98333 AU; aphelion 2025-07-03 19:55 UTC 1.01664 AU
    assert orb.sun_distance_au(julian_date("2025-01-04T13:28:00Z")) == pytest.approx(0.98333, abs=2e-4)
    assert orb.sun_distance_au(julian_date("2025-07-03T19:55:00Z")) == pytest.approx(1.01664, abs=2e-4)


@pytest.mark.parametrize("alt_km", [400.0, 1000.0])
def test_eclipse_fraction_of_a_circular_orbit_against_the_closed_form(alt_km):
    jd = julian_date("2026-03-20T00:00:00Z")  # near the equinox: the Sun near the equator
    p = OrbitParams(a=R_EARTH + alt_km * 1e3, i=math.radians(51.6), raan=0.4, jd_epoch=jd)
    T = 2.0 * math.pi / orb.orbit_rates(p).n
    s = orb.sun_direction_N(jd, 0.0)  # held: the Sun moves 0.07 deg in a LEO orbit
    n = 20000
    dark = sum(orb.in_eclipse(orb.orbit_state(p, T * k / n)[0], s) for k in range(n))
    r0, v0 = orb.orbit_state(p, 0.0)
    h = np.cross(r0, v0)
    beta = math.asin(float(s @ h) / np.linalg.norm(h))
    # cylindrical shadow: in shadow while |cos u| cos(beta) > sqrt(1 - (R/a)^2) behind the Earth,
    # fraction = acos(sqrt(1 - (R/a)^2) / cos(beta)) / pi
    ref = math.acos(math.sqrt(1.0 - (R_EARTH / p.a) ** 2) / math.cos(beta)) / math.pi
    assert dark / n == pytest.approx(ref, abs=2.0 / n)


# --- gravity gradient ---------------------------------------------------------------------------


def _dcm(sigma):
    s = np.asarray(sigma, float)
    ss = s @ s
    S = np.array([[0, -s[2], s[1]], [s[2], 0, -s[0]], [-s[1], s[0], 0]])
    return np.eye(3) + (8 * S @ S - 4 * (1 - ss) * S) / (1 + ss) ** 2


def test_gravity_gradient_orbit_against_numpy():
    rng = np.random.default_rng(11)
    for _ in range(100):
        A = rng.normal(size=(3, 3))
        J = A @ A.T + 3.0 * np.eye(3)
        s = rng.normal(size=3) * 0.4
        r = rng.normal(size=3) * 7e6
        r_B = _dcm(s) @ r
        ref = 3.0 * MU_EARTH / np.linalg.norm(r) ** 5 * np.cross(r_B, J @ r_B)
        got = orb.gravity_gradient_orbit(J, s, r)
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * np.linalg.norm(ref) + 1e-25)


def test_gravity_gradient_orbit_equals_the_constant_rate_form_where_nadir_is_e3():
    # a polar circular orbit at the north pole: r_N along e3 of N, w0^2 = mu / a^3
    a = R_EARTH + 500e3
    p = OrbitParams(a=a, i=math.pi / 2, M0=math.pi / 2)
    r, _ = orb.orbit_state(p, 0.0)
    np.testing.assert_allclose(r / np.linalg.norm(r), [0.0, 0.0, 1.0], atol=1e-15)
    w0 = math.sqrt(MU_EARTH / a**3)
    rng = np.random.default_rng(2)
    J = np.diag([10.0, 15.0, 20.0]) + 0.5 * np.ones((3, 3))
    for _ in range(50):
        s = rng.normal(size=3) * 0.4
        ref = _core.gravity_gradient(J, s, w0)
        np.testing.assert_allclose(orb.gravity_gradient_orbit(J, s, r), ref, rtol=0,
                                   atol=1e-12 * np.linalg.norm(ref))
    # a quarter orbit later nadir is along -e1 of N: the constant-rate form, which
    # holds nadir on e3 of N, no longer applies; the orbit's form is that of R3 -> x
    s = np.array([0.1, -0.2, 0.05])
    rq, _ = orb.orbit_state(p, 0.25 * 2 * math.pi / w0)
    C = _dcm(s)
    R1 = C @ (rq / np.linalg.norm(rq))
    np.testing.assert_allclose(orb.gravity_gradient_orbit(J, s, rq), 3 * w0**2 * np.cross(R1, J @ R1),
                               rtol=1e-9, atol=1e-15)
    assert np.linalg.norm(orb.gravity_gradient_orbit(J, s, rq) - _core.gravity_gradient(J, s, w0)) > 1e-7
