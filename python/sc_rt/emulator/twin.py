"""The plant emulator's arithmetic of a row and the bytes of its messages
(emulator/process.py runs the loops).

- ``PlantTwin``: ``n_sub`` RK4 steps with the command held, the C++ plant
  twin (``_core.plant_rk4_step``, bitwise the Python
  ``model.truth.rk4_step``) or, with ``cpp=False``, the Python one (for a
  changed model/plant.py); a row's wheel saturation, acceleration and
  lumped disturbance (the C++ twins of ``actuators.wheel_accel`` and
  ``plant.lumped_disturbance``, bitwise, or those); the truth's fault
  fields. Always for the fault set the row was applied with (``act``: a
  fault command may change the emulator's while it waits).
- a run with magnetic control: the true field in B at a control instant
  (``field_B``: ``_core.plant_field_B`` or ``model.plant.field_B``, the
  ideal magnetometer) and the rods' dipole commands held over the period
  through the plant's rods and their faults at each step's time
  (``rods_dipole_B``), as the offline engines do (sim/engines.py). The
  rods too are the row's (``rods``: a rod fault command replaces the
  emulator's; None: the scenario's).
- the truth's rod fields (``rod_fields``): the commands the row holds,
  each rod's dipole and fault state at t and the body dipole the step
  applies.
- ``plant_state_t`` and ``plant_truth_t`` packed with struct, exactly the
  generated encoding (tests/test_emulator_wire.py), for speed.
"""

from __future__ import annotations

import dataclasses
import struct

import numpy as np
import sc_rt_lcm

from sc_rt import _core
from sc_rt.model import actuators, plant, truth
from sc_rt.model.rods import rods_applied, rods_dipole_B, rods_to_cpp

__all__ = ["NO_RODS", "PlantTwin", "RodHold", "state_bytes", "truth_bytes"]

# plant_state_t: utime, seq, session, t, sigma_BN[3], omega_BN_B[3], wheel_speed[4]
_STATE_FP = sc_rt_lcm.plant_state_t._get_packed_fingerprint()
_STATE_LAYOUT = struct.Struct(">qqqd3d3d4d")
# plant_truth_t: utime, seq, t, cmd_seq_applied, u_cmd[4], wheel_accel[4],
# delta2[3], disturbance[3], fault_Y[4], fault_effectiveness[4], fault_bias[4],
# fault_stuck[4] (int8), cmd_stale (int8), gyro_bias[3], n_rods (int8),
# rod_dipole_cmd[6], rod_dipole[6], dipole_B[3], rod_fault[6] (int8)
_TRUTH_FP = sc_rt_lcm.plant_truth_t._get_packed_fingerprint()
_TRUTH_LAYOUT = struct.Struct(">qqdq4d4d3d3d4d4d4d4bb3db6d6d3d6bqq")
_NO_BIAS = (0.0, 0.0, 0.0)
#: the truth's rod fields of a plant without rods: n_rods, rod_dipole_cmd, rod_dipole, dipole_B, rod_fault
NO_RODS = (0, (0.0,) * 6, (0.0,) * 6, (0.0,) * 3, (0,) * 6)
assert _STATE_LAYOUT.size + 8 == len(sc_rt_lcm.plant_state_t().encode())
assert _TRUTH_LAYOUT.size + 8 == len(sc_rt_lcm.plant_truth_t().encode())


def state_bytes(utime: int, k: int, session: int, t: float, x: np.ndarray) -> bytes:
    """plant_state_t of state k at t."""
    return _STATE_FP + _STATE_LAYOUT.pack(utime, k, session, t, *x[0:10])


def truth_bytes(utime: int, k: int, t: float, cmd_seq: int, u_cmd, accel, delta2, disturbance, fault_y,
                eff_bias_stuck, stale: bool, gyro_bias=_NO_BIAS, rods=NO_RODS, fault_seqs=(-1, -1)) -> bytes:
    """plant_truth_t of row k (``rods``: its rod fields, ``PlantTwin.rod_fields``;
    ``fault_seqs``: the seqs of the newest fault commands applied and refused)."""
    n_rods, d_cmd, d, m_B, fault = rods
    return _TRUTH_FP + _TRUTH_LAYOUT.pack(utime, k, t, cmd_seq, *u_cmd, *accel, *delta2, *disturbance,
                                          *fault_y, *eff_bias_stuck, 1 if stale else 0, *gyro_bias,
                                          n_rods, *d_cmd, *d, *m_B, *fault, *fault_seqs)


class PlantTwin:
    """The plant of ``params`` (model.plant_params.PlantParams) with the actuators
    each call is given."""

    def __init__(self, params, cpp: bool = True):
        self.params, self.cpp = params, cpp
        #: what torque-commanded wheels carry from row to row (truth.new_motor: the
        #: motor torques of a lag, the Stribeck switches); ``motor_at_start``: as it
        #: was at the latest row's start
        self.motor: list[float] | None = None
        self.motor_at_start: tuple | None = None
        self._cpp_params: tuple = (None, None)
        self._fault_fields: tuple = (None,)
        self._pp = None  # the C++ plant parameters of the field (no faults in them)
        self._rod_params: tuple = (None,)  # (rods, the plant parameters with them, their C++ PlantRods)

    def _params(self, rods):
        """The plant parameters with ``rods`` (model.rods.Magnetorquers, as a
        rod fault command left them; None: the scenario's)."""
        if rods is None or rods is self.params.magnetorquers:
            return self.params
        if self._rod_params[0] is not rods:  # the rods' faults changed (live injection)
            self._rod_params = (rods, dataclasses.replace(self.params, magnetorquers=rods), rods_to_cpp(rods))
        return self._rod_params[1]

    def _cpp(self, act, rods=None) -> tuple:
        if self._cpp_params[0] is not act or self._cpp_params[1] is not rods:  # a fault set changed (live)
            self._cpp_params = (act, rods, plant.plant_params_to_cpp(self._params(rods)),
                                actuators.actuator_params_to_cpp(act))
        return self._cpp_params[2], self._cpp_params[3]

    def field_B(self, t: float, x: np.ndarray) -> tuple | None:
        """[T] the plant's true field in B at t for the state x (None: no field)."""
        if self.cpp:
            B = _core.plant_field_B(self._plant_cpp(), t, x[0:3])
            return None if B is None else tuple(float(v) for v in B)
        return plant.field_B(self.params, t, x)

    def dipole_B(self, t: float, d_cmd, rods=None) -> tuple | None:
        """[A m^2] the body dipole of the rod commands ``d_cmd`` [A m^2] (one
        per rod; None: no magnetic control, the step holds the rods' own) at t
        through the plant's rods and their faults (``rods``: the row's; None:
        the scenario's)."""
        if d_cmd is None:
            return None
        if self.cpp:  # the C++ loop's (closed_loop.cpp), bitwise the Python one
            c = self._plant_cpp().rods if self._params(rods) is self.params else self._rod_params[2]
            return _core.rods_dipole_B(c, t, np.asarray(d_cmd, float))
        return rods_dipole_B(self._params(rods).magnetorquers, t, d_cmd)

    def rod_fields(self, t: float, d_cmd, rods=None) -> tuple:
        """The truth's rod fields at t (``NO_RODS`` without rods): n_rods, the
        commands ``d_cmd`` the row holds [A m^2] (None: no magnetic control,
        a zero command), each rod's dipole through its limit and fault
        (model.rods.rods_applied: exact, the same on either path), the body
        dipole the step applies (``dipole_B``: the C++ or the Python twin's),
        each rod's fault state; the arrays padded to 6 with 0."""
        r = self._params(rods).magnetorquers
        if r is None:
            return NO_RODS
        n, pad = r.n_rods, (0.0,) * (6 - r.n_rods)
        cmd = (0.0,) * n if d_cmd is None else tuple(float(v) for v in d_cmd)
        d, fault = rods_applied(r, t, cmd)
        return (n, cmd + pad, (*d, *pad), tuple(self.dipole_B(t, cmd, rods)), (*fault, *(0,) * (6 - n)))

    def _plant_cpp(self):
        if self._pp is None:
            self._pp = plant.plant_params_to_cpp(self.params)
        return self._pp

    def integrate(self, act, t: float, x: np.ndarray, u_cmd: np.ndarray, n_sub: int, h: float,
                  sensors=None, i0: int = 0, d_cmd=None, rods=None) -> np.ndarray:
        """n_sub RK4 steps of h from t with u_cmd held (``d_cmd``: the rods'
        dipole commands, held too, through the rods at each step's time;
        ``rods``: the row's rods and faults, None: the scenario's). ``sensors`` (a
        emulator.sensorpub.SensorPublisher, the row's first plant step ``i0``):
        ticked before each sub-step j > 0 whose plant step i0 + j it names
        (``next_tick``), at t + j h with the state then, as the offline loop
        does (sim/sensed.py)."""
        if act.wheels is not None and self.motor is None:
            self.motor = truth.new_motor(act)
        self.motor_at_start = None if self.motor is None else tuple(self.motor)
        if not self.cpp:
            for j in range(n_sub):
                if j > 0 and sensors is not None and i0 + j == sensors.next_tick:
                    sensors.tick(i0 + j, t + j * h, x)
                x = truth.rk4_step(self._params(rods), act, t + j * h, x, h, u_cmd, self.motor,
                                   self.dipole_B(t + j * h, d_cmd, rods))
            return x
        pp, ap = self._cpp(act, rods)
        xs = _core.PlantState.from_vector(x)
        motor = None if self.motor is None else np.array(self.motor)
        for j in range(n_sub):
            if j > 0 and sensors is not None and i0 + j == sensors.next_tick:
                sensors.tick(i0 + j, t + j * h, xs.to_vector())
            m_B = self.dipole_B(t + j * h, d_cmd, rods)
            if motor is None:
                xs = _core.plant_rk4_step(pp, ap, t + j * h, xs, h, u_cmd, m_B)
            else:
                xs, motor = _core.plant_rk4_step_motor(pp, ap, t + j * h, xs, h, u_cmd, motor, m_B)
        if motor is not None:
            self.motor[:] = motor.tolist()
        return xs.to_vector()

    def row(self, act, t: float, x: np.ndarray, u_cmd: np.ndarray, motor=None, d_cmd=None, rods=None) -> tuple:
        """(u_sat, wheel accel, delta2) of the row at t, state x, command u_cmd
        (``motor``: the motor torques at t, ``motor_at_start`` of its integrate;
        ``d_cmd``: the rods' commands the row holds, the step's first stage's dipole;
        ``rods``: the row's rods, None: the scenario's)."""
        m_B = self.dipole_B(t, d_cmd, rods)
        if self.cpp:
            pp, ap = self._cpp(act, rods)
            xs = _core.PlantState.from_vector(x)
            w = _core.plant_row(pp, ap, t, xs, u_cmd, None if motor is None else np.array(motor), m_B)
            u_sat, accel = w.u_sat, w.accel
            delta2 = _core.lumped_disturbance(pp, t, xs, u_sat, accel)
        else:
            u_sat, accel, delta2 = truth.row(self._params(rods), act, t, x, u_cmd,
                                             None if motor is None else list(motor), m_B)
        return u_sat, accel, delta2

    def fault_fields(self, act, t: float) -> tuple[list, list]:
        """(fault_Y per wheel at t, effectiveness[4] + bias[4] + stuck[4])."""
        if self._fault_fields[0] is not act:  # the fault set changed (live injection)
            faults = {f.wheel: f for f in act.faults}
            self._fault_fields = (
                act, [faults.get(i) for i in range(4)],
                [faults[i].effectiveness if i in faults else 1.0 for i in range(4)]
                + [faults[i].bias if i in faults else 0.0 for i in range(4)]
                + [1 if i in faults and faults[i].stuck else 0 for i in range(4)])
        _, per_wheel, eff_bias_stuck = self._fault_fields
        return [actuators.fault_Y(f, t) for f in per_wheel], eff_bias_stuck

    def disturbance(self, t: float):
        return plant.disturbance(self.params, t)


class RodHold:
    """The rods' commands a row holds (a run with magnetic control; ``n_rods``
    0: none, ``for_row`` returns None): the rod command answering the same
    state as the row's wheel command; without one the previous commands go
    on (zero-order hold, counted ``rod_cmd_held``); under the watchdog (no
    wheel command) zero, as the wheels."""

    def __init__(self, n_rods: int, counters):
        self.n_rods, self.counters = n_rods, counters
        self.held = (0.0,) * n_rods  # [A m^2]

    def for_row(self, cmd, rod) -> tuple | None:
        """[A m^2] the row's rod commands for the wheel command ``cmd`` (None:
        the watchdog's zero) and the rod command ``rod`` (None: none)."""
        if not self.n_rods:
            return None
        if cmd is None:
            self.held = (0.0,) * self.n_rods
        elif rod is None or rod.state_seq != cmd.state_seq or rod.session != cmd.session:
            self.counters["rod_cmd_held"] += 1
        else:
            self.held = tuple(rod.dipole)
        return self.held
