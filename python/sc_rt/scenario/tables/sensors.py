"""The scenario's sensors and estimator: the ``[sensors]`` tables,
``[controller] measurement`` and ``[controller.estimator]`` (docs/SCENARIOS.md,
"Sensors"), read and checked here, and turned into the core's
``_core.NavConfig`` (the models themselves are C++: cpp/include/sc_rt/sensors.hpp,
mekf.hpp).

Units in the file are the data sheets' (deg/sqrt(h), deg/h, arcsec, ppm;
the magnetometer's nT, sc_rt.scenario.tables.magnetometer); :func:`nav_config`
converts to SI.

Rates and the plant step: every sensor samples on the plant's grid, so
1 / (rate_hz * plant_step) must be a whole number of plant steps, and the
star tracker's latency a whole number of plant steps; other values are
refused (ScenarioError naming the key and the nearest valid rates).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sc_rt import _core
from sc_rt.scenario.schema import ScenarioError, ScenarioIssue, Spec, Table, convert, read_only, spec, vector_spec
from sc_rt.scenario.tables.magnetometer import MagnetometerSpec, magnetometer_params

__all__ = ["GyroSpec", "StarTrackerSpec", "TachometerSpec", "EstimatorSpec", "Sensors",
           "MEASUREMENTS", "read_sensors", "nav_config", "period_ticks", "ARCSEC", "DEG_PER_H",
           "DEG_PER_RT_H", "sensors_data"]

ARCSEC = math.pi / 180.0 / 3600.0  #: [rad] one arcsecond
DEG_PER_H = math.pi / 180.0 / 3600.0  #: [rad/s] one deg/h
DEG_PER_RT_H = math.pi / 180.0 / 60.0  #: [rad/sqrt(s)] one deg/sqrt(h)
MEASUREMENTS = ("truth", "estimate")


def _zeros3() -> np.ndarray:
    return read_only(np.zeros(3))


def _zeros6() -> np.ndarray:
    return read_only(np.zeros(6))


#: [sensors.gyro] output -> sc_rt._core's GYRO_RATE / GYRO_MEAN_RATE
GYRO_OUTPUTS = ("rate", "increment")


@dataclass(frozen=True)
class GyroSpec:
    """[sensors.gyro], data-sheet units (docs/SCENARIOS.md)."""

    rate_hz: float = field(default=10.0, metadata=spec("number", gt=0))  # [Hz]
    arw: float = field(default=0.0, metadata=spec("number", ge=0))  # [deg/sqrt(h)]
    bias_sigma: float = field(default=0.0, metadata=spec("number", ge=0))  # [deg/h] Gauss-Markov
    bias_tau: float = field(default=3600.0, metadata=spec("number", gt=0))  # [s]
    rrw: float = field(default=0.0, metadata=spec("number", ge=0))  # [deg/h/sqrt(h)]
    bias0: np.ndarray = field(default_factory=_zeros3, metadata=vector_spec(3, scalar_ok=True))  # [deg/h]
    scale_factor: np.ndarray = field(default_factory=_zeros3, metadata=vector_spec(3, scalar_ok=True))  # [ppm]
    misalignment: np.ndarray = field(default_factory=_zeros3, metadata=vector_spec(3, scalar_ok=True))  # [arcsec]
    quantization: float = field(default=0.0, metadata=spec("number", ge=0))  # [arcsec]
    saturation: float = field(default=math.inf, metadata=spec("number", gt=0, allow_inf=True))  # [deg/s]
    #: "rate": the rate at each sample instant; "increment": an integrating gyro, its delta
    #: angle over the interval since the previous sample as a mean rate, tagged at its end
    output: str = field(default="rate", metadata=spec("str", choices=GYRO_OUTPUTS))


@dataclass(frozen=True)
class StarTrackerSpec:
    """[sensors.star_tracker]."""

    rate_hz: float = field(default=4.0, metadata=spec("number", gt=0))  # [Hz]
    sigma_cross: float = field(default=0.0, metadata=spec("number", ge=0))  # [arcsec] 1 sigma
    sigma_boresight: float = field(default=0.0, metadata=spec("number", ge=0))  # [arcsec]
    boresight: np.ndarray = field(default_factory=lambda: read_only([0.0, 0.0, 1.0]), metadata=vector_spec(3))
    latency: float = field(default=0.0, metadata=spec("number", ge=0))  # [s]
    loss_probability: float = field(default=0.0, metadata=spec("number", ge=0, le=1))  # [-]
    blackouts: tuple[tuple[float, float], ...] = ()  # [s] [start, end) exposure windows


@dataclass(frozen=True)
class TachometerSpec:
    """[sensors.tachometer]."""

    rate_hz: float = field(default=10.0, metadata=spec("number", gt=0))  # [Hz]
    counts_per_rev: float = field(default=0.0, metadata=spec("number", ge=0))  # [-] 0: exact


@dataclass(frozen=True)
class EstimatorSpec:
    """[controller.estimator]: the MEKF's start and degraded mode (its noise
    model is the sensors' configured one)."""

    initial_attitude_sigma: float = field(default=30.0, metadata=spec("number", ge=0))  # [arcsec]
    initial_bias_sigma: float = field(default=1.0, metadata=spec("number", ge=0))  # [deg/h]
    degraded_after: float = field(default=2.0, metadata=spec("number", gt=0))  # [s]
    #: the calibrating filter: 15 states, also the gyro's scale factors and misalignments
    calibrate: bool = field(default=False, metadata=spec("bool"))
    initial_scale_factor_sigma: float = field(default=1000.0, metadata=spec("number", ge=0))  # [ppm]
    initial_misalignment_sigma: float = field(default=200.0, metadata=spec("number", ge=0))  # [arcsec]
    #: the calibrating filter's initial estimate (calibrate): scale factors s1 s2 s3 [ppm]
    initial_scale_factor: np.ndarray = field(default_factory=_zeros3, metadata=vector_spec(3, scalar_ok=True))
    #: and misalignments ku1 ku2 ku3, kl1 kl2 kl3 [arcsec] of S = [[s1 ku1 ku2], [kl1 s2 ku3], [kl2 kl3 s3]]
    initial_misalignment: np.ndarray = field(default_factory=_zeros6, metadata=vector_spec(6, scalar_ok=True))


@dataclass(frozen=True)
class Sensors:
    """The [sensors] tables (None for an absent sensor) and how the law is fed."""

    seed: int = 0
    gyro: GyroSpec | None = None
    star_tracker: StarTrackerSpec | None = None
    tachometer: TachometerSpec | None = None
    measurement: str = "truth"
    magnetometer: MagnetometerSpec | None = None
    estimator: EstimatorSpec = field(default_factory=EstimatorSpec)


def period_ticks(rate_hz: float, plant_step: float) -> tuple[int, str]:
    """(plant steps per sample, "") or (0, why the rate does not fit the grid)."""
    n = 1.0 / (rate_hz * plant_step)
    k = round(n)
    if k >= 1 and abs(n - k) <= 1e-9 * n:
        return k, ""
    lo, hi = max(1, math.floor(n)), max(1, math.ceil(n))
    near = sorted({1.0 / (lo * plant_step), 1.0 / (hi * plant_step)}, reverse=True)
    return 0, (f"1 / rate_hz = {1.0 / rate_hz:g} s is {n:.6g} plant steps of {plant_step:g} s: "
               f"it must be a whole number (nearest valid rates: "
               + " or ".join(f"{r:g} Hz" for r in near) + ")")


def _latency_ticks(latency: float, plant_step: float) -> tuple[int, str]:
    n = latency / plant_step
    k = round(n)
    if abs(n - k) <= 1e-9 * max(n, 1.0):
        return k, ""
    return 0, (f"latency {latency:g} s is {n:.6g} plant steps of {plant_step:g} s: it must be a "
               f"whole number (nearest: {math.floor(n) * plant_step:g} s or {math.ceil(n) * plant_step:g} s)")


def _read_blackouts(t: Table) -> tuple[tuple[float, float], ...] | None:
    t.used.add("blackouts")
    raw = t.raw("blackouts")
    if raw is None:
        return ()
    pair = Spec("vector", shape=(2,))
    if not isinstance(raw, list):
        t.fail("blackouts", "blackouts must be a list of [start, end] pairs [s]")
        return None
    out = []
    for i, w in enumerate(raw):
        v, problem = convert(w, pair)
        key = f"blackouts[{i}]"
        if problem:
            t.doc.error(t.dotted("blackouts"), w, f"{key} {problem}")
            return None
        if not v[1] > v[0]:
            t.doc.error(t.dotted("blackouts"), w, f"{key} must have end > start (got [{v[0]:g}, {v[1]:g}])")
            return None
        out.append((float(v[0]), float(v[1])))
    return tuple(out)


def _read_values_except(t: Table, cls: type, skip: tuple[str, ...]) -> dict[str, Any]:
    values = {}
    for f in dataclasses.fields(cls):
        if f.name in skip:
            continue
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        values[f.name] = t.read(f.name, f.metadata["spec"], default)
    return values


def read_sensors(root: Table, controller: Table, run: Any) -> Sensors | None:
    """The [sensors] tables and [controller] measurement / [controller.estimator];
    None when there is no [sensors] table (then ``measurement`` must be "truth").
    ``run``: the RunParams read (None if it failed: the grid checks are skipped)."""
    measurement = controller.read("measurement", Spec("str", choices=MEASUREMENTS), default="truth")
    est_t = controller.sub("estimator", required=False)
    est_v = _read_values_except(est_t, EstimatorSpec, ())
    for key in ("initial_scale_factor", "initial_misalignment"):  # an initial calibration: the calibrating filter's
        v = est_v.get(key)
        if v is not None and np.any(np.asarray(v) != 0.0) and not est_v.get("calibrate"):
            est_t.fail(key, "an initial calibration estimate needs calibrate = true")
            est_v[key] = None
    est_t.finish()
    if not root.has("sensors"):
        root.used.add("sensors")
        if measurement == "estimate":
            controller.fail("measurement", 'measurement = "estimate" needs an estimator: give a '
                            "[sensors.gyro] table (and a [sensors.star_tracker])")
        if controller.has("estimator"):
            controller.fail("estimator", "[controller.estimator] without a [sensors] table")
        return None
    s = root.sub("sensors")
    seed = s.read("seed", Spec("int", ge=0), default=0)
    step = None if run is None else run.plant_step
    duration = None if run is None else run.duration
    specs: dict[str, Any] = {}
    ok = True
    for name, cls in (("gyro", GyroSpec), ("star_tracker", StarTrackerSpec), ("tachometer", TachometerSpec),
                      ("magnetometer", MagnetometerSpec)):
        if not s.has(name):
            s.used.add(name)
            specs[name] = None
            continue
        t = s.sub(name)
        v = _read_values_except(t, cls, ("blackouts",))
        if cls is StarTrackerSpec:
            v["blackouts"] = _read_blackouts(t)
            if v["boresight"] is not None and not np.linalg.norm(v["boresight"]) > 1e-12:
                t.fail("boresight", "boresight must be a nonzero direction in the body")
                v["boresight"] = None
            if v["latency"] is not None and duration is not None and v["latency"] >= duration:
                t.fail("latency", f"latency must be shorter than the run (run.duration = {duration:g} s)")
                v["latency"] = None
            if v["latency"] is not None and step is not None:
                _, problem = _latency_ticks(v["latency"], step)
                if problem:
                    t.fail("latency", problem)
                    v["latency"] = None
        if v.get("rate_hz") is not None and step is not None:
            _, problem = period_ticks(v["rate_hz"], step)
            if problem:
                t.fail("rate_hz", f"{problem}; the plant step is run.plant_step")
                v["rate_hz"] = None
        t.finish()
        if any(x is None for x in v.values()):
            ok = False
            continue
        specs[name] = cls(**v)
    s.finish()
    if measurement == "estimate" and s.data is not None and not s.has("gyro"):
        controller.fail("measurement", 'measurement = "estimate" needs an estimator, and the '
                        "estimator needs a gyro: give a [sensors.gyro] table")
        ok = False
    g, st = specs.get("gyro"), specs.get("star_tracker")
    if ok and g is not None and st is not None and st.rate_hz > g.rate_hz * (1 + 1e-12):
        s.sub("star_tracker").fail(
            "rate_hz", f"the estimator needs the star tracker no faster than the gyro "
                       f"(sensors.gyro.rate_hz = {g.rate_hz:g})")
        ok = False
    if not ok or seed is None or measurement is None or any(x is None for x in est_v.values()):
        return None
    return Sensors(seed=seed, gyro=g, star_tracker=st, tachometer=specs.get("tachometer"),
                   measurement=measurement, estimator=EstimatorSpec(**est_v), magnetometer=specs.get("magnetometer"))


def nav_config(sensors: Sensors, plant_step: float, where: str = "scenario") -> _core.NavConfig:
    """The core's NavConfig for a plant step [s] (ScenarioError if a rate no
    longer fits the grid, e.g. after a plant_step override)."""
    issues = []

    def ticks(key: str, rate: float) -> int:
        k, problem = period_ticks(rate, plant_step)
        if problem:
            issues.append(ScenarioIssue(0, key, rate, problem))
        return max(k, 1)

    c = _core.NavConfig()
    p = c.sensors
    p.seed = int(sensors.seed)
    p.dt = float(plant_step)
    m = c.mekf
    if (g := sensors.gyro) is not None:
        p.gyro.enabled = True
        p.gyro.period_ticks = ticks("sensors.gyro.rate_hz", g.rate_hz)
        p.gyro.arw = g.arw * DEG_PER_RT_H
        p.gyro.bias_sigma = g.bias_sigma * DEG_PER_H
        p.gyro.bias_tau = g.bias_tau
        p.gyro.rrw = g.rrw * DEG_PER_H / 60.0  # deg/h per sqrt(h) -> rad/s per sqrt(s)
        p.gyro.bias0 = np.asarray(g.bias0) * DEG_PER_H
        p.gyro.scale_factor = np.asarray(g.scale_factor) * 1e-6
        p.gyro.misalignment = np.asarray(g.misalignment) * ARCSEC
        p.gyro.quantization = g.quantization * ARCSEC
        p.gyro.saturation = g.saturation * math.pi / 180.0
        p.gyro.output = GYRO_OUTPUTS.index(g.output)  # 0 GYRO_RATE, 1 GYRO_MEAN_RATE
        m.arw, m.rrw = p.gyro.arw, p.gyro.rrw
        m.bias_sigma, m.bias_tau, m.quantization = p.gyro.bias_sigma, g.bias_tau, p.gyro.quantization
    if (st := sensors.star_tracker) is not None:
        p.star_tracker.enabled = True
        p.star_tracker.period_ticks = ticks("sensors.star_tracker.rate_hz", st.rate_hz)
        p.star_tracker.sigma_cross = st.sigma_cross * ARCSEC
        p.star_tracker.sigma_boresight = st.sigma_boresight * ARCSEC
        p.star_tracker.boresight = np.asarray(st.boresight, float)
        lat, problem = _latency_ticks(st.latency, plant_step)
        if problem:
            issues.append(ScenarioIssue(0, "sensors.star_tracker.latency", st.latency, problem))
        p.star_tracker.latency_ticks = lat
        p.star_tracker.loss_probability = st.loss_probability
        p.star_tracker.blackouts = list(st.blackouts)
        m.sigma_cross, m.sigma_boresight = p.star_tracker.sigma_cross, p.star_tracker.sigma_boresight
        m.boresight = p.star_tracker.boresight
    if (tc := sensors.tachometer) is not None:
        p.tachometer.enabled = True
        p.tachometer.period_ticks = ticks("sensors.tachometer.rate_hz", tc.rate_hz)
        p.tachometer.counts_per_rev = tc.counts_per_rev
        p.tachometer.period = 1.0 / tc.rate_hz
    if (mg := sensors.magnetometer) is not None:
        p.magnetometer = magnetometer_params(mg, ticks("sensors.magnetometer.rate_hz", mg.rate_hz))
    if issues:
        raise ScenarioError(where, issues)
    e = sensors.estimator
    m.initial_attitude_sigma = e.initial_attitude_sigma * ARCSEC
    m.initial_bias_sigma = e.initial_bias_sigma * DEG_PER_H
    m.degraded_after = e.degraded_after
    m.calibrate = bool(e.calibrate)
    m.initial_scale_factor_sigma = e.initial_scale_factor_sigma * 1e-6
    m.initial_misalignment_sigma = e.initial_misalignment_sigma * ARCSEC
    m.initial_calibration = np.concatenate([np.asarray(e.initial_scale_factor, float) * 1e-6,
                                            np.asarray(e.initial_misalignment, float) * ARCSEC])
    g_ticks = p.gyro.period_ticks if p.gyro.enabled else 1
    m.history = int(p.star_tracker.latency_ticks // g_ticks + 3) if p.star_tracker.enabled else 3
    c.use_estimate = sensors.measurement == "estimate"
    return c


def sensors_data(sensors: Sensors) -> tuple[dict[str, Any], dict[str, Any]]:
    """(the [sensors] table, the [controller] keys measurement and estimator) as
    parsed TOML that reads back to ``sensors`` (sc_rt.scenario.keys.scenario_data)."""

    def table(part: Any) -> dict[str, Any]:
        out = {}
        for f in dataclasses.fields(part):
            v = getattr(part, f.name)
            out[f.name] = (v.tolist() if isinstance(v, np.ndarray)
                           else [list(w) for w in v] if f.name == "blackouts" else v)
        return out

    data: dict[str, Any] = {"seed": int(sensors.seed)}
    for name in ("gyro", "star_tracker", "tachometer", "magnetometer"):
        part = getattr(sensors, name)
        if part is not None:
            data[name] = table(part)
    return data, {"measurement": sensors.measurement, "estimator": table(sensors.estimator)}
