"""Scenarios with magnetic control for the tests (tests/test_mag_control.py,
test_mag_detumble.py, test_mag_scenario.py): flight_wheels on an orbit in
IGRF with three rods, a secular torque and nothing periodic; and the tests'
independent field along an orbit, ppigrf's IGRF-14 (``ppigrf_field_N``)."""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import numpy as np

from sc_rt.scenario.reader import scenario_from_data
from sc_rt.scenario.shipped import resolve

__all__ = ["MAG", "STUCK", "BIAS", "MOMENTUM", "H0", "mag_data", "mag_scenario", "detumble_switch"]

#: an orbit, IGRF, three orthogonal 30 A m^2 rods (the third stuck at 5 A m^2 from 20 s) on the flight-like
#: wheels of flight_wheels, a secular body torque of 1e-4 N m and nothing periodic
MAG = """
[orbit]
altitude = 500e3
inclination = 51.6
raan = 40.0
epoch = 2026-03-20T00:00:00Z

[environment]
field = "igrf"

[magnetorquers]
axes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
max_dipole = 30.0
"""

STUCK = """
[[magnetorquers.faults]]
rod = 3
kind = "stuck"
dipole = 5.0
onset = 20.0
"""

#: [N m] the secular torque: |bias| = 1e-4 N m
BIAS = [5.773502691896258e-05, -5.773502691896258e-05, 5.773502691896258e-05]


def mag_data(extra: str, *, duration: float, wheel_speed=(0.0, 0.0, 0.0, 0.0), omega=(0.0, 0.0, 0.0),
             sigma=None, paper_wheels: bool = False) -> dict:
    """flight_wheels with MAG and ``extra`` as TOML data: the hold at its sigma_d0, starting on it."""
    data = tomllib.loads(Path(resolve("flight_wheels")).read_text() + MAG + extra)
    data.pop("requirements", None)
    data["run"]["duration"] = duration
    data["disturbance"] = {"amp": [0.0, 0.0, 0.0], "freq": [0.0, 0.0, 0.0], "bias": BIAS}
    data["initial"] = {"sigma_BN": list(sigma or data["guidance"]["sigma_d0"]), "omega_BN_B": list(omega),
                       "wheel_speed": list(wheel_speed)}
    if paper_wheels:
        del data["wheels"]
        data["spacecraft"].update(umin=-7.0, umax=10.0, Jw=0.338)
        data["disturbance"]["bias"] = [0.0, 0.0, 0.0]
    return data


def mag_scenario(extra: str, *, duration: float, gravity_gradient: bool = True, **kw):
    """The Scenario of ``mag_data`` (``gravity_gradient`` False: the plant without any, the
    orbit's nor the constant-rate form's, w0 = 0)."""
    data = mag_data(extra, duration=duration, **kw)
    if not gravity_gradient:
        data["spacecraft"]["w0"] = 0.0
    scn = scenario_from_data(data, "mag.toml")
    if not gravity_gradient:  # test-only switch of the plant (PlantParams.orbit_gravity_gradient)
        scn = dataclasses.replace(scn, plant=dataclasses.replace(scn.plant, orbit_gravity_gradient=False))
    return scn


MOMENTUM = """
[momentum]
kind = "cross_product"
gain = 0.01
capacity = 1.0
on_fraction = 0.5
off_fraction = 0.1
null_gain = 0.01
null_bias = 5.0
"""


#: [rad/s] / 10: wheel speeds whose momentum fills MOMENTUM's capacity beyond on_fraction
H0 = (-3.0, 6.0, 5.0, 4.0)


def ppigrf_field_N(orbit, jd_epoch: float, times, when) -> np.ndarray:
    """[T] the tests' independent field: IGRF-14 by the ``ppigrf`` package
    (its coefficients at ``when``) at ``orbit``'s positions, rotated from
    ECEF to ECI (N) with sc-rt's Earth rotation from ``jd_epoch``; (n, 3)."""
    import ppigrf

    from sc_rt.model.orbit import eci_to_ecef, orbit_state

    r_N = np.array([orbit_state(orbit, t)[0] for t in times])
    C = [eci_to_ecef(jd_epoch, t) for t in times]
    r_E = np.array([c @ r for c, r in zip(C, r_N)])
    r = np.linalg.norm(r_E, axis=1)
    th, ph = np.arccos(r_E[:, 2] / r), np.arctan2(r_E[:, 1], r_E[:, 0])
    Br, Bt, Bp = (np.ravel(v) for v in ppigrf.igrf_gc(r / 1e3, np.degrees(th), np.degrees(ph), when))
    rh = np.c_[np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)]
    thh = np.c_[np.cos(th) * np.cos(ph), np.cos(th) * np.sin(ph), -np.sin(th)]
    phh = np.c_[-np.sin(ph), np.cos(ph), np.zeros_like(ph)]
    B_E = Br[:, None] * rh + Bt[:, None] * thh + Bp[:, None] * phh  # [nT]
    return np.array([c.T @ b for c, b in zip(C, B_E)]) * 1e-9


def detumble_switch(run) -> int:
    """The row of a record's one switch from B-dot to the attitude law:
    ``detumble_mode`` 0 (detumble) from the start, 1 (attitude) from that row
    on, which carries FLAG_MODE_SWITCH (fields.hpp)."""
    from sc_rt import _core

    mode = np.asarray(run["detumble_mode"])
    k = int(np.argmax(mode == 1))
    assert mode[0] == 0 and k > 0 and np.all(mode[:k] == 0) and np.all(mode[k:] == 1), mode
    assert run["flags"][k] & _core.FLAG_MODE_SWITCH
    return k
