"""A forger for the authentication test: knows the protocol (it strips the
32-byte trailer, decodes the states) but not the key. For each genuine state
it hears it publishes a command answering it and a state of its own, with a
tag under a wrong key, and the same without a tag.

    python forge_lcm.py URL OUT.json      (until SCRT_WAIT_PID ends)
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import sys

import lcm
import sc_rt_lcm

WRONG = b"not the bench's key"


def tagged(ch: str, data: bytes) -> bytes:
    return data + hmac.new(WRONG, ch.encode() + b"\0" + data, hashlib.sha256).digest()


def handle_until_bench_ends(lc) -> None:
    """Handle ``lc``'s messages until the process $SCRT_WAIT_PID (the bench
    under attack) has ended (gone, or a zombie its shell has not reaped)."""
    pid = int(os.environ["SCRT_WAIT_PID"])
    while True:
        lc.handle_timeout(50)
        try:
            with open(f"/proc/{pid}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] == "Z":
                    return
        except OSError:
            return


def main(url: str, out: str) -> int:
    lc = lcm.LCM(url)
    sent = {"SCRT_CMD": 0, "SCRT_STATE": 0}
    heard = [0]

    def on_state(ch, data):
        try:
            st = sc_rt_lcm.plant_state_t.decode(data[:-32])
        except Exception:
            return  # one of ours, or not a state
        if st.session == 12345:
            return
        heard[0] += 1
        c = sc_rt_lcm.wheel_cmd_t()
        c.seq, c.session, c.state_seq, c.t = 10**6 + st.seq, st.session ^ 1, st.seq, st.t
        c.u_cmd = [0.1, -0.1, 0.1, -0.1]
        c.u_sat = list(c.u_cmd)
        c.mode = 1
        s = sc_rt_lcm.plant_state_t()
        s.seq, s.session, s.t = st.seq + 1, 12345, st.t
        s.sigma_BN = [0.3, 0.0, 0.0]
        s.omega_BN_B = [0.01, 0.0, 0.0]
        for chan, m in (("SCRT_CMD", c), ("SCRT_STATE", s)):
            raw = m.encode()
            lc.publish(chan, tagged(chan, raw))
            lc.publish(chan, raw)
            sent[chan] += 2

    lc.subscribe("SCRT_STATE", on_state).set_queue_capacity(100_000)
    handle_until_bench_ends(lc)
    with open(out, "w") as f:
        json.dump({"sent": sent, "heard": heard[0]}, f)
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
