"""Independent numpy re-implementations used by the tests as references.

Written from docs/MODEL.md, not from the C++ sources: attitude via quaternions
and rotation matrices, the control laws term by term.
"""

from __future__ import annotations

import numpy as np


def skew(x):
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


def mrp_to_quat(s):
    """MRP -> unit quaternion (q0 scalar first)."""
    s = np.asarray(s, float)
    ss = s @ s
    return np.concatenate([[(1 - ss) / (1 + ss)], 2 * s / (1 + ss)])


def quat_to_dcm(q):
    """Unit quaternion (scalar first) -> DCM [BN] mapping N components to B."""
    q0, q1, q2, q3 = q
    return np.array(
        [
            [q0**2 + q1**2 - q2**2 - q3**2, 2 * (q1 * q2 + q0 * q3), 2 * (q1 * q3 - q0 * q2)],
            [2 * (q1 * q2 - q0 * q3), q0**2 - q1**2 + q2**2 - q3**2, 2 * (q2 * q3 + q0 * q1)],
            [2 * (q1 * q3 + q0 * q2), 2 * (q2 * q3 - q0 * q1), q0**2 - q1**2 - q2**2 + q3**2],
        ]
    )


def dcm_to_quat(C):
    """Shepperd's method: DCM -> unit quaternion with q0 >= 0."""
    tr = np.trace(C)
    b2 = np.array(
        [(1 + tr) / 4, (1 + 2 * C[0, 0] - tr) / 4, (1 + 2 * C[1, 1] - tr) / 4, (1 + 2 * C[2, 2] - tr) / 4]
    )
    i = int(np.argmax(b2))
    q = np.zeros(4)
    if i == 0:
        q[0] = np.sqrt(b2[0])
        q[1] = (C[1, 2] - C[2, 1]) / (4 * q[0])
        q[2] = (C[2, 0] - C[0, 2]) / (4 * q[0])
        q[3] = (C[0, 1] - C[1, 0]) / (4 * q[0])
    elif i == 1:
        q[1] = np.sqrt(b2[1])
        q[0] = (C[1, 2] - C[2, 1]) / (4 * q[1])
        q[2] = (C[0, 1] + C[1, 0]) / (4 * q[1])
        q[3] = (C[2, 0] + C[0, 2]) / (4 * q[1])
    elif i == 2:
        q[2] = np.sqrt(b2[2])
        q[0] = (C[2, 0] - C[0, 2]) / (4 * q[2])
        q[1] = (C[0, 1] + C[1, 0]) / (4 * q[2])
        q[3] = (C[1, 2] + C[2, 1]) / (4 * q[2])
    else:
        q[3] = np.sqrt(b2[3])
        q[0] = (C[0, 1] - C[1, 0]) / (4 * q[3])
        q[1] = (C[2, 0] + C[0, 2]) / (4 * q[3])
        q[2] = (C[1, 2] + C[2, 1]) / (4 * q[3])
    return q if q[0] >= 0 else -q


def quat_to_mrp(q):
    return np.asarray(q[1:]) / (1 + q[0])


def dcm_to_mrp(C):
    """DCM -> MRP of the short rotation (|sigma| <= 1)."""
    return quat_to_mrp(dcm_to_quat(C))


def mrp_dcm(s):
    return quat_to_dcm(mrp_to_quat(s))


def rotation_exp(w, h):
    """exp(-[w x] h) by Rodrigues' formula: DCM increment for body rate w over h."""
    th = np.linalg.norm(w) * h
    if th == 0:
        return np.eye(3)
    k = w / np.linalg.norm(w)
    K = skew(k)
    return np.eye(3) - np.sin(th) * K + (1 - np.cos(th)) * K @ K


# --- the controller's math, term by term from docs/MODEL.md -----------------

def G(s):
    s = np.asarray(s, float)
    return 0.25 * ((1 - s @ s) * np.eye(3) + 2 * skew(s) + 2 * np.outer(s, s))


def R(s):
    """(10) written out."""
    s = np.asarray(s, float)
    ss = s @ s
    S = skew(s)
    return np.eye(3) + (8 * S @ S - 4 * (1 - ss) * S) / (1 + ss) ** 2


def mrp_sub(s, sd):
    """(8) with the short-rotation mapping."""
    ss, sdsd = s @ s, sd @ sd
    num = sd * (ss - 1) + s * (1 - sdsd) - 2 * np.cross(sd, s)
    den = 1 + ss * sdsd + 2 * sd @ s
    e = num / den
    return -e / (e @ e) if e @ e > 1 else e


def omega_d(g, t):
    w = g["freq"]
    return g["bias"] + g["cos"] * np.cos(w * t) + g["sin"] * np.sin(w * t)


def omega_d_dot(g, t):
    w = g["freq"]
    return w * (-g["cos"] * np.sin(w * t) + g["sin"] * np.cos(w * t))


def guidance_step(g, s, t, h):
    f = lambda tt, ss: G(ss) @ omega_d(g, tt)  # noqa: E731
    k1 = f(t, s)
    k2 = f(t + h / 2, s + h / 2 * k1)
    k3 = f(t + h / 2, s + h / 2 * k2)
    k4 = f(t + h, s + h * k3)
    s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return -s / (s @ s) if s @ s > 1 else s


def chi(p, t):
    return (p["chi0"] - p["chiinf"]) * np.exp(-p["gamma"] * t) + p["chiinf"]


def chi_dot(p, t):
    return -p["gamma"] * (p["chi0"] - p["chiinf"]) * np.exp(-p["gamma"] * t)


def ppc(p, x1, t, margin=1e-6):
    c = chi(p, t)
    lam = x1 / c
    dmin, dmax = p["dmin"], p["dmax"]
    m = margin * (dmin + dmax)
    viol = np.zeros(3, bool)
    for i in range(3):
        if not (-dmin[i] < lam[i] < dmax[i]):
            viol[i] = True
        lam[i] = min(max(lam[i], -dmin[i] + m[i]), dmax[i] - m[i])
    eps = 0.5 * np.log((dmin + lam) / (dmax - lam))
    e1 = eps - 0.5 * np.log(dmin / dmax)
    r = 1 / (2 * c) * (1 / (lam + dmin) - 1 / (lam - dmax))
    return dict(chi=c, chi_dot=chi_dot(p, t), lam=lam, eps=eps, e1=e1, r=r, violated=viol)


def sig(v, a):
    return np.sign(v) * np.abs(v) ** a


def neso_rhs(n, z1, z2, A, x2, Bu):
    e = z1 - x2
    d1 = A + Bu + z2 - n["k1"] * sig(e, n["alpha"]) - n["k2"] * e
    d2 = -n["k3"] * sig(e, 2 * n["alpha"] - 1) - n["k4"] * e
    return d1, d2


def neso_update(n, z1, z2, h, A0, A1, x0, x1, Bu, substeps):
    hs = h / substeps
    for k in range(substeps):
        fa, fm, fb = k / substeps, (k + 0.5) / substeps, (k + 1) / substeps
        Aa, Am, Ab = A0 + fa * (A1 - A0), A0 + fm * (A1 - A0), A0 + fb * (A1 - A0)
        xa, xm, xb = x0 + fa * (x1 - x0), x0 + fm * (x1 - x0), x0 + fb * (x1 - x0)
        a1, a2 = neso_rhs(n, z1, z2, Aa, xa, Bu)
        b1, b2 = neso_rhs(n, z1 + hs / 2 * a1, z2 + hs / 2 * a2, Am, xm, Bu)
        c1, c2 = neso_rhs(n, z1 + hs / 2 * b1, z2 + hs / 2 * b2, Am, xm, Bu)
        d1, d2 = neso_rhs(n, z1 + hs * c1, z2 + hs * c2, Ab, xb, Bu)
        z1 = z1 + hs / 6 * (a1 + 2 * b1 + 2 * c1 + d1)
        z2 = z2 + hs / 6 * (a2 + 2 * b2 + 2 * c2 + d2)
    return z1, z2


def model_terms(sc, sigma_BN, omega, wheel, x1, x2, od, odd):
    """A of (21) and R(x1) omega_d."""
    J0, Cbar, Jw, w0 = sc["J0"], sc["Cbar"], sc["Jw"], sc["w0"]
    Rx = R(x1)
    R3 = R(sigma_BN)[:, 2]
    ug0 = 3 * w0**2 * np.cross(R3, J0 @ R3)
    J0i = np.linalg.inv(J0)
    h = J0 @ omega + Cbar @ (Jw * wheel)
    return -J0i @ np.cross(omega, h) + np.cross(x2, Rx @ od) - Rx @ odd + J0i @ ug0


class RefController:
    """numpy re-implementation of the four laws and their discretisation
    (docs/CORE.md): observer with A, x2 linear and B u held over a period,
    exact updates of the filter (37), compensator (42) and RFT gain."""

    def __init__(self, law, sc, g, ppc_p, neso, dsc, pd, rft, rate):
        self.law, self.sc, self.g, self.p = law, sc, g, ppc_p
        self.n, self.dsc, self.pd, self.rft = neso, dsc, pd, rft
        self.max_step = 1.0 / rate
        J0i = np.linalg.inv(sc["J0"])
        self.B = -J0i @ sc["Cbar"] @ np.diag(sc["Jw"])
        self.Bp = self.B.T @ np.linalg.inv(self.B @ self.B.T)

    def _guidance_to(self, t):
        if t <= self.tg:
            return
        span = t - self.tg
        n = max(1, int(np.ceil(span / self.max_step - 1e-9)))
        h = span / n
        for i in range(n):
            self.sd = guidance_step(self.g, self.sd, self.tg + i * h, h)
        self.tg = t

    def _errors(self, m):
        t = m["t"]
        od, odd = omega_d(self.g, t), omega_d_dot(self.g, t)
        x1 = mrp_sub(m["sigma"], self.sd)
        x2 = m["omega"] - R(x1) @ od
        A = model_terms(self.sc, m["sigma"], m["omega"], m["wheel"], x1, x2, od, odd)
        return x1, x2, A

    def _x2bar(self, x1, t_rel):
        Gi = np.linalg.inv(G(x1))
        k1 = self.dsc["k1"]
        if self.law == "dsc":
            return -Gi @ (k1 * x1), x1, np.ones(3)
        q = ppc(self.p, x1, t_rel)
        # (36) as printed: -(r G)^-1 (k1 e1 - r Lambda chi_dot)
        rG = np.diag(q["r"]) @ G(x1)
        xb = -np.linalg.solve(rG, k1 * q["e1"] - q["r"] * q["lam"] * q["chi_dot"])
        return xb, q["e1"], q["r"]

    def reset(self, m):
        self.t0 = self.tprev = m["t"]
        self.tg, self.sd = 0.0, np.array(self.g["sigma_d0"], float)
        self._guidance_to(m["t"])
        self.tg = m["t"]
        self.usat_prev = np.zeros(4)
        self.first = True
        x1, x2, A = self._errors(m)
        if self.law in ("dsc-ppc", "dsc"):
            xb, _, _ = self._x2bar(x1, 0.0)
            self.xbar_prev = xb
            self.x2d = xb.copy()
            self.vs = np.zeros(4)
            self.du_prev = np.zeros(4)
            self.z1 = x2.copy() if self.n.get("init_from_measurement") else np.zeros(3)
            self.z2 = np.zeros(3)
            self.A_prev, self.x2_prev = A, x2
        elif self.law == "rft":
            self.rho = self.rft["rho0"]
            self.s_prev = np.linalg.norm(x2 + self.rft["c"] * x1)

    def step(self, m):
        t = m["t"]
        dt = t - self.tprev
        if dt < 0 or (dt == 0 and not self.first):
            dt = 0.0
        self.first = False
        self._guidance_to(t)
        x1, x2, A = self._errors(m)
        out = dict(sigma_BD=x1, omega_BD_B=x2, sigma_DN=self.sd.copy())
        if self.law in ("dsc-ppc", "dsc"):
            d = self.dsc
            if dt > 0:
                self.z1, self.z2 = neso_update(
                    self.n, self.z1, self.z2, dt, self.A_prev, A, self.x2_prev, x2,
                    self.B @ self.usat_prev, self.n["substeps"])
                a = np.exp(-dt / d["tau"])
                self.x2d = a * self.x2d + (1 - a) * self.xbar_prev
                b = np.exp(-d["k4"] * dt)
                self.vs = b * self.vs + (1 - b) / d["k4"] * self.du_prev
            xb, e1, r = self._x2bar(x1, t - self.t0)
            x2d_dot = (xb - self.x2d) / d["tau"]
            e2 = x2 - self.x2d
            v = -A - d["k2"] * e2 - G(x1).T @ (r * e1) - d["k3"] * self.B @ self.vs - self.z2 + x2d_dot
            u = self.Bp @ v
            out.update(e1=e1, e2=e2, z1=self.z1.copy(), z2=self.z2.copy(), x2d=self.x2d.copy(),
                       vs=self.vs.copy(), x2bar=xb, x2d_dot=x2d_dot, r=r, A=A)
            self.xbar_prev, self.A_prev, self.x2_prev = xb, A, x2
        elif self.law == "pd":
            u = -self.Bp @ (self.pd["beta1"] * x1 + self.pd["beta2"] * x2)
        else:
            c = self.rft
            if dt > 0:
                a = np.exp(-c["leak"] * dt)
                self.rho = a * self.rho + (1 - a) / c["leak"] * c["gain"] * self.s_prev
            s = x2 + c["c"] * x1
            sat = np.clip(s / c["phi"], -1, 1)
            v = -A - c["c"] * G(x1) @ x2 - c["k"] * s - self.rho * sat
            u = self.Bp @ v
            self.s_prev = np.linalg.norm(s)
            out.update(rho_hat=self.rho)
        usat = np.clip(u, self.sc["umin"], self.sc["umax"])
        if self.law in ("dsc-ppc", "dsc"):
            self.du_prev = usat - u
        self.usat_prev = usat
        if dt > 0:
            self.tprev = t
        out.update(u_cmd=u, u_sat=usat)
        return out
