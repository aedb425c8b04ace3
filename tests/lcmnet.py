"""Run a command where LCM multicast works: in a private network namespace
with the multicast route on lo when this process may create one (root),
otherwise on the host loopback (the URLs use ttl=0: nothing leaves)."""

from __future__ import annotations

import functools
from pathlib import Path
import shlex
import subprocess


@functools.lru_cache(maxsize=1)
def can_unshare() -> bool:
    try:
        r = subprocess.run(["unshare", "-n", "sh", "-c",
                            "ip link set lo up && ip route add 224.0.0.0/4 dev lo"],
                           capture_output=True, timeout=10)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return r.returncode == 0


@functools.lru_cache(maxsize=1)
def host_has_multicast_route() -> bool:
    r = subprocess.run(["ip", "route", "get", "239.255.76.67"], capture_output=True)
    return r.returncode == 0


def lcm_available() -> bool:
    return can_unshare() or host_has_multicast_route()


def wrap(cmd: list[str]) -> list[str]:
    """cmd, run inside a fresh network namespace when possible."""
    if not can_unshare():
        return cmd
    inner = "ip link set lo up && ip route add 224.0.0.0/4 dev lo && exec " + shlex.join(cmd)
    return ["unshare", "-n", "sh", "-c", inner]


ROOT = Path(__file__).resolve().parent.parent


def require() -> None:
    """Fail (never skip) when LCM cannot run here: CI is root with namespaces."""
    import pytest

    if not lcm_available():  # pragma: no cover
        pytest.fail("LCM needs a multicast route or permission to create a network namespace",
                    pytrace=False)


def run(cmd: list[str], *, timeout: float = 300, env=None, netns: bool = True) -> subprocess.CompletedProcess:
    """cmd from the repository root, in a network namespace (when netns and
    possible) and its own process group, killed whole on a timeout."""
    import os
    import signal

    import pytest

    full = wrap(cmd) if netns else cmd
    p = subprocess.Popen(full, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                         start_new_session=True, env=env)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        out, err = p.communicate()
        pytest.fail(f"{' '.join(cmd)[:200]} did not finish in {timeout} s:\n{err[-3000:]}")
    return subprocess.CompletedProcess(full, p.returncode, out, err)


def run_script(script: str, *, timeout: float = 300, env=None) -> subprocess.CompletedProcess:
    """A shell script, all its processes in one network namespace."""
    return run(["sh", "-c", script], timeout=timeout, env=env)


def run_cli(args: list[str], *, timeout: float = 300, netns: bool = True) -> subprocess.CompletedProcess:
    """`sc-rt ARGS` through this interpreter (see run)."""
    import sys

    return run([sys.executable, "-m", "sc_rt.cli", *args], timeout=timeout, netns=netns)


def cli_memq(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    """`sc-rt ARGS` with LCM in-process (``memq://``, SCRT_LCM_URL): a command
    that publishes to no one (its own checks, its messages, no echo)."""
    import os
    import sys

    return subprocess.run([sys.executable, "-m", "sc_rt.cli", *args], capture_output=True, text=True, cwd=ROOT,
                          env=dict(os.environ, SCRT_LCM_URL="memq://"), timeout=timeout)


def two_emulators(emu: str, url: str, url2: str, logs) -> str:
    """The head of a fault test's script: the emulator command ``emu`` started
    twice in the background, on ``url`` accepting fault commands ($E1) and on
    ``url2`` not ($E2), logs in the directory ``logs``; it goes on once both
    publish states (tests/buswait.py). The script ends with
    ``kill -INT $E1 $E2; wait``."""
    import sys

    wait = f"{shlex.quote(sys.executable)} {shlex.quote(str(ROOT / 'tests' / 'buswait.py'))}"
    return f"""
{emu} --accept-fault-commands --lcm-url '{url}' > {logs}/emu1.log 2>&1 &
E1=$!
{emu} --lcm-url '{url2}' > {logs}/emu2.log 2>&1 &
E2=$!
{wait} '{url}' state 60 > /dev/null && {wait} '{url2}' state 60 > /dev/null
"""


def realtime_outcome(r: subprocess.CompletedProcess, out: Path) -> bool:
    """A real-time run's exit: 0, or 1 only because it did not keep real time
    under this machine's load (the bench judged it so, rightly: whether it
    keeps real time is not what such a test is about; docs/HIL.md "When a run
    is valid"). True when it kept real time; anything else fails the test."""
    import json

    if r.returncode == 0:
        return True
    why = str(json.loads((Path(out) / "metrics.json").read_text()).get("invalid_reason") or "")
    assert r.returncode == 1 and why.startswith("did not keep real time"), r.stderr[-3000:] + r.stdout[-3000:]
    return False
