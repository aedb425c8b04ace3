"""The geomagnetic field (sc_rt.model.field, cpp/src/geomag.cpp): the
coefficient tables against the file the ppigrf package ships and against
IAGA's published IGRF-14 values, the field against ppigrf's own evaluator
along an orbit and on a grid (<= 1 nT), the evaluator fed WMM2020's
coefficients against NOAA's published WMM2020 test values (0.06 nT), the
dipole against its closed form, and the C++ twin bit for bit."""

from __future__ import annotations

import datetime as dt
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.model import field as fld
from sc_rt.model.field import GeomagField, decimal_year, field_for, geomag_dipole, igrf14_coefficients
from sc_rt.model.igrf14_table import ROWS, YEARS
from sc_rt.model.orbit import OrbitParams, R_EARTH, eci_to_ecef, orbit_state
from sc_rt.scenario.tables.orbit import julian_date

ROOT = Path(__file__).resolve().parent.parent

# IGRF-14 as IAGA Working Group V-MOD published it (igrf14coeffs.txt; Alken et al.
# 2025): (year, n, m, g or h) [nT]; m < 0 for h. 2030.0 = 2025.0 + 5 SV, with the
# 2025-2030 SV of g10, g11, h11 = 12.6, 10.0, -21.5 nT/yr.
OFFICIAL = [
    (2025.0, 1, 0, -29350.0), (2025.0, 1, 1, -1410.3), (2025.0, 1, -1, 4545.5),
    (2025.0, 2, 0, -2556.2), (2025.0, 2, 1, 2950.9), (2025.0, 2, -1, -3133.6), (2025.0, 2, 2, 1648.7),
    (2030.0, 1, 0, -29350.0 + 5 * 12.6), (2030.0, 1, 1, -1410.3 + 5 * 10.0), (2030.0, 1, -1, 4545.5 - 5 * 21.5),
    (2020.0, 1, 0, -29403.41), (2020.0, 1, 1, -1451.37), (2020.0, 1, -1, 4653.35),
    (2000.0, 1, 0, -29619.4), (2000.0, 1, 1, -1728.2), (2000.0, 1, -1, 5186.1),
    (1900.0, 1, 0, -31543.0), (1900.0, 1, 1, -2298.0), (1900.0, 1, -1, 5922.0),
]


def _table(year, n, m):
    row = next(vals for nn, mm, vals in ROWS if (nn, mm) == (n, m))
    return row[YEARS.index(year)]


@pytest.mark.parametrize(("year", "n", "m", "value"), OFFICIAL)
def test_table_holds_iagas_published_coefficients(year, n, m, value):
    assert _table(year, n, m) == pytest.approx(value, abs=1e-9)


def test_the_2020_dipole_is_igrf14s_definitive_one_not_igrf13s_forecast():
    # IGRF-13's 2020.0 (a forecast, replaced by IGRF-14's definitive DGRF 2020):
    # g10, g11, h11 = -29404.8, -1450.9, 4652.5: the constants a peer calls "2020 IGRF"
    c = igrf14_coefficients(2020.0, nmax=1)
    got = (c.g[1][0], c.g[1][1], c.h[1][1])
    assert got == (-29403.41, -1451.37, 4653.35)
    assert max(abs(a - b) for a, b in zip(got, (-29404.8, -1450.9, 4652.5))) > 0.4
    B0, m = geomag_dipole(c)
    assert B0 == pytest.approx(math.sqrt(29403.41**2 + 1451.37**2 + 4653.35**2), rel=1e-15)
    np.testing.assert_allclose(m * B0, [-1451.37, 4653.35, -29403.41], rtol=1e-15)
    B0c, mc = _core.geomag_dipole(_core.igrf14_coefficients(2020.0, 1))
    assert B0c == B0 and np.array_equal(mc, m)


def test_generated_tables_are_what_the_generator_makes_of_the_package_file():
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "gen_igrf14.py"), "--check"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_table_equals_the_package_file_read_by_the_package():
    ppigrf = pytest.importorskip("ppigrf")
    g, h = ppigrf.ppigrf.read_shc(ppigrf.ppigrf.shc_fn_igrf14)
    assert [t.year for t in g.index] == [int(y) for y in YEARS]
    for n, m, vals in ROWS:
        col = g[(n, m)] if m >= 0 else h[(n, -m)]
        assert np.array_equal(col.to_numpy(dtype=float), np.array(vals)), (n, m)


def _sph(r_E):
    x, y, z = r_E
    return np.linalg.norm(r_E), math.degrees(math.atan2(math.hypot(x, y), z)), math.degrees(math.atan2(y, x))


def _vs_ppigrf(f, points, when):
    """max |B_ours - B_ppigrf| [nT] over ECEF positions on a date (ppigrf called once)."""
    ppigrf = pytest.importorskip("ppigrf")
    sph = np.array([_sph(r_E) for r_E in points])
    Br, Bt, Bp = (np.ravel(v) for v in ppigrf.igrf_gc(sph[:, 0] / 1e3, sph[:, 1], sph[:, 2], when))
    worst = 0.0
    for k, r_E in enumerate(points):
        t, p = math.radians(sph[k, 1]), math.radians(sph[k, 2])
        rh = np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])
        thh = np.array([math.cos(t) * math.cos(p), math.cos(t) * math.sin(p), -math.sin(t)])
        phh = np.array([-math.sin(p), math.cos(p), 0.0])
        ref = Br[k] * rh + Bt[k] * thh + Bp[k] * phh
        worst = max(worst, float(np.linalg.norm(f.B_ecef(r_E) - ref)))
    return worst


def test_field_along_an_orbit_against_ppigrf_within_one_nt():
    when = dt.datetime(2026, 6, 1)
    jd = julian_date(when)
    f = field_for("igrf", jd)
    o = OrbitParams(a=R_EARTH + 500e3, e=0.002, i=math.radians(97.4), raan=2.0, jd_epoch=jd, j2=True)
    # an orbit, with the date's coefficients (their SV over it: 1e-3 nT)
    points = [eci_to_ecef(jd, t) @ orbit_state(o, t)[0] for t in np.linspace(0.0, 6000.0, 61)]
    worst = _vs_ppigrf(f, points, when)
    # the residual: ppigrf interpolates by calendar time, we by Julian years (< 0.1 nT)
    assert worst < 1.0


@pytest.mark.parametrize("year", [2000, 2020, 2025, 2029])
def test_field_on_a_grid_against_ppigrf_within_one_nt(year):
    when = dt.datetime(year, 7, 2)
    f = GeomagField(igrf14_coefficients(decimal_year(julian_date(when))))
    points = []
    for alt in (0.0, 800e3):
        for lat in (-89.0, -45.0, 0.0, 33.0, 80.0):
            for lon in (-170.0, -60.0, 10.0, 135.0):
                la, lo, r = math.radians(lat), math.radians(lon), 6371.2e3 + alt
                points.append(r * np.array([math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)]))
    assert _vs_ppigrf(f, points, when) < 1.0


def test_dipole_is_the_closed_form_of_a_centred_dipole():
    c = igrf14_coefficients(2025.0, nmax=1)
    f = GeomagField(c)
    M = np.array([c.g[1][1], c.h[1][1], c.g[1][0]])  # [nT]
    rng = np.random.default_rng(4)
    for _ in range(50):
        r_E = rng.normal(size=3) * 7e6
        rn = np.linalg.norm(r_E)
        rh = r_E / rn
        ref = (6371.2e3 / rn) ** 3 * (3.0 * (M @ rh) * rh - M)  # B = (a/r)^3 (3 (M.r) r - M)
        np.testing.assert_allclose(f.B_ecef(r_E), ref, rtol=0, atol=1e-9 * np.linalg.norm(ref))
        # NED is ECEF in the local geocentric axes
        ned = f.B_ned(r_E)
        assert np.linalg.norm(ned) == pytest.approx(np.linalg.norm(ref), rel=1e-12)
        assert ned[2] == pytest.approx(-(ref @ rh), rel=1e-9, abs=1e-9)


def test_eci_field_is_the_ecef_field_rotated():
    jd = julian_date("2026-02-01T06:00:00Z")
    f = field_for("igrf", jd)
    r_N = np.array([3e6, -5e6, 4e6])
    C = eci_to_ecef(jd, 100.0)
    np.testing.assert_allclose(f.B_eci(r_N, jd, 100.0), C.T @ f.B_ecef(C @ r_N), rtol=0, atol=1e-9)


def test_python_and_cpp_field_bit_identical():
    rng = np.random.default_rng(9)
    for year, nmax in ((2026.3, 13), (2021.9, 13), (2025.0, 1), (1987.6, 10)):
        c_py, c_c = igrf14_coefficients(year, nmax), _core.igrf14_coefficients(year, nmax)
        assert np.array_equal(np.array(c_py.g), np.array(c_c.g)) and np.array_equal(np.array(c_py.h), np.array(c_c.h))
        f_py, f_c = GeomagField(c_py), _core.GeomagField(c_c)
        for _ in range(40):
            r = rng.normal(size=3) * 7e6
            jd, t = 2461000.0 + rng.uniform(0, 900), float(rng.uniform(0, 86400))
            assert np.array_equal(f_py.B_ecef(r), f_c.B_ecef(r))
            assert np.array_equal(f_py.B_ned(r), f_c.B_ned(r))
            assert np.array_equal(f_py.B_eci(r, jd, t), f_c.B_eci(r, jd, t))
        for r_E in ((0.0, 0.0, 7e6), (1e-4, 0.0, -7e6)):  # on the polar axis: 1 mm off it
            assert np.array_equal(f_py.B_ecef(r_E), f_c.B_ecef(np.array(r_E)))
            assert np.all(np.isfinite(f_py.B_ecef(r_E)))
    assert decimal_year(2461041.5) == _core.decimal_year(2461041.5)
    assert fld.GEOMAG_RADIUS == _core.GEOMAG_RADIUS


def test_bad_dates_and_degrees_are_refused_naming_the_value():
    with pytest.raises(ValueError, match="year must be in"):
        igrf14_coefficients(2031.0)
    with pytest.raises(ValueError, match="got 2031"):
        _core.igrf14_coefficients(2031.0)
    with pytest.raises(ValueError, match="nmax must be in"):
        _core.igrf14_coefficients(2025.0, 14)
    with pytest.raises(ValueError, match="field must be one of"):
        field_for("wmm", 2461041.5)
    assert field_for("none", 2461041.5) is None


# WMM2020's official test values (NOAA NCEI, README of WMM2020COF: "a set of test
# values ... Here are a few"): (decimal year, height above WGS-84 [km], geodetic
# lat, lon [deg], X, Y, Z [nT], rounded to 0.1 nT)
WMM2020_TEST_VALUES = [
    (2020.0, 66.0, 14.0, 143.0, 34916.8, 70.2, 8114.9),
    (2020.0, 18.0, 0.0, 21.0, 29311.2, 536.0, -14589.0),
    (2020.5, 6.0, -36.0, -137.0, 23948.6, 8791.9, -32897.6),
    (2020.5, 63.0, 26.0, 81.0, 34737.7, 259.2, 30023.4),
]


def _wmm_coefficients(year: float, path: Path) -> fld.GeomagCoeffs:
    """A WMM .COF file's coefficients at ``year``: g + gdot (year - epoch) (the WMM report's eq. (9))."""
    lines = path.read_text().splitlines()
    epoch = float(lines[0].split()[0])
    g = [[0.0] * 14 for _ in range(14)]
    h = [[0.0] * 14 for _ in range(14)]
    for ln in lines[1:]:
        f = ln.split()
        if len(f) != 6:
            break  # the closing line of 9s
        n, m = int(f[0]), int(f[1])
        gv, hv, gd, hd = (float(v) for v in f[2:])
        g[n][m] = gv + gd * (year - epoch)
        h[n][m] = hv + hd * (year - epoch)
    return fld.GeomagCoeffs(tuple(map(tuple, g)), tuple(map(tuple, h)), 12)


@pytest.mark.parametrize(("year", "hae_km", "lat", "lon", "X", "Y", "Z"), WMM2020_TEST_VALUES)
def test_the_evaluator_reproduces_wmm2020s_official_test_values(year, hae_km, lat, lon, X, Y, Z):
    # the evaluator is the model's: fed WMM2020's coefficients (as pygeomag ships
    # WMM.COF) it must give NOAA's published values, in the geodetic frame
    pygeomag = pytest.importorskip("pygeomag")
    cof = Path(pygeomag.__file__).parent / "wmm" / "WMM_2020.COF"
    f = GeomagField(_wmm_coefficients(year, cof))
    a, e2 = 6378137.0, 6.69437999014e-3  # WGS-84
    la, lo, hgt = math.radians(lat), math.radians(lon), hae_km * 1e3
    Nr = a / math.sqrt(1.0 - e2 * math.sin(la) ** 2)
    r_E = np.array([(Nr + hgt) * math.cos(la) * math.cos(lo), (Nr + hgt) * math.cos(la) * math.sin(lo),
                    (Nr * (1.0 - e2) + hgt) * math.sin(la)])
    B = f.B_ecef(r_E)
    north = np.array([-math.sin(la) * math.cos(lo), -math.sin(la) * math.sin(lo), math.cos(la)])
    east = np.array([-math.sin(lo), math.cos(lo), 0.0])
    down = -np.array([math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)])
    np.testing.assert_allclose([B @ north, B @ east, B @ down], [X, Y, Z], rtol=0, atol=0.06)
