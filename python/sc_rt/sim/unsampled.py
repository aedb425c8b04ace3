"""The unsampled reference mode of ``sc-rt sim`` (``--engine unsampled``):
the control law evaluated inside every RK4 stage of the plant, with its
states (guidance, observer (22), filter (37), anti-windup (42), RFT gain)
integrated as continuous states of one ODE, as a Simulink model with a
fixed-step solver would run it. No zero-order hold, no sample delay.

A reference, not a product path: the law is written here once more in
continuous time (numpy, with the core's kinematics, errors and PPC
transform through ``_core``), so that the sampled-data effects of the real
controller can be told apart from the law itself (docs/REPRODUCTION.md).
Rows are recorded at the scenario's control rate, with the same keys as the
sampled engines.
"""

from __future__ import annotations

import numpy as np

from sc_rt import _core
from sc_rt.isolate import beat
from sc_rt.model import actuators, plant
from sc_rt.scenario.model import Scenario
from sc_rt.scenario.overrides import grid, initial_state

__all__ = ["run_unsampled"]


#: The laws the reference mode writes out in continuous time (below). Any
#: other law (a plugin, a Python class) is refused, never replaced by one of
#: these: a run must be the law it names.
LAWS = ("dsc-ppc", "dsc", "pd", "rft")


def refusal(law: str) -> str | None:
    """Why the unsampled engine cannot run ``law`` (one line), or None."""
    if law in LAWS:
        return None
    return (f"the unsampled engine writes out the built-in laws only ({', '.join(LAWS)}) and cannot run "
            f"{law}; use --engine python or cpp")


class _Law:
    """uc(t, X) and the derivatives of the law's states, continuous time."""

    def __init__(self, scn: Scenario):
        cfg = scn.core_config()
        self.law = scn.run.controller
        if (why := refusal(self.law)) is not None:
            raise ValueError(why)
        if scn.actuators.wheels is not None:
            raise ValueError("the unsampled engine has the paper's wheels only, not the scenario's [wheels]; "
                             "use --engine python or cpp")
        if scn.magnetic_control is not None:
            raise ValueError("the unsampled engine has no magnetic control ([momentum], [bdot]); "
                             "use --engine python or cpp")
        self.cfg = cfg
        self.model = _core.SpacecraftModel(cfg.spacecraft)
        self.B = np.asarray(self.model.B)
        self.Bp = np.asarray(self.model.B_pinv)
        self.umin, self.umax = np.asarray(cfg.spacecraft.umin), np.asarray(cfg.spacecraft.umax)
        # the law's parameters as the C++ law runs them: its defaults and its table
        self.p = p = scn.controller.resolved(self.law)
        if self.law in ("dsc-ppc", "dsc"):
            self.k1o, self.k2o, self.k3o, self.k4o = (np.broadcast_to(np.asarray(p[f"neso_{k}"], float), 3)
                                                      for k in ("k1", "k2", "k3", "k4"))
            self.alpha = p["neso_alpha"]
        # the paper's sigma_d is a state of the ODE; a hold, slew or table is a closed form
        self.integrated = _core.guidance_integrated(cfg.guidance)

    def evaluate(self, t: float, X: np.ndarray):
        """(u_cmd, telemetry dict, derivative of the law's states)."""
        c = self.cfg
        sigma, omega, wheel = X[0:3], X[3:6], X[6:10]
        sd, z1, z2, x2d, vs, rho = X[10:13], X[13:16], X[16:19], X[19:22], X[22:26], X[26]
        if not self.integrated:
            sd = np.asarray(_core.sigma_d(c.guidance, t))
        od, odd = _core.omega_d(c.guidance, t), _core.omega_d_dot(c.guidance, t)
        e = _core.tracking_errors(self.model, _core.Measurement(t, sigma, omega, wheel), sd, od, odd)
        x1, x2, A = np.asarray(e.sigma_BD), np.asarray(e.omega_BD_B), np.asarray(e.A)
        ppc = _core.ppc_transform(c.ppc, x1, t)
        G = np.asarray(_core.mrp_G(x1))
        dX = np.zeros(17)
        dX[0:3] = np.asarray(_core.mrp_G(sd)) @ od  # guidance
        tel = {"sigma_DN": sd, "sigma_BD": x1, "omega_BD_B": x2, "chi": np.asarray(ppc.chi),
               "lam": np.asarray(ppc.lambda_), "z1": z1, "z2": z2}
        p = self.p
        if self.law in ("dsc-ppc", "dsc"):
            Ginv = np.asarray(_core.mrp_G_inverse(x1))
            if self.law == "dsc":
                e1, r = x1, np.ones(3)
                x2bar = -Ginv @ (p["k1"] * e1)
            else:
                e1, r = np.asarray(ppc.e1), np.asarray(ppc.r)
                x2bar = -Ginv @ (p["k1"] * e1 / r - np.asarray(ppc.lambda_) * np.asarray(ppc.chi_dot))  # (36)
            x2d_dot = (x2bar - x2d) / p["tau"]  # (37)
            e2 = x2 - x2d  # (27)
            u = self.Bp @ (-A - p["k2"] * e2 - G.T @ (r * e1) - p["k3"] * self.B @ vs - z2 + x2d_dot)  # (41)
            usat = np.clip(u, self.umin, self.umax)
            ev = z1 - x2
            sa = np.sign(ev) * np.abs(ev) ** self.alpha
            sb = np.sign(ev) * np.abs(ev) ** (2 * self.alpha - 1)
            dX[3:6] = A + self.B @ usat + z2 - self.k1o * sa - self.k2o * ev  # (22)
            dX[6:9] = -self.k3o * sb - self.k4o * ev
            dX[9:12] = x2d_dot
            dX[12:16] = -p["k4"] * vs + (usat - u)  # (42)
        elif self.law == "pd":
            u = -self.Bp @ (p["beta1"] * x1 + p["beta2"] * x2)
        else:  # rft (the only law left: __init__ refused the others)
            s = x2 + p["c"] * x1
            u = self.Bp @ (-A - p["c"] * G @ x2 - p["k"] * s - rho * np.clip(s / p["phi"], -1, 1))
            dX[16] = p["gain"] * np.linalg.norm(s) - p["leak"] * rho
        return u, tel, dX


def _init_states(law: _Law, scn: Scenario, x0: np.ndarray) -> np.ndarray:
    c = law.cfg
    sd = np.asarray(c.guidance.sigma_d0, float)
    X = np.zeros(27)
    X[0:10] = x0
    X[10:13] = sd
    X[26] = law.p["rho0"] if law.law == "rft" else 0.0
    if law.law in ("dsc-ppc", "dsc"):
        # x2d(0) = x2bar(0) (37): evaluate the law once with x2d = 0, take x2bar
        u0, tel, dX = law.evaluate(0.0, X)
        X[19:22] = dX[9:12] * law.p["tau"]  # x2d_dot * tau = x2bar - 0
        if law.p["neso_init_from_measurement"] == 1.0:
            X[13:16] = tel["omega_BD_B"]
    return X


def run_unsampled(scn: Scenario) -> tuple[dict[str, np.ndarray], int, bool]:
    """Rows at t_k = k / rate; between them n_sub RK4 steps of the whole ODE.
    Returns (run columns, rows, diverged)."""
    n_ctrl, n_sub, _, rate = grid(scn)
    law = _Law(scn)
    pp, act = scn.plant, scn.actuators
    X = _init_states(law, scn, initial_state(scn))
    h = 1.0 / (rate * n_sub)

    def f(t: float, X: np.ndarray):
        u, tel, dXc = law.evaluate(t, X)
        _, accel, _ = actuators.wheel_accel(act, t, u, X[6:10])
        dX = np.empty(27)
        dX[0:10] = plant.derivative(t, X[0:10], accel, pp)
        dX[10:27] = dXc
        return dX

    traj = {k: np.full((n_ctrl + 1, w), np.nan) for k, w in (
        ("sigma_BN", 3), ("omega_BN_B", 3), ("wheel_speed", 4), ("u_cmd", 4), ("u_sat", 4),
        ("wheel_accel", 4), ("delta2", 3), ("sigma_DN", 3), ("sigma_BD", 3), ("omega_BD_B", 3),
        ("chi", 3), ("lam", 3), ("z1", 3), ("z2", 3))}
    traj["t"] = np.full(n_ctrl + 1, np.nan)
    rows, diverged = 0, False
    for k in range(n_ctrl + 1):
        t = k / rate
        u, tel, _ = law.evaluate(t, X)
        u_sat, accel, _ = actuators.wheel_accel(act, t, u, X[6:10])
        traj["t"][k] = t
        traj["sigma_BN"][k], traj["omega_BN_B"][k], traj["wheel_speed"][k] = X[0:3], X[3:6], X[6:10]
        traj["u_cmd"][k], traj["u_sat"][k] = u, np.clip(u, law.umin, law.umax)
        traj["wheel_accel"][k] = accel
        traj["delta2"][k] = plant.lumped_disturbance(pp, t, X[0:10], u_sat, accel)
        for name, v in tel.items():
            traj[name][k] = v
        rows = k + 1
        beat(t)  # a step done: for a parent watching a contained run (sc_rt.isolate)
        if k == n_ctrl:
            break
        for j in range(n_sub):
            tj = t + j * h
            k1 = f(tj, X)
            k2 = f(tj + h / 2, X + h / 2 * k1)
            k3 = f(tj + h / 2, X + h / 2 * k2)
            k4 = f(tj + h, X + h * k3)
            X = X + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            for a in (0, 10):  # shadow sets of the plant's and the guidance's MRPs
                X[a:a + 3] = np.asarray(_core.mrp_short(X[a:a + 3]))
        if not np.all(np.isfinite(X)):
            diverged = True
            break
    return traj, rows, diverged
