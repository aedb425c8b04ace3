"""The parameters of the paper's plant (docs/MODEL.md section 1), validated:
``PlantParams`` (the true inertia J0 + dJ, the wheels' axes and spin inertias,
the orbit rate, the disturbance ``DisturbanceParams``, the orbit, the field,
the residual dipole, the rods) and the plain-float closures its hot path
steps with (``_PlantFast``, built on first use). The dynamics that take them
are sc_rt.model.plant's, and torque_plant.py's for torque-commanded wheels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sc_rt.model.actuators import frozen
from sc_rt.model.field import FIELD_MODELS
from sc_rt.model.kernels import inv3, make_disturbance, make_orbit_gg, make_rhs, make_wheel_map
from sc_rt.model.magnetic import make_field_N
from sc_rt.model.orbit import OrbitParams
from sc_rt.model.rods import Magnetorquers

__all__ = ["DisturbanceParams", "PlantParams"]


@dataclass(frozen=True)
class DisturbanceParams:
    """External torque d(t) = bias + amp * cos(freq * t), per axis [N m].

    The paper's d(t) = 1e-3 [5 cos(0.02 t), -5 cos(0.025 t), 6 cos(0.04 t)].
    """

    amp: np.ndarray = field(default_factory=lambda: np.array([5e-3, -5e-3, 6e-3]))  # [N m]
    freq: np.ndarray = field(default_factory=lambda: np.array([0.02, 0.025, 0.04]))  # [rad/s]
    bias: np.ndarray = field(default_factory=lambda: np.zeros(3))  # [N m]

    def __post_init__(self) -> None:
        errs: list[str] = []
        amp = frozen(self.amp, (3,), "DisturbanceParams.amp", errs)
        freq = frozen(self.freq, (3,), "DisturbanceParams.freq", errs)
        bias = frozen(self.bias, (3,), "DisturbanceParams.bias", errs)
        if errs:
            raise ValueError("invalid DisturbanceParams: " + "; ".join(errs))
        object.__setattr__(self, "amp", amp)
        object.__setattr__(self, "freq", freq)
        object.__setattr__(self, "bias", bias)


@dataclass(frozen=True)
class PlantParams:
    """True plant parameters (SI units).

    Validated on construction (ValueError naming the field and the value):
    ``J0`` and ``J0 + dJ`` symmetric positive definite, ``dJ`` symmetric,
    ``Cbar`` (3, 4) with unit columns (to 1e-2, as the controller's
    ``SpacecraftParams``), ``Jw > 0``, ``w0 >= 0``, everything finite. The
    arrays are stored as read-only float64 copies.
    """

    J0: np.ndarray  # [kg m^2] nominal inertia (what the controller knows)
    dJ: np.ndarray  # [kg m^2] inertia error; the plant uses J = J0 + dJ
    Cbar: np.ndarray  # [-] 3x4 wheel spin axes in B
    Jw: np.ndarray  # [kg m^2] (4,) wheel spin inertias
    w0: float  # [rad/s] orbit rate for gravity gradient (5)
    disturbance: DisturbanceParams = field(default_factory=DisturbanceParams)
    # an orbit: u_g of its actual radius and nadir replaces the w0 form (docs/MODEL.md section 11)
    orbit: OrbitParams | None = None
    # the geomagnetic field along the orbit ([environment] field: "igrf", "dipole", "wmm2025", "none"),
    # through which the residual dipole and the magnetorquers' dipole act (docs/MODEL.md section 16)
    field_model: str = "none"
    # [A m^2] the spacecraft's residual dipole in B, a disturbance m x B
    residual_dipole: np.ndarray = field(default_factory=lambda: np.zeros(3))
    # test-only: False drops the orbit's gravity gradient (u_g then has the w0 form; w0 = 0: none)
    orbit_gravity_gradient: bool = True
    # the magnetorquer rods (sc_rt.model.rods): a step without a dipole input holds
    # their dipole for a zero command (a stuck rod's; none when healthy)
    magnetorquers: Magnetorquers | None = None

    def __post_init__(self) -> None:
        errs: list[str] = []
        J0 = frozen(self.J0, (3, 3), "PlantParams.J0", errs)
        dJ = frozen(self.dJ, (3, 3), "PlantParams.dJ", errs)
        Cbar = frozen(self.Cbar, (3, 4), "PlantParams.Cbar", errs)
        Jw = frozen(self.Jw, (4,), "PlantParams.Jw", errs)
        if J0 is not None:
            _check_spd(J0, "PlantParams.J0", errs)
        if dJ is not None and np.max(np.abs(dJ - dJ.T)) > 1e-9 * max(1.0, np.max(np.abs(dJ))):
            errs.append(f"PlantParams.dJ is not symmetric: {dJ.tolist()!r}")
        if J0 is not None and dJ is not None:
            _check_spd(J0 + dJ, "PlantParams.J0 + dJ (the true inertia J)", errs, symmetric=False)
        if Cbar is not None:
            norms = np.linalg.norm(Cbar, axis=0)
            for i in range(4):
                if abs(norms[i] - 1.0) > 1e-2:
                    errs.append(
                        f"PlantParams.Cbar column {i} is not a unit vector "
                        f"(norm {float(norms[i])!r})"
                    )
        if Jw is not None:
            for i in range(4):
                if not Jw[i] > 0.0:
                    errs.append(f"PlantParams.Jw of wheel {i} must be > 0, got {float(Jw[i])!r}")
        try:
            w0 = float(self.w0)
        except (TypeError, ValueError):
            w0 = math.nan
        if not (math.isfinite(w0) and w0 >= 0.0):
            errs.append(f"PlantParams.w0 must be finite and >= 0, got {self.w0!r}")
        if not isinstance(self.disturbance, DisturbanceParams):
            errs.append(
                f"PlantParams.disturbance must be a DisturbanceParams, got {self.disturbance!r}"
            )
        if self.orbit is not None and not isinstance(self.orbit, OrbitParams):
            errs.append(f"PlantParams.orbit must be an OrbitParams or None, got {self.orbit!r}")
        res = frozen(self.residual_dipole, (3,), "PlantParams.residual_dipole", errs)
        if self.field_model not in FIELD_MODELS:
            errs.append(f"PlantParams.field_model must be one of {sorted(FIELD_MODELS)}, got {self.field_model!r}")
        elif self.field_model != "none" and self.orbit is None:
            errs.append(f"PlantParams.field_model = {self.field_model!r} needs an orbit")
        if self.magnetorquers is not None and not isinstance(self.magnetorquers, Magnetorquers):
            errs.append(f"PlantParams.magnetorquers must be a Magnetorquers or None, got {self.magnetorquers!r}")
        if errs:
            raise ValueError("invalid PlantParams: " + "; ".join(errs))
        object.__setattr__(self, "J0", J0)
        object.__setattr__(self, "dJ", dJ)
        object.__setattr__(self, "Cbar", Cbar)
        object.__setattr__(self, "Jw", Jw)
        object.__setattr__(self, "w0", w0)
        object.__setattr__(self, "residual_dipole", res)
        object.__setattr__(self, "orbit_gravity_gradient", bool(self.orbit_gravity_gradient))
        # the closure cache (_PlantFast) is built on first use (__getattr__) and
        # left out of pickles: closures do not pickle, and a Scenario must
        # travel to Monte Carlo workers

    def __getattr__(self, name: str):
        # called only for attributes not found normally: after the first use
        # _fast sits in __dict__ and the hot path reads it without this call
        if name == "_fast":
            fast = _PlantFast(self)
            object.__setattr__(self, "_fast", fast)
            return fast
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __getstate__(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if k != "_fast"}

    @property
    def J(self) -> np.ndarray:
        """True inertia J0 + dJ [kg m^2]."""
        return self.J0 + self.dJ


def _check_spd(M: np.ndarray, name: str, errs: list[str], symmetric: bool = True) -> None:
    if symmetric and np.max(np.abs(M - M.T)) > 1e-9 * np.max(np.abs(M)):
        errs.append(f"{name} is not symmetric: {M.tolist()!r}")
        return
    ev = np.linalg.eigvalsh(0.5 * (M + M.T))
    if not ev.min() > 0.0:
        errs.append(
            f"{name} is not positive definite (eigenvalues {ev.tolist()!r}): {M.tolist()!r}"
        )


class _PlantFast:
    """Closures over plain-float copies of PlantParams for the hot path."""

    __slots__ = ("f", "f0", "wheel", "dist", "gg", "field", "res")

    def __init__(self, p: PlantParams):
        CJ = p.Cbar * p.Jw
        k = 3.0 * p.w0 * p.w0
        self.f = make_rhs(p.J, inv3(p.J), k)  # the true plant
        self.f0 = make_rhs(p.J0, inv3(p.J0), k)  # the controller's model (21)
        self.wheel = make_wheel_map(CJ)
        self.dist = make_disturbance(p.disturbance)
        self.gg = make_orbit_gg(p.orbit if p.orbit_gravity_gradient else None)
        self.field = make_field_N(p.orbit, p.field_model)  # B_N(t) [T], None: no field
        self.res = tuple(p.residual_dipole.tolist())  # [A m^2]
