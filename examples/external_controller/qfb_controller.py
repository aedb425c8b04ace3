"""An external controller: quaternion feedback over LCM, sc_rt_lcm types only.

    python qfb_controller.py CONFIG      (or env SCRT_CONFIG; sc-rt config SCENARIO --out CONFIG)

Env: SCRT_LCM_URL (bus), SCRT_PREFIX (channel prefix). Answers every plant_state_t
with a wheel_cmd_t (same seq answered again when re-sent), using the guidance_t of
the same seq; announces itself with controller_info_t; sends no status.
"""
import os, secrets, signal, sys, time
import lcm, numpy as np
from sc_rt_lcm import controller_config_t, controller_info_t, guidance_t, plant_state_t, wheel_cmd_t

P = os.environ.get("SCRT_PREFIX", "")
cfg = controller_config_t.decode(open(sys.argv[1] if len(sys.argv) > 1 else os.environ["SCRT_CONFIG"], "rb").read())
J0, Cbar, Jw = np.array(cfg.J0), np.array(cfg.Cbar), np.array(cfg.Jw)
B_pinv = np.linalg.pinv(-np.linalg.solve(J0, Cbar * Jw))     # u = B+ v, B = -J0^-1 Cbar Jw
umin, umax = np.array(cfg.umin), np.array(cfg.umax)
table = dict(zip(cfg.law_param_keys, cfg.law_param_values)) if set(cfg.law_param_len) <= {1} else {}
KP, KD = table.get("kp", 0.5 * 0.05693), table.get("kd", 0.2386)  # the law's table, else the PD's defaults
lc, session = lcm.LCM(os.environ.get("SCRT_LCM_URL", "")), secrets.randbits(62)
st = {"seq": 0, "plant": None, "guid": {}, "last": None}

def mrp_sub(s, d):  # sigma_BD from sigma_BN and sigma_DN (Schaub & Junkins), short rotation
    ss, dd = s @ s, d @ d
    x = (1 - dd) * s - (1 - ss) * d + 2 * np.cross(s, d)
    r = x / (1 + ss * dd + 2 * (d @ s))
    return -r / (r @ r) if r @ r > 1 else r

def dcm(s):  # R_BD of an MRP
    t, ss = np.array([[0, -s[2], s[1]], [s[2], 0, -s[0]], [-s[1], s[0], 0]]), s @ s
    return np.eye(3) + (8 * t @ t - 4 * (1 - ss) * t) / (1 + ss) ** 2

def announce():
    m = controller_info_t()
    m.utime, m.session, m.protocol = int(time.time() * 1e6), session, controller_info_t.PROTOCOL_VERSION
    m.sends_status, m.law, m.description = False, "quaternion-feedback", "examples/external_controller"
    lc.publish(P + "SCRT_CTRL_INFO", m.encode())

def on_guidance(_ch, data):
    g = guidance_t.decode(data)
    st["guid"] = {g.seq: g}  # the newest only

def on_state(_ch, data):
    s = plant_state_t.decode(data)
    if s.session != st["plant"]:  # a new plant (run): announce, start afresh
        st["plant"], st["last"] = s.session, None
        announce()
    elif st["last"] is not None and s.seq <= st["last"][0]:  # re-sent or old
        if s.seq == st["last"][0]:
            publish(*st["last"])
        return
    g = st["guid"].get(s.seq)
    if g is None:
        return  # no reference for this state: the emulator sends it again
    x1 = mrp_sub(np.array(s.sigma_BN), np.array(g.sigma_DN))
    x2 = np.array(s.omega_BN_B) - dcm(x1) @ np.array(g.omega_DN_D)
    x1x1 = x1 @ x1
    q0, qv = (1 - x1x1) / (1 + x1x1), 2 * x1 / (1 + x1x1)
    u = -B_pinv @ (KP * np.copysign(1.0, q0) * qv + KD * x2)
    st["last"] = (s.seq, s.t, u)
    publish(*st["last"])

def publish(seq, t, u):
    c = wheel_cmd_t()
    c.utime, c.seq, c.session, c.state_seq, c.t = int(time.time() * 1e6), st["seq"], session, seq, t
    sat = np.clip(u, umin, umax)
    c.u_cmd, c.u_sat, c.mode = list(u), list(sat), wheel_cmd_t.MODE_NORMAL
    c.flags = sum(wheel_cmd_t.FLAG_SAT_1 << i for i in range(4) if sat[i] != u[i])
    st["seq"] += 1
    lc.publish(P + "SCRT_CMD", c.encode())

lc.subscribe(P + "SCRT_GUIDANCE", on_guidance)
lc.subscribe(P + "SCRT_STATE", on_state).set_queue_capacity(1000)
announce()
print("qfb_controller: listening", file=sys.stderr, flush=True)
signal.signal(signal.SIGINT, signal.SIG_DFL)  # Ctrl-C: just stop
while True:
    lc.handle()
