"""A forger without the key that tries the sequence numbers (issue 40 item 2):

    python seqjump_lcm.py URL MODE OUT.json      (until SCRT_WAIT_PID ends)

- ``state``: at the 200th genuine plant state it hears, one copy of it with
  seq + 10^6 (the plant's session): were it taken as the newest, the
  controller would drop every genuine state after it.
- ``state_in_window``: the same with seq + 999, inside the window of 1000
  that a plant which lost states may jump: taken as the newest, so the
  genuine states after it are out of order until they pass it.
- ``cmd``: at the 200th genuine command, one copy with seq + 10^6 and the
  command [9, -7, 9, -7] (the controller's session), for the plant side.
- ``race``: from the 200th genuine state on, for each state a command
  answering it with the controller's session and the next command seq,
  [9, -7, 9, -7], racing the controller's own.
"""

from __future__ import annotations

import json
import sys

import lcm
import sc_rt_lcm

from forge_lcm import handle_until_bench_ends

FORGED_U = [9.0, -7.0, 9.0, -7.0]
AT = 200


def main(url: str, mode: str, out: str) -> int:
    lc = lcm.LCM(url)
    sent = {"SCRT_STATE": 0, "SCRT_CMD": 0}
    heard = {"SCRT_STATE": 0, "SCRT_CMD": 0}
    last_cmd: list = [None]

    def on_state(ch, data):
        try:
            st = sc_rt_lcm.plant_state_t.decode(data)
        except Exception:
            return
        heard[ch] += 1
        if mode in ("state", "state_in_window") and heard[ch] == AT:
            st.seq += 10**6 if mode == "state" else 999
            lc.publish(ch, st.encode())
            sent[ch] += 1
        elif mode == "race" and heard[ch] >= AT and last_cmd[0] is not None:
            c = last_cmd[0]
            f = sc_rt_lcm.wheel_cmd_t()
            f.seq, f.session, f.state_seq, f.t = c.seq + 1, c.session, st.seq, st.t
            f.u_cmd, f.u_sat, f.mode = FORGED_U, FORGED_U, 1
            lc.publish("SCRT_CMD", f.encode())
            sent["SCRT_CMD"] += 1

    def on_cmd(ch, data):
        try:
            c = sc_rt_lcm.wheel_cmd_t.decode(data)
        except Exception:
            return
        if list(c.u_cmd) == FORGED_U:
            return  # our own, looped back
        heard[ch] += 1
        last_cmd[0] = c
        if mode == "cmd" and heard[ch] == AT:
            c.seq += 10**6
            c.u_cmd, c.u_sat = FORGED_U, FORGED_U
            lc.publish(ch, c.encode())
            sent[ch] += 1

    lc.subscribe("SCRT_STATE", on_state).set_queue_capacity(100_000)
    lc.subscribe("SCRT_CMD", on_cmd).set_queue_capacity(100_000)
    handle_until_bench_ends(lc)
    with open(out, "w") as f:
        json.dump({"sent": sent, "heard": heard}, f)
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:4]))
