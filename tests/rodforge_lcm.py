"""A forger without the key that tries the rods' sequence numbers (issue 43):

    python rodforge_lcm.py URL OUT.json      (until SCRT_WAIT_PID ends)

At the 200th genuine rod command it hears (rod_cmd_t on SCRT_ROD_CMD), one
copy with seq + 10^6 (the controller's session, the state it answers) and
the dipoles FORGED_D: were it taken as the newest, every genuine rod command
after it would be "out of order" and the plant would hold the forged dipoles.
"""

from __future__ import annotations

import json
import sys

import lcm
import sc_rt_lcm

from forge_lcm import handle_until_bench_ends

FORGED_D = [29.0, -29.0, 29.0, 0.0, 0.0, 0.0]
AT = 200


def main(url: str, out: str) -> int:
    lc = lcm.LCM(url)
    sent = heard = 0

    def on_rod(ch, data):
        nonlocal sent, heard
        try:
            r = sc_rt_lcm.rod_cmd_t.decode(data)
        except Exception:
            return
        if list(r.dipole) == FORGED_D:
            return  # our own, looped back
        heard += 1
        if heard == AT:
            r.seq += 10**6
            r.dipole = FORGED_D
            lc.publish(ch, r.encode())
            sent += 1

    lc.subscribe("SCRT_ROD_CMD", on_rod).set_queue_capacity(100_000)
    handle_until_bench_ends(lc)
    with open(out, "w") as f:
        json.dump({"sent": sent, "heard": heard}, f)
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
