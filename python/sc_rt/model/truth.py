"""The true plant a run integrates, whichever wheels its scenario has: the
paper's acceleration-commanded wheels (sc_rt.model.plant, actuators) or,
when ``ActuatorParams.wheels`` is set, flight-like torque-commanded wheels
(sc_rt.model.torque_plant). The engines and the emulator call only this
module; the C++ twins are ``_core.plant_rk4_step`` and ``_core.plant_row``
(cpp/src/plant.cpp and torque_plant.cpp), bitwise equal.

With the paper's wheels every function here is exactly the old call
(tests/test_plant_pin.py pins the shipped scenarios' runs).
"""

from __future__ import annotations

from sc_rt.model import actuators, plant
from sc_rt.model.actuators import ActuatorParams
from sc_rt.model.plant_params import PlantParams
from sc_rt.model.rods import rods_dipole_B
from sc_rt.model.torque_plant import TorquePlant, step_inputs
from sc_rt.model.wheels import motor_lag, stribeck_switch

__all__ = ["rk4_step", "row", "torque_plant", "new_motor"]


def new_motor(act: ActuatorParams) -> list[float] | None:
    """What torque-commanded wheels carry from step to step, all 0 at the
    start (None for the paper's wheels): the 4 motor torques [N m] (a lag's
    state), then with ``stribeck_switching`` the 4 switches of the
    friction's static part (1.0 on, 0.0 off). ``rk4_step`` updates it in
    place, ``row`` reads it."""
    if act.wheels is None:
        return None
    return [0.0] * (8 if act.wheels.stribeck_switching else 4)


def _lagged(act: ActuatorParams, motor) -> bool:
    if act.wheels.stribeck_switching and (motor is None or len(motor) != 8):
        raise ValueError("wheels with stribeck_switching need the carried switches (truth.new_motor, 8 numbers)")
    if not any(act.wheels.lag):
        return False
    if motor is None:
        raise ValueError("wheels with a motor lag need the motor state (truth.new_motor)")
    return True


def torque_plant(p: PlantParams, act: ActuatorParams) -> TorquePlant:
    """The TorquePlant of ``p`` on ``act.wheels``, built once per pair."""
    cached = act.__dict__.get("_torque_plant")
    if cached is None or cached[0] is not p:
        cached = (p, TorquePlant(p, act.wheels))
        object.__setattr__(act, "_torque_plant", cached)
    return cached[1]


def rk4_step(p: PlantParams, act: ActuatorParams, t: float, x, h: float, u_cmd, motor=None,
             dipole_B=None):
    """One RK4 step of the true plant from t to t + h [s], the wheel command
    ``u_cmd`` held (sc_rt.model.plant.rk4_step for the paper's wheels; for
    torque-commanded ones, the torques of ``step_inputs`` at t held, through
    the motor lag when there is one: ``motor``, from ``new_motor``, is then
    advanced to t + h in place). ``dipole_B``: the magnetorquers' body dipole
    [A m^2] held over the step (None or zeros: none; sc_rt.model.magnetic)."""
    if act.wheels is None:
        return plant.rk4_step(p, act, t, x, h, u_cmd, dipole_B)
    tp = torque_plant(p, act)
    x0 = [float(v) for v in x]
    h = float(h)
    if dipole_B is None and p.magnetorquers is not None:
        dipole_B = rods_dipole_B(p.magnetorquers, float(t))  # the rods' own dipole (a stuck rod's)
    u, scale, brake = step_inputs(act, p.Jw, float(t), u_cmd, x0[6:10])
    if _lagged(act, motor):
        for i, tau in enumerate(act.wheels.lag):
            u[i], motor[i] = motor_lag(u[i], motor[i], tau, h)
    elif motor is not None:
        motor[0:4] = u
    if not act.wheels.stribeck_switching:
        return tp.step_held(float(t), x0, h, u, scale, brake, dipole_B)
    on = [motor[4 + i] != 0.0 for i in range(4)]
    x1 = tp.step_held(float(t), x0, h, u, scale, brake, dipole_B, on)
    motor[4:8] = [1.0 if v else 0.0 for v in on]
    return x1


def row(p: PlantParams, act: ActuatorParams, t: float, x, u_cmd, motor=None, dipole_B=None) -> tuple:
    """(u_sat, wheel accel, delta2) of a row: the command after the wheels'
    limits [rad/s^2], the wheels' actual acceleration relative to the body
    Omega_w_dot [rad/s^2] and the true lumped disturbance delta_2 [rad/s^2].

    For torque-commanded wheels u_sat is the applied motor torque over Jw
    (the acceleration it gives a free wheel) and the acceleration comes from
    the dynamics at (t, x); delta_2 is then exact, since (7) holds for them
    with the true Omega_w_dot. With a motor lag the motor torque at t is the
    state ``motor`` (before this row's step), not the command; with
    ``stribeck_switching`` the friction's static part is the one the step's
    first stage takes (``motor``'s switches through the rule at t).
    ``dipole_B``: the magnetorquers' body dipole [A m^2] the step from t
    holds (``rk4_step``'s; None: the rods' for a zero command), so that the
    acceleration is the step's first stage's (docs/MODEL.md section 17).
    """
    if act.wheels is None:
        u_sat, accel, _ = actuators.wheel_accel(act, t, u_cmd, x[6:10])
    else:
        tp = torque_plant(p, act)
        x0 = [float(v) for v in x]
        u, scale, brake = step_inputs(act, p.Jw, float(t), u_cmd, x0[6:10])
        if _lagged(act, motor):
            u = [m if tau > 0.0 else c for m, c, tau in zip(motor, u, act.wheels.lag)]
        if dipole_B is None and p.magnetorquers is not None:
            dipole_B = rods_dipole_B(p.magnetorquers, float(t))  # the rods' own dipole (a stuck rod's)
        on = None  # the static part as the step's first stage takes it (its omega - omega_start = 0)
        if act.wheels.stribeck_switching:
            on = [stribeck_switch(motor[4 + i] != 0.0, x0[6 + i], x0[6 + i], act.wheels.friction[i])
                  for i in range(4)]
        accel = tp.derivative(float(t), x0, u, scale, brake, dipole_B, on)[6:10]
        u_sat = [u[i] / float(p.Jw[i]) for i in range(4)]
    return u_sat, accel, plant.lumped_disturbance(p, t, x, u_sat, accel)
