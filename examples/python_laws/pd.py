"""The PD baseline as a Python law: u = -B+ (beta1 sigma_BD + beta2 omega_BD_B).

The same law as the core's built-in "pd" (cpp/src/law_pd.cpp), its gains from
its own table ([laws.python-pd] of the scenario) with the built-in PD's
defaults; `sc-rt sim --law pd` and
`sc-rt sim --law examples/python_laws/pd.py:PythonPD` agree to 1e-12.
"""

import numpy as np

#: the built-in PD's defaults (cpp/src/law_pd.cpp), to run the same law
PD_DEFAULTS = {"beta1": 0.05693, "beta2": 0.2386}


class PythonPD:
    name = "python-pd"

    def __init__(self, setup):
        self.B_pinv = setup.model.B_pinv
        # [laws.python-pd] beta1, beta2; default: the built-in PD's
        self.beta1 = setup.params.get("beta1", PD_DEFAULTS["beta1"])
        self.beta2 = setup.params.get("beta2", PD_DEFAULTS["beta2"])

    def reset(self, inp):
        pass

    def step(self, inp):
        x1, x2 = inp.e.sigma_BD, inp.e.omega_BD_B
        u = -self.B_pinv @ (self.beta1 * x1 + self.beta2 * x2)
        return u, {"e1": x1, "e2": x2}


class QuaternionFeedback:
    """Quaternion feedback (Wie): u = -B+ (Kp q_v sign(q0) + Kd omega_BD_B)
    on the error quaternion of sigma_BD; gains from its table ([laws.quaternion-feedback]),
    by default from the built-in PD's."""

    name = "quaternion-feedback"

    def __init__(self, setup):
        self.B_pinv = setup.model.B_pinv
        self.kp = setup.params.get("kp", 0.5 * PD_DEFAULTS["beta1"])
        self.kd = setup.params.get("kd", PD_DEFAULTS["beta2"])

    def reset(self, inp):
        pass

    def step(self, inp):
        s = inp.e.sigma_BD
        s2 = float(s @ s)
        q0, qv = (1.0 - s2) / (1.0 + s2), 2.0 * s / (1.0 + s2)
        return -self.B_pinv @ (self.kp * np.copysign(1.0, q0) * qv + self.kd * inp.e.omega_BD_B)
