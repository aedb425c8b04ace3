"""The scenario's ``[momentum]`` and ``[bdot]`` tables: the controller's
magnetic part, the momentum manager and B-dot detumbling beside the
attitude law (cpp/include/sc_rt/magnetic_control.hpp; docs/MODEL.md section
17, docs/SCENARIOS.md). Without either table (or with ``enabled = false``)
the controller has none, exactly as before.

Both drive the ``[magnetorquers]`` rods (the controller knows them as
given, without their faults) in the field along the ``[orbit]``: they need
both tables. They run offline and on the bus (``controller_config_t``'s
``mag_*`` and ``bdot_*``, docs/PROTOCOL.md). With ``[sensors]`` the
controller gets the field it measures, so a run with ``[sensors]`` needs
``[sensors.magnetometer]`` (docs/MODEL.md section 17); without ``[sensors]``
it gets the true field.

``[bdot] gain = "auto"`` is Markley & Crassidis' rule (after Avanzini &
Giulietti 2012), ``k = 2 n (1 + sin xi_m) J_min`` [N m s]: n the orbit's
mean motion, xi_m its magnetic inclination (``magnetic_inclination``: the
angle between the orbit's normal and the field's dipole axis at the epoch)
and J_min the smallest principal moment of the nominal inertia J0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sc_rt import _core
from sc_rt.model.field import geomag_dipole, igrf14_coefficients, decimal_year
from sc_rt.model.orbit import OrbitParams, gmst
from sc_rt.model.rods import Magnetorquers
from sc_rt.scenario.schema import Spec, Table

__all__ = ["MomentumTable", "BdotTable", "MagneticControl", "read_magnetic_control", "magnetic_inclination",
           "auto_bdot_gain", "KINDS", "DERIVATIVES"]

#: [momentum] kind -> the core's UnloadKind
KINDS = {"cross_product": _core.UnloadKind.CrossProduct, "continuous": _core.UnloadKind.Continuous}
#: [bdot] derivative -> the core's BdotDerivative
DERIVATIVES = {"difference": _core.BdotDerivative.Difference, "analytic": _core.BdotDerivative.Analytic}


@dataclass(frozen=True)
class MomentumTable:
    """``[momentum]``: the momentum manager (cpp/include/sc_rt/momentum.hpp)."""

    kind: str = "cross_product"  # "cross_product" or "continuous"
    gain: float = 0.005  # [1/s] k (c of the continuous form)
    hysteresis: bool = True  # cross_product: on above on_fraction, off below off_fraction
    on_fraction: float = 0.5  # [-] of capacity
    off_fraction: float = 0.1  # [-] of capacity
    capacity: float = 0.0  # [N m s]; 0: min_i Jw_i omega_max_i
    null_gain: float = 0.0  # [1/s] null-space management (0: off)
    null_bias: float = 0.0  # [rad/s] the target speeds' smallest magnitude


@dataclass(frozen=True)
class BdotTable:
    """``[bdot]``: B-dot detumbling as a controller mode (cpp/include/sc_rt/bdot.hpp)."""

    gain: float  # [N m s] (normalized form), "auto" resolved at reading
    gain_auto: bool = True  # the gain came from the rule
    derivative: str = "difference"  # "difference" or "analytic"
    filter_tau: float = 0.0  # [s] low-pass of the difference (0: none)
    rate_on: float = 0.035  # [rad/s] detumble above (2 deg/s)
    rate_off: float = 0.0087  # [rad/s] attitude law below (0.5 deg/s)


@dataclass(frozen=True)
class MagneticControl:
    """The controller's magnetic part of a scenario: either table (None: not enabled)."""

    momentum: MomentumTable | None = None
    bdot: BdotTable | None = None

    def data(self) -> dict:
        """The ``[momentum]`` and ``[bdot]`` tables as parsed TOML that reads back to the same
        values (sc_rt.scenario.keys.scenario_data; ``gain = "auto"`` kept as the rule)."""
        out: dict = {}
        if self.momentum is not None:
            out["momentum"] = {k: getattr(self.momentum, k) for k in MomentumTable.__dataclass_fields__}
        if self.bdot is not None:
            b = self.bdot
            out["bdot"] = {"gain": "auto" if b.gain_auto else b.gain, "derivative": b.derivative,
                           "filter_tau": b.filter_tau, "rate_on": b.rate_on, "rate_off": b.rate_off}
        return out

    def to_core(self, rods: Magnetorquers) -> _core.MagneticConfig:
        """The core's MagneticConfig: the nominal rods of ``rods`` (no faults) and the parts enabled."""
        c = _core.MagneticConfig()
        c.rods_enabled = True
        mp = _core.MagnetorquerParams()
        mp.G_B = np.array(rods.axes)
        mp.dipole_max = np.array(rods.max_dipole)
        c.rods = mp
        if self.momentum is not None:
            m, p = self.momentum, _core.MomentumParams()
            p.kind = KINDS[m.kind]
            for name in ("gain", "hysteresis", "on_fraction", "off_fraction", "capacity", "null_gain", "null_bias"):
                setattr(p, name, getattr(m, name))
            c.momentum_enabled, c.momentum = True, p
        if self.bdot is not None:
            b, p = self.bdot, _core.BdotParams()
            p.gain, p.normalized = b.gain, True
            p.derivative = DERIVATIVES[b.derivative]
            p.filter_tau, p.rate_on, p.rate_off = b.filter_tau, b.rate_on, b.rate_off
            c.bdot_enabled, c.bdot = True, p
        return c


def magnetic_inclination(orbit: OrbitParams) -> float:
    """The orbit's magnetic inclination xi_m [rad] in [0, pi/2]: the angle
    between its normal and the IGRF-14 dipole axis at the epoch (the axis
    rotated from ECEF to ECI by GMST)."""
    _, d = geomag_dipole(igrf14_coefficients(decimal_year(orbit.jd_epoch), 1))
    th = gmst(orbit.jd_epoch, 0.0)
    c, s = math.cos(th), math.sin(th)
    d_N = np.array([c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]])
    si = math.sin(orbit.i)
    n_N = np.array([si * math.sin(orbit.raan), -si * math.cos(orbit.raan), math.cos(orbit.i)])
    return math.acos(min(1.0, abs(float(n_N @ d_N))))


def auto_bdot_gain(orbit: OrbitParams, J0: np.ndarray) -> float:
    """``k = 2 n (1 + sin xi_m) J_min`` [N m s] (``_core.bdot_gain``) for the orbit and the nominal inertia."""
    n = math.sqrt(orbit.mu / orbit.a ** 3)
    return _core.bdot_gain(n, magnetic_inclination(orbit), float(np.linalg.eigvalsh(J0).min()))


def _enabled(t: Table) -> bool | None:
    return t.read("enabled", Spec("bool"), default=True)


def _read_momentum(t: Table, speed_limits: np.ndarray) -> MomentumTable | None | bool:
    on = _enabled(t)
    kind = t.read("kind", Spec("str", choices=tuple(KINDS)), default="cross_product")
    vals = {name: t.read(name, s, default=getattr(MomentumTable, name)) for name, s in (
        ("gain", Spec("number", gt=0)), ("hysteresis", Spec("bool")), ("on_fraction", Spec("number", gt=0, le=1)),
        ("off_fraction", Spec("number", ge=0, le=1)), ("capacity", Spec("number", ge=0)),
        ("null_gain", Spec("number", ge=0)), ("null_bias", Spec("number")))}
    t.finish()
    if on is None or kind is None or None in vals.values():
        return False
    if not vals["off_fraction"] < vals["on_fraction"]:
        t.fail("off_fraction", f"off_fraction must be < on_fraction ({vals['on_fraction']:g})")
        return False
    if vals["capacity"] == 0 and not np.all(np.isfinite(speed_limits) & (speed_limits > 0)):
        t.fail("capacity", "capacity = 0 takes min_i Jw_i omega_max_i, but the wheels have no speed limit: "
                           "give a capacity [N m s]")
        return False
    return MomentumTable(kind=kind, **vals) if on else None


def _read_bdot(t: Table, orbit: OrbitParams | None, J0: np.ndarray) -> BdotTable | None | bool:
    on = _enabled(t)
    t.used.add("gain")
    raw = t.raw("gain") if t.has("gain") else "auto"
    gain, auto = None, raw == "auto"
    if auto:
        gain = auto_bdot_gain(orbit, J0) if orbit is not None else 1.0  # (no orbit: refused by the caller)
    elif isinstance(raw, (int, float)) and not isinstance(raw, bool) and math.isfinite(raw) and raw > 0:
        gain = float(raw)
    else:
        t.fail("gain", 'gain must be a number > 0 [N m s] or "auto" (Markley & Crassidis\' rule)')
    deriv = t.read("derivative", Spec("str", choices=tuple(DERIVATIVES)), default="difference")
    tau = t.read("filter_tau", Spec("number", ge=0), default=0.0)
    rate_on = t.read("rate_on", Spec("number", gt=0), default=BdotTable.rate_on)
    rate_off = t.read("rate_off", Spec("number", ge=0), default=BdotTable.rate_off)
    t.finish()
    if None in (on, gain, deriv, tau, rate_on, rate_off):
        return False
    if not rate_off < rate_on:
        t.fail("rate_off", f"rate_off must be < rate_on ({rate_on:g} rad/s)")
        return False
    return BdotTable(gain=gain, gain_auto=auto, derivative=deriv, filter_tau=float(tau), rate_on=float(rate_on),
                     rate_off=float(rate_off)) if on else None


def read_magnetic_control(root: Table, orbit: OrbitParams | None, rods: Magnetorquers | None, has_sensors: bool,
                          J0: np.ndarray | None, speed_limits: np.ndarray,
                          has_magnetometer: bool = False) -> MagneticControl | None | bool:
    """The scenario's ``[momentum]`` and ``[bdot]`` tables; None when neither
    is given or enabled; False after reporting a problem (a bad value, or a
    table enabled without ``[orbit]`` and ``[magnetorquers]``, or with
    ``[sensors]`` but no ``[sensors.magnetometer]``: the controller uses the
    field it measures). ``speed_limits`` [rad/s]: the wheels' (inf: none)."""
    parts: dict[str, object] = {}
    for name in ("momentum", "bdot"):
        if not root.has(name):
            root.used.add(name)
            continue
        t = root.sub(name)
        if t.data is None:
            return False
        if name == "momentum":
            part = _read_momentum(t, speed_limits)
        else:
            part = _read_bdot(t, orbit if orbit else None, J0 if J0 is not None else np.eye(3))
        if part is False:
            return False
        if part is None:
            continue
        key = "enabled" if t.has("enabled") else next(iter(t.data), "enabled")
        if not orbit or not rods:
            missing = " and ".join(n for n, v in (("[orbit]", orbit), ("[magnetorquers]", rods)) if not v)
            t.fail(key, f"[{name}] drives the magnetorquer rods in the field along the orbit: give {missing}")
            return False
        if has_sensors and not has_magnetometer:
            t.fail(key, f"[{name}] with [sensors] needs a [sensors.magnetometer] table: the controller uses "
                        "the field it measures")
            return False
        parts[name] = part
    return MagneticControl(**parts) if parts else None
