"""Drive a real-time sc-rt-controller with states at 100 Hz, pause 0.5 s,
resume; record every command and status it sends (the status carries the
controller's own measurement of the state's age at each step) and the seqs
of the last state before the pause and the first after it.
Usage: stale_driver.py URL CFG OUT.json"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time

import lcm
import numpy as np
import sc_rt_lcm

from sc_rt.hil.procs import controller_binary

url, cfg, out = sys.argv[1:4]
ctl = subprocess.Popen([controller_binary(), "--config", cfg, "--mode", "realtime", "--trigger", "timer",
                        "--lcm-url", url,
                        "--summary", out + ".summary"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
ctl.stderr.readline()
lc = lcm.LCM(url)
cmds = []
status = []
lc.subscribe("SCRT_CMD", lambda c, d: cmds.append((time.monotonic(), sc_rt_lcm.wheel_cmd_t.decode(d))))
lc.subscribe("SCRT_CTRL_STATUS", lambda c, d: status.append(sc_rt_lcm.controller_status_t.decode(d)))
stop = threading.Event()
th = threading.Thread(target=lambda: [lc.handle_timeout(20) for _ in iter(stop.is_set, True)], daemon=True)
th.start()
sigma = np.array([0.323, -0.194, -0.388])
omega = np.array([-0.01, 0.02, -0.03])
t0 = time.monotonic()
phases = []
seq = 0


def publish_for(seconds: float) -> None:
    global seq
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        m = sc_rt_lcm.plant_state_t()
        m.seq, m.session, m.t = seq, 42, seq * 0.01
        m.sigma_BN, m.omega_BN_B, m.wheel_speed = list(sigma), list(omega), [0.0] * 4
        lc.publish("SCRT_STATE", m.encode())
        seq += 1
        time.sleep(0.01)


publish_for(1.0)
phases.append(("pause_start", time.monotonic() - t0))
seq_pause = seq - 1
time.sleep(0.5)
phases.append(("resume", time.monotonic() - t0))
seq_resume = seq
publish_for(1.0)
phases.append(("end", time.monotonic() - t0))
time.sleep(0.05)
ctl.terminate()
ctl.wait(5)
stop.set()
rows = [{"t": tt - t0, "seq": c.seq, "mode": c.mode, "flags": c.flags, "state_seq": c.state_seq,
         "u": list(c.u_cmd)} for tt, c in cmds]
st = [{"cmd_seq": s.cmd_seq, "mode": s.mode, "flags": s.flags, "state_seq": s.state_seq,
       "state_age_us": s.state_age_us, "u": list(s.u_cmd)} for s in status]
json.dump({"phases": dict(phases), "seq_pause": seq_pause, "seq_resume": seq_resume, "cmds": rows,
           "status": st, "summary": json.load(open(out + ".summary"))}, open(out, "w"))
