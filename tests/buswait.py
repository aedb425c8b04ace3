"""Wait for an event on the LCM bus, for the shell scripts of the LCM tests
(an event with a long timeout, never a fixed sleep).

    python buswait.py URL state TIMEOUT          a plant_state_t on SCRT_STATE
    python buswait.py URL cmd TIMEOUT            a wheel_cmd_t on SCRT_CMD
    python buswait.py URL stuck WHEEL N TIMEOUT  N plant_truth_t reporting WHEEL (1-based) stuck

Prints the simulation time of the last message it used (plant_state_t.t,
plant_truth_t.t; for cmd the newest state's) and exits 0; exits 1 with a
message after TIMEOUT seconds, or as soon as the process SCRT_WAIT_PID names
(when set: the run being waited on) has ended."""

from __future__ import annotations

import os
import sys
import time

import lcm
import sc_rt_lcm


def _alive(pid: int) -> bool:
    """Whether pid runs (a zombie, exited but not reaped, does not)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def main(argv: list[str]) -> int:
    url, what = argv[0], argv[1]
    t_sim: list[float] = []
    done = [False]
    lc = lcm.LCM(url)
    if what == "stuck":
        wheel, n, timeout = int(argv[2]) - 1, int(argv[3]), float(argv[4])
        seen = [0]

        def on_truth(_c, d):
            try:
                m = sc_rt_lcm.plant_truth_t.decode(d)
            except Exception:
                return
            if m.fault_stuck[wheel]:
                seen[0] += 1
                t_sim.append(m.t)
                done[0] = seen[0] >= n

        lc.subscribe("SCRT_TRUTH", on_truth)
    else:
        timeout = float(argv[2])

        def on_state(_c, d):
            try:
                t_sim.append(sc_rt_lcm.plant_state_t.decode(d).t)
            except Exception:
                return
            done[0] = done[0] or what == "state"

        def on_cmd(_c, _d):
            done[0] = bool(t_sim)

        lc.subscribe("SCRT_STATE", on_state)
        if what == "cmd":
            lc.subscribe("SCRT_CMD", on_cmd)
    end = time.monotonic() + timeout
    watched = os.environ.get("SCRT_WAIT_PID")
    while not done[0]:
        gone = watched is not None and not _alive(int(watched))
        if gone or time.monotonic() > end:
            why = "the run has ended" if gone else f"in {timeout} s"
            print(f"buswait: no {' '.join(argv[1:-1])} on {url}: {why}", file=sys.stderr)
            return 1
        lc.handle_timeout(50)
    print(t_sim[-1])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
