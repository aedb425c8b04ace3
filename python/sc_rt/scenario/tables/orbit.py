"""The scenario's ``[orbit]`` table: a Keplerian orbit and its epoch
(sc_rt.model.orbit.OrbitParams; docs/SCENARIOS.md, docs/MODEL.md section 11).
Without the table the plant keeps the constant-rate gravity gradient of
``spacecraft.w0``, exactly as before.

The ``[environment]`` table names the geomagnetic field model evaluated
along the orbit (``field = "igrf" | "dipole" | "wmm2025" | "none"``,
sc_rt.model.field; the orbit's epoch must be in the model's window,
``FIELD_WINDOWS``)
and the spacecraft's residual dipole (``residual_dipole = [x, y, z]`` in
A m^2, body frame), whose torque m x B the plant adds
(sc_rt.model.magnetic; docs/MODEL.md section 16).

Angles are given in degrees, lengths in metres; the epoch as a TOML
date-time (``epoch = 2026-01-01T00:00:00Z``), an ISO string, or a Julian
date (``jd_epoch``).
"""

from __future__ import annotations

import datetime as dt
import math

from sc_rt.model.field import FIELD_MODELS, FIELD_WINDOWS, decimal_year
from sc_rt.model.orbit import R_EARTH, OrbitParams, mean_anomaly_from_true
from sc_rt.scenario.schema import Spec, Table

__all__ = ["DEFAULT_EPOCH", "julian_date", "read_orbit", "read_environment"]

DEFAULT_EPOCH = "2026-01-01T00:00:00Z"  # the default epoch (UTC)
_JD_UNIX = 2440587.5  # [day] Julian date of 1970-01-01 00:00 UTC
_DEG = math.pi / 180.0
_ANGLE = Spec("number")


def julian_date(when: dt.datetime | dt.date | str) -> float:
    """UTC Julian date [day] of a date-time (naive: UTC) or an ISO 8601 string.

    >>> julian_date("2000-01-01T12:00:00Z")
    2451545.0
    """
    if isinstance(when, str):
        when = dt.datetime.fromisoformat(when.replace("Z", "+00:00"))
    if not isinstance(when, dt.datetime):  # a bare date: its midnight
        when = dt.datetime(when.year, when.month, when.day)
    if when.tzinfo is None:
        when = when.replace(tzinfo=dt.timezone.utc)
    delta = when - dt.datetime(1970, 1, 1, tzinfo=dt.timezone.utc)
    return _JD_UNIX + delta.days + (delta.seconds + delta.microseconds * 1e-6) / 86400.0


def _read_epoch(t: Table) -> float | None:
    if t.has("epoch") and t.has("jd_epoch"):
        t.fail("jd_epoch", "give the epoch once: epoch or jd_epoch, not both")
        return None
    if t.has("jd_epoch"):
        return t.read("jd_epoch", Spec("number", gt=2415020.5, le=2488069.5))
    t.used.add("epoch")
    raw = t.raw("epoch") if t.has("epoch") else DEFAULT_EPOCH
    if isinstance(raw, (dt.datetime, dt.date)) or isinstance(raw, str):
        try:
            jd = julian_date(raw)
        except ValueError:
            jd = None
        if jd is not None and 2415020.5 < jd < 2488069.5:
            return jd
    t.fail("epoch", "epoch must be a UTC date-time in 1900-2100 (2026-01-01T00:00:00Z or its ISO string)")
    return None


def read_orbit(root: Table) -> OrbitParams | None | bool:
    """The OrbitParams of the scenario's ``[orbit]`` table; None when it has
    none; False after reporting a problem."""
    if not root.has("orbit"):
        root.used.add("orbit")
        return None
    t = root.sub("orbit")
    if t.data is None:
        return False
    if t.has("a") and t.has("altitude"):
        t.fail("a", "give the orbit's size once: a or altitude, not both")
        t.used.update(("a", "altitude"))
        t.finish()
        return False
    if t.has("a"):
        a = t.read("a", Spec("number", gt=0))
    else:
        alt = t.read("altitude", Spec("number", gt=0), default=400e3)
        a = None if alt is None else R_EARTH + alt
    e = t.read("e", Spec("number", ge=0, le=0.98), default=0.0)
    inc = t.read("inclination", _ANGLE, default=0.0)
    raan = t.read("raan", _ANGLE, default=0.0)
    argp = t.read("argp", _ANGLE, default=0.0)
    if t.has("true_anomaly") and t.has("mean_anomaly"):
        t.fail("mean_anomaly", "give the anomaly once: true_anomaly or mean_anomaly, not both")
        anomaly = None
    elif t.has("true_anomaly"):
        anomaly = t.read("true_anomaly", _ANGLE)
    else:
        anomaly = t.read("mean_anomaly", _ANGLE, default=0.0)
    jd = _read_epoch(t)
    j2 = t.read("j2", Spec("bool"), default=False)
    t.finish()
    if None in (a, e, inc, raan, argp, anomaly, jd, j2):
        return False
    M0 = anomaly * _DEG
    if t.has("true_anomaly"):
        M0 = mean_anomaly_from_true(M0, e)
    try:
        return OrbitParams(a=a, e=e, i=inc * _DEG, raan=raan * _DEG, argp=argp * _DEG, M0=M0,
                           jd_epoch=jd, j2=bool(j2))
    except ValueError as err:
        key = "altitude" if t.has("altitude") else "a"
        t.fail(key, str(err).replace("invalid OrbitParams: OrbitParams", "the orbit"))
        return False


def read_environment(root: Table, orbit: OrbitParams | None | bool) -> tuple[str, tuple] | None:
    """The ``[environment]`` table's field model and residual dipole [A m^2]
    (``("none", (0, 0, 0))`` without the table); None after reporting a
    problem. ``orbit`` is ``read_orbit``'s answer (None: no ``[orbit]``;
    False: refused, reported). A field other than "none" needs ``[orbit]``,
    whose epoch must be in the model's window (``FIELD_WINDOWS``: IGRF-14
    1900-2030, WMM2025 2025-2030); a nonzero residual dipole needs a field."""
    has_orbit = orbit is not None
    t = root.sub("environment", required=False)
    if t.data is None:
        return None
    model = t.read("field", Spec("str", choices=tuple(FIELD_MODELS)), default="none")
    res = t.read("residual_dipole", Spec("vector", shape=(3,)), default=[0.0, 0.0, 0.0])
    t.finish()
    if model is None or res is None:
        return None
    if model != "none" and not has_orbit:
        t.fail("field", f'field = "{model}" is evaluated along the orbit: give an [orbit] table too')
        return None
    if model != "none" and isinstance(orbit, OrbitParams):
        first, last = FIELD_WINDOWS[model]
        year = decimal_year(orbit.jd_epoch)
        if not (first <= year <= last):
            t.fail("field", f'"{model}" is valid for epochs {first:.1f}-{last:.1f}; the orbit\'s epoch is '
                            f"{year:.2f}: give an [orbit] epoch within it or another field")
            return None
    res = tuple(float(v) for v in res)
    if model == "none" and any(res):
        t.fail("residual_dipole",
               'a residual dipole acts through the field: give field = "igrf", "dipole" or "wmm2025"')
        return None
    return model, res
