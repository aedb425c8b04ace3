"""The plant with torque-commanded reaction wheels (issue #28): the Python
reference of the dynamics, checked against Basilisk's own test cases and
closed forms (tests/test_torque_plant.py). A scenario with a ``[wheels]``
table runs it (sc_rt.model.truth picks it from ``ActuatorParams.wheels``).

Its C++ twin, ``sc_rt._core.TorquePlant`` (cpp/src/torque_plant.cpp,
``torque_plant_to_cpp``), gives the same bits.

The state is the paper's, x = [sigma_BN, omega_BN_B, Omega_w]: the wheel
speeds relative to the body. With the motor torque u_i [N m] of wheel i on
its axis g_i (the columns of Cbar), the wheel's spin obeys
Jw_i (g_i' omega_dot + Omega_dot_i) = u_i, and the body gets -g_i u_i.
Put into (7) (J omega_dot = -omega^ H - Cbar Jw Omega_dot + u_g + d, with
J the whole spacecraft's inertia, wheels included, and H = J omega +
Cbar Jw Omega_w):

    M omega_dot = -omega^ H - Cbar u + u_g + d,   M = J - Cbar diag(Jw) Cbar'
    Omega_dot_i = u_i / Jw_i - g_i' omega_dot

M is the inertia without the wheels' spin inertia about their axes: what
Basilisk's balanced-wheel model solves with, its hub inertia (the total,
as J here) less Js g g' per wheel. u is the net torque on each wheel:
the motor torque after its limits (sc_rt.model.wheels.applied_torque: torque
limit, deadband, power and speed limits), taken once per step at the step's
start speed and held over it, plus the friction
(sc_rt.model.wheels.friction_torque) at each RK4 stage's wheel speed, as
Basilisk takes them (docs/MODEL.md, "Flight-like wheels"). With
``stribeck_switching`` the friction's static part is switched per wheel at
every stage by Basilisk's rule (sc_rt.model.wheels.stribeck_switch, against
the step's start speed), the switches carried from step to step.
"""

from __future__ import annotations

import math

import numpy as np

from sc_rt.model.actuators import ActuatorParams
from sc_rt.model.magnetic import held_dipole, make_field_N
from sc_rt.model.kernels import inv3, make_disturbance, make_orbit_gg, make_rhs, mrp_to_dcm
from sc_rt.model.plant_params import PlantParams
from sc_rt.model.wheels import TorqueWheels, applied_torque, friction_torque, stribeck_switch, wheel_torque_command

__all__ = ["TorqueWheels", "TorquePlant", "torque_plant_to_cpp", "step_inputs"]

_FREE = TorqueWheels()  # no limits, no friction
_ONES = (1.0, 1.0, 1.0, 1.0)
_ZEROS = (0.0, 0.0, 0.0, 0.0)


class TorquePlant:
    """The plant ``p`` on the wheels ``wheels`` (module docstring).

    Parameters
    ----------
    p : PlantParams
        The spacecraft (J = J0 + dJ, the whole spacecraft's inertia with the
        wheels; Cbar; Jw; w0; the disturbance).
    wheels : TorqueWheels
        The wheels' limits and friction.

    Raises
    ------
    ValueError
        M = J - Cbar diag(Jw) Cbar' is not positive definite (the wheels'
        spin inertia is more than the spacecraft's).
    """

    def __init__(self, p: PlantParams, wheels: TorqueWheels = _FREE):
        self.p, self.wheels = p, wheels
        J = np.asarray(p.J, float).tolist()
        C = np.asarray(p.Cbar, float).tolist()
        Jw = [float(v) for v in p.Jw]
        # M, element by element, the wheels subtracted in order 1..4 (a C++ twin repeats it)
        M = [[J[r][c] for c in range(3)] for r in range(3)]
        for r in range(3):
            for c in range(3):
                for i in range(4):
                    M[r][c] -= (C[r][i] * Jw[i]) * C[c][i]
        Mn = np.array(M)
        if not np.all(np.linalg.eigvalsh(0.5 * (Mn + Mn.T)) > 0.0):
            raise ValueError(f"TorquePlant: J - Cbar diag(Jw) Cbar' is not positive definite: {M!r}")
        self.M = Mn
        self._f = make_rhs(p.J, inv3(Mn), 3.0 * p.w0 * p.w0)  # H and u_g with J, solved with M
        self._C, self._Jw = C, Jw
        self._CJ = [[C[r][i] * Jw[i] for i in range(4)] for r in range(3)]
        self._dist = make_disturbance(p.disturbance)
        # the orbit's gravity gradient (None: the w0 form)
        self._gg = make_orbit_gg(p.orbit if p.orbit_gravity_gradient else None)
        self._field = make_field_N(p.orbit, p.field_model)  # B_N(t) [T] (None: no field)
        self._res = tuple(p.residual_dipole.tolist())  # [A m^2] the residual dipole

    def motor_torques(self, u_cmd, omega_w) -> list[float]:
        """[N m] the motor torques the wheels apply for the commands ``u_cmd``
        at the wheel speeds ``omega_w`` (their limits)."""
        return [applied_torque(float(u_cmd[i]), float(omega_w[i]), self.wheels.limits[i]) for i in range(4)]

    def net_torques(self, u_motor, omega_w, scale=_ONES, brake=_ZEROS, on=None) -> list[float]:
        """[N m] motor torque plus friction (times ``scale``, a friction-rise
        fault) minus the seizure brake ``brake`` Omega at the wheel speeds
        ``omega_w``; ``on``: per wheel, the friction's static part on (None:
        ``wheels.stribeck`` for all)."""
        w = self.wheels
        on = (w.stribeck,) * 4 if on is None else on
        return [u_motor[i] + scale[i] * friction_torque(float(omega_w[i]), w.friction[i], bool(on[i]))
                - brake[i] * float(omega_w[i]) for i in range(4)]

    def derivative(self, t: float, x, u_motor, scale=_ONES, brake=_ZEROS, dipole_B=None, on=None) -> list[float]:
        """x_dot (10) at time ``t`` [s] and state ``x`` with the motor torques
        ``u_motor`` [N m] (after their limits; the friction, times
        ``scale``, and the seizure brake are added here) and the
        magnetorquers' body dipole ``dipole_B`` [A m^2] (None: none; the
        residual dipole acts either way, sc_rt.model.magnetic); ``on``: per
        wheel, the friction's static part on (None: ``wheels.stribeck``)."""
        s1, s2, s3, w1, w2, w3, O1, O2, O3, O4 = (float(v) for v in x)
        u1, u2, u3, u4 = self.net_torques(u_motor, (O1, O2, O3, O4), scale, brake, on)
        C, CJ, Jw = self._C, self._CJ, self._Jw
        hw = [CJ[r][0] * O1 + CJ[r][1] * O2 + CJ[r][2] * O3 + CJ[r][3] * O4 for r in range(3)]
        tw = [C[r][0] * u1 + C[r][1] * u2 + C[r][2] * u3 + C[r][3] * u4 for r in range(3)]
        m = held_dipole(self._res, dipole_B)
        mb = None if m is None or self._field is None else m + self._field(float(t))
        sd1, sd2, sd3, a1, a2, a3 = self._f(s1, s2, s3, w1, w2, w3, *hw, *tw, *self._dist(float(t)),
                                            self._gg(float(t)), mb)
        return [sd1, sd2, sd3, a1, a2, a3,
                *(u / Jw[i] - (C[0][i] * a1 + C[1][i] * a2 + C[2][i] * a3)
                  for i, u in enumerate((u1, u2, u3, u4)))]

    def step(self, t: float, x, h: float, u_cmd) -> np.ndarray:
        """One classical RK4 step from t to t + h [s] with the motor commands
        ``u_cmd`` [N m] held (their limits at the step's start speed), the
        friction at each stage; the attitude mapped to the MRP short set after."""
        x0 = [float(v) for v in x]
        return self.step_held(t, x0, h, self.motor_torques(u_cmd, x0[6:10]))

    def step_held(self, t: float, x, h: float, u, scale=_ONES, brake=_ZEROS, dipole_B=None,
                  stribeck=None) -> np.ndarray:
        """One RK4 step with the motor torques ``u`` [N m] (after limits and
        faults), the friction scale, the seizure brake and the magnetorquers'
        body dipole ``dipole_B`` [A m^2] (None: none) held over it.

        ``stribeck``: with ``wheels.stribeck_switching``, the 4 switches of
        the friction's static part carried from the previous step (a list,
        updated in place): each stage first applies Basilisk's rule
        (``stribeck_switch``) at its wheel speeds against the step's start
        speeds, then evaluates the friction with the result.
        """
        x0 = [float(v) for v in x]
        hh = 0.5 * h
        m = dipole_B
        switching = self.wheels.stribeck_switching
        if switching and stribeck is None:
            raise ValueError("TorquePlant: stribeck_switching needs the carried switches (step_held's stribeck)")
        fr = self.wheels.friction

        def on(xs):  # Basilisk's switch at this stage; None: the fixed flag
            if not switching:
                return None
            for i in range(4):
                stribeck[i] = stribeck_switch(bool(stribeck[i]), xs[6 + i], x0[6 + i], fr[i])
            return tuple(stribeck)

        k1 = self.derivative(t, x0, u, scale, brake, m, on(x0))
        xs = [a + hh * b for a, b in zip(x0, k1)]
        k2 = self.derivative(t + hh, xs, u, scale, brake, m, on(xs))
        xs = [a + hh * b for a, b in zip(x0, k2)]
        k3 = self.derivative(t + hh, xs, u, scale, brake, m, on(xs))
        xs = [a + h * b for a, b in zip(x0, k3)]
        k4 = self.derivative(t + h, xs, u, scale, brake, m, on(xs))
        h6 = h / 6.0
        out = [a + h6 * (b + 2.0 * (c + d) + e) for a, b, c, d, e in zip(x0, k1, k2, k3, k4)]
        ss = out[0] * out[0] + out[1] * out[1] + out[2] * out[2]
        if ss > 1.0:  # MRP shadow set: same attitude, |sigma| <= 1
            out[0:3] = [-v / ss for v in out[0:3]]
        return np.array(out)

    def momentum_N(self, x) -> np.ndarray:
        """[N m s] the spacecraft's and wheels' angular momentum in N (3,)."""
        xs = np.asarray(x, float)
        H_B = np.asarray(self.p.J) @ xs[3:6] + (np.asarray(self.p.Cbar) * np.asarray(self.p.Jw)) @ xs[6:10]
        return mrp_to_dcm(xs[0:3]).T @ H_B

    def energy(self, x) -> float:
        """[J] the rotational kinetic energy of spacecraft and wheels:
        1/2 omega' M omega + 1/2 sum Jw_i (g_i' omega + Omega_i)^2."""
        xs = np.asarray(x, float)
        w, wheel = xs[3:6], xs[6:10]
        spin = np.asarray(self.p.Cbar).T @ w + wheel
        return float(0.5 * w @ self.M @ w + 0.5 * np.sum(np.asarray(self.p.Jw) * spin * spin))


def step_inputs(act: ActuatorParams, Jw, t: float, u_cmd, omega_w) -> tuple[list, list, list]:
    """What the wheels ``act.wheels`` hold over a step from ``t``: (motor
    torques [N m], friction scales [-], seizure brakes [N m s]).

    Per wheel: the command as a motor torque (``wheel_torque_command``), its
    limits at the speed ``omega_w`` (``applied_torque``), then its fault while
    active (onset <= t < end): a seized wheel (``stuck``) gets no motor torque
    and a brake Jw rate, so that its speed decays with the time constant
    1/rate; any other fault, with Y = 1 - exp(-rate (t - onset)), changes the
    torque to u + Y ((L - 1) u + Jw bias) and multiplies the friction by
    1 + Y (friction - 1) (torque loss, friction rise).
    """
    w = act.wheels
    u, scale, brake = [0.0] * 4, [1.0] * 4, [0.0] * 4
    for i in range(4):
        u[i] = applied_torque(wheel_torque_command(float(u_cmd[i]), float(Jw[i]), w.command),
                              float(omega_w[i]), w.limits[i])
    for f in act.faults:
        i = f.wheel
        if not (f.onset <= t < f.end_time):
            continue
        if f.stuck:
            u[i], brake[i] = 0.0, float(Jw[i]) * f.rate
        else:
            Y = -math.expm1(-f.rate * (t - f.onset))
            u[i] = u[i] + Y * ((f.effectiveness - 1.0) * u[i] + float(Jw[i]) * f.bias)
            scale[i] = 1.0 + Y * (f.friction - 1.0)
    return u, scale, brake


def torque_plant_to_cpp(p: PlantParams, wheels: TorqueWheels = _FREE):
    """The C++ twin, ``sc_rt._core.TorquePlant``, of ``TorquePlant(p, wheels)``."""
    from sc_rt import _core
    from sc_rt.model.plant import plant_params_to_cpp

    limits = [(w.u_max, w.u_min, w.p_max, w.omega_max) for w in wheels.limits]
    friction = [(f.coulomb, f.static, f.beta, f.viscous, f.omega_limit_cycle) for f in wheels.friction]
    if wheels.stribeck_switching:
        raise ValueError("torque_plant_to_cpp: stribeck_switching needs the carried switches: the C++ twin is "
                         "_core.plant_rk4_step_motor (truth.rk4_step's)")
    return _core.TorquePlant(plant_params_to_cpp(p), limits, friction, wheels.stribeck)
