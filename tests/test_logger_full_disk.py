"""sc-rt-logger stops at its first failed write (issue 40 item 5): on a
disk that fills it says so in one line and exits 1 at once, so that the bench,
which watches it, stops the run within its poll (0.25 s) instead of going
on with a log that no longer grows. Before, it counted its write errors and
went on. A tmpfs of 64 kB in a private mount and network namespace."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import lcmnet

BIN = Path(sys.executable).parent / "sc-rt-logger"
PY = sys.executable


@pytest.mark.lcm
def test_the_logger_stops_at_its_first_failed_write(tmp_path):
    lcmnet.require()
    if not lcmnet.can_unshare():
        pytest.fail("needs root for a private mount namespace (CI runs as root)")
    d = tmp_path / "small"
    url = "udpm://239.255.76.67:7991?ttl=0"
    pub = (f"import lcm, time\nlc = lcm.LCM('{url}')\n"
           "for i in range(20000):\n    lc.publish('SCRT_X', bytes(1000))\n")
    inner = (f"ip link set lo up && ip route add 224.0.0.0/4 dev lo && mkdir -p {d} && "
             f"mount -t tmpfs -o size=64k tmpfs {d} && "
             f"{{ {BIN} --lcm-url '{url}' {d}/run.lcmlog 2> {tmp_path}/logger.err & }} && L=$! && "
             f"{PY} -c \"{pub}\" && "
             # the logger has stopped by itself (it is not signalled): 60 s at most
             f"for i in $(seq 600); do kill -0 $L 2>/dev/null || break; sleep 0.1; done; "
             f"kill -0 $L 2>/dev/null && {{ echo still-running; kill $L; }}; "
             f"wait $L; echo rc=$?")
    r = subprocess.run(["unshare", "-m", "-n", "sh", "-c", inner], capture_output=True, text=True, timeout=120)
    err = (tmp_path / "logger.err").read_text()
    assert "rc=1" in r.stdout, r.stdout + r.stderr + err
    assert "sc-rt-logger: cannot write the log (No space left on device): stopping" in err, err
