"""The scenario's ``[wheels]`` table: flight-like torque-commanded wheels
(sc_rt.model.wheels.TorqueWheels; docs/SCENARIOS.md, docs/MODEL.md
"Flight-like wheels"). Without the table the plant has the paper's
acceleration-commanded wheels, exactly as before.

A ``preset`` fills the values from a datasheet; any key given beside it
overrides the preset's value. Every per-wheel value is a number (the same
for the four wheels) or a list of 4.
"""

from __future__ import annotations

import math

import numpy as np

from sc_rt.model.wheels import COMMANDS, TorqueWheels, WheelFriction, WheelLimits
from sc_rt.scenario.schema import Spec, Table

__all__ = ["PRESETS", "LIMIT_KEYS", "FRICTION_KEYS", "read_wheels", "check_wheel_fault"]

_RPM = 2.0 * math.pi / 60.0

#: Datasheet presets. Each value's source is in the comment beside it.
PRESETS: dict[str, dict[str, float]] = {
    # Honeywell HR16 (Constellation series): the values Basilisk's
    # simIncludeRW.Honeywell_HR16 quotes from Honeywell's datasheet. Its
    # spin inertia follows from the momentum option: Jw = H_max / Omega_max,
    # 0.159 kg m^2 for the 100 N m s wheel (75: 0.119, 50: 0.0796).
    "HR16": {
        "u_max": 0.200,             # [N m] maximum torque
        "u_min": 0.00001,           # [N m] minimum torque (deadband)
        "omega_max": 6000.0 * _RPM,  # [rad/s] 6000 rpm
        "coulomb": 0.0005,          # [N m] Coulomb friction
    },
    # Blue Canyon Technologies RWp050 (datasheet: 0.050 N m s momentum,
    # 0.007 N m torque). The datasheet gives no speed and no friction: the
    # speed limit is taken as 6000 rpm (as Basilisk's preset of its sibling
    # RWP015), so Jw = 0.050 / 628.3 = 7.96e-5 kg m^2; friction none.
    "RWp050": {
        "u_max": 0.007,             # [N m]
        "omega_max": 6000.0 * _RPM,  # [rad/s] assumed (above)
    },
}

LIMIT_KEYS = ("u_max", "u_min", "p_max", "omega_max")
FRICTION_KEYS = ("coulomb", "static", "beta", "viscous", "omega_limit_cycle")
_PER_WHEEL = Spec("vector", shape=(4,), scalar_ok=True, ge=0)


def read_wheels(root: Table) -> TorqueWheels | None | bool:
    """The TorqueWheels of the scenario's ``[wheels]`` table; None when it
    has none; False after reporting a problem."""
    if not root.has("wheels"):
        root.used.add("wheels")
        return None
    t = root.sub("wheels")
    if t.data is None:
        return False
    preset_name = t.read("preset", Spec("str", choices=tuple(PRESETS)), default="")
    if preset_name is None:
        t.finish()
        return False
    preset = PRESETS.get(preset_name, {})
    command = t.read("command", Spec("str", choices=COMMANDS), default="acceleration")
    stribeck = t.read("stribeck", Spec("bool"), default=False)
    switching = t.read("stribeck_switching", Spec("bool"), default=False)
    lag = t.read("lag", _PER_WHEEL, default=np.zeros(4))
    values: dict[str, np.ndarray | None] = {}
    for key in (*LIMIT_KEYS, *FRICTION_KEYS):
        values[key] = t.read(key, _PER_WHEEL, default=np.full(4, float(preset.get(key, 0.0))))
    t.finish()
    if (command is None or stribeck is None or switching is None or lag is None
            or any(v is None for v in values.values())):
        return False
    if stribeck and not np.all(values["beta"] > 0.0):
        t.fail("stribeck", "the static (Stribeck) friction needs beta > 0 on every wheel")
        return False
    if switching and stribeck:
        t.fail("stribeck_switching", "give stribeck (the static friction always on) or stribeck_switching "
                                     "(switched by Basilisk's rule), not both")
        return False
    if switching and not (np.all(values["beta"] > 0.0) and np.all(values["omega_limit_cycle"] > 0.0)):
        t.fail("stribeck_switching", "Basilisk's switch needs beta > 0 and omega_limit_cycle > 0 on every wheel "
                                     "(it switches on below 0.1 omega_limit_cycle)")
        return False
    if values["u_min"] is not None and np.any((values["u_max"] > 0.0) & (values["u_min"] > values["u_max"])):
        t.fail("u_min", "u_min (the deadband) must be <= u_max")
        return False
    limits = tuple(WheelLimits(**{k: float(values[k][i]) for k in LIMIT_KEYS}) for i in range(4))
    friction = tuple(WheelFriction(**{k: float(values[k][i]) for k in FRICTION_KEYS}) for i in range(4))
    return TorqueWheels(limits=limits, friction=friction, stribeck=bool(stribeck),
                        stribeck_switching=bool(switching), command=command, lag=tuple(float(v) for v in lag))


def check_wheel_fault(t: Table, stuck: bool, rate: float | None, has_wheels: bool,
                      plant_step: float | None) -> None:
    """A fault's keys that need ``[wheels]``, and a seizure fast enough to
    make the RK4 step unstable (rate h > 2), reported on its table ``t``."""
    if not has_wheels and t.has("friction"):
        t.fail("friction", "a friction rise needs flight-like wheels (a [wheels] table): "
                           "the paper's wheels have no friction")
    if has_wheels and stuck and rate is not None and plant_step is not None and rate * plant_step > 2.0:
        t.fail("rate", f"a seized wheel stops with the time constant 1/rate; rate * run.plant_step = "
                       f"{rate * plant_step:g} > 2 makes the RK4 step unstable")
