"""The scenario's ``[sensors.magnetometer]`` table (docs/SCENARIOS.md,
"Sensors"): a three-axis magnetometer in the sensor model beside the gyro,
star tracker and tachometers (the core's ``Magnetometer``,
cpp/include/sc_rt/sensors.hpp; docs/MODEL.md section 13), read here and
turned into the core's ``_core.MagnetometerParams``.

Units in the file are the data sheets' (nT, ppm, arcsec); :func:`magnetometer_params`
converts to SI (tesla, rad). The model, in the sensor frame S:

    B_m = q(sat(M R_SB B_B + bias + n)),   M = (I + diag(scale_factor)) (I - misalignment^)

``R_SB`` is the mounting, the MRP ``mounting`` = sigma_SB (body to sensor);
the controller knows only the mounting (it rotates the sample back to B),
not the bias, scale factors or misalignment.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sc_rt import _core
from sc_rt.model.kernels import mrp_to_dcm
from sc_rt.scenario.schema import read_only, spec, vector_spec

__all__ = ["MagnetometerSpec", "NT", "magnetometer_params"]

NT = 1e-9  #: [T] one nanotesla
_ARCSEC = math.pi / 180.0 / 3600.0  # [rad]


def _zeros3() -> np.ndarray:
    return read_only(np.zeros(3))


@dataclass(frozen=True)
class MagnetometerSpec:
    """[sensors.magnetometer], data-sheet units (docs/SCENARIOS.md)."""

    rate_hz: float = field(default=10.0, metadata=spec("number", gt=0))  # [Hz]
    noise: float = field(default=0.0, metadata=spec("number", ge=0))  # [nT] 1 sigma per axis, white
    bias: np.ndarray = field(default_factory=_zeros3, metadata=vector_spec(3, scalar_ok=True))  # [nT] sensor frame
    scale_factor: np.ndarray = field(default_factory=_zeros3, metadata=vector_spec(3, scalar_ok=True))  # [ppm]
    misalignment: np.ndarray = field(default_factory=_zeros3, metadata=vector_spec(3, scalar_ok=True))  # [arcsec]
    #: the mounting: MRP sigma_SB of the sensor frame S relative to the body B (R_SB = C(sigma_SB))
    mounting: np.ndarray = field(default_factory=_zeros3, metadata=vector_spec(3, mrp=True))  # [-]
    lsb: float = field(default=0.0, metadata=spec("number", ge=0))  # [nT] quantum, 0: none
    range: float = field(default=math.inf, metadata=spec("number", gt=0, allow_inf=True))  # [nT] per axis


def magnetometer_params(m: MagnetometerSpec, period_ticks: int) -> _core.MagnetometerParams:
    """The core's MagnetometerParams (SI) of ``m``, sampling every ``period_ticks`` plant steps."""
    p = _core.MagnetometerParams()
    p.enabled = True
    p.period_ticks = int(period_ticks)
    p.noise = m.noise * NT
    p.bias = np.asarray(m.bias, float) * NT
    s = np.asarray(m.scale_factor, float) * 1e-6
    a = np.asarray(m.misalignment, float) * _ARCSEC
    skew = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    p.M = (np.eye(3) + np.diag(s)) @ (np.eye(3) - skew)  # the gyro's form (docs/MODEL.md section 10)
    p.R_SB = mrp_to_dcm(np.asarray(m.mounting, float))
    p.lsb = m.lsb * NT
    p.range = m.range * NT
    return p
