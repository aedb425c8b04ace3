"""Run a command where LCM multicast works: in a private network namespace
with the multicast route on lo when this process may create one (root),
otherwise on the host loopback (the URLs use ttl=0: nothing leaves)."""

from __future__ import annotations

import functools
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
