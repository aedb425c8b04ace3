"""LCM plumbing shared by the emulator, the HIL runner, the monitor and the
report: URLs, channel names, guarded decoding, the wheel's real binaries."""

from __future__ import annotations

import os
import socket
from pathlib import Path

import lcm

from sc_rt import _core

__all__ = ["DEFAULT_URL", "CHANNELS", "channel", "lcm_prefix", "lcm_binary",
           "free_port_url", "open_lcm"]

#: Nothing leaves the machine: ttl=0.
#: The default URL of every process (one constant for both languages: the
#: C++ processes' cpp/shell/defaults.hpp, through the bindings).
DEFAULT_URL: str = _core.DEFAULT_LCM_URL

#: Channel -> (LCM type name, who publishes, rate).
CHANNELS = {
    "SCRT_STATE": ("plant_state_t", "emulator", "one per plant publish period"),
    "SCRT_CMD": ("wheel_cmd_t", "controller", "one per control step"),
    "SCRT_TRUTH": ("plant_truth_t", "emulator", "one per plant state"),
    "SCRT_CTRL_STATUS": ("controller_status_t", "controller", "one per control step"),
    "SCRT_FAULT": ("fault_cmd_t", "sc-rt fault", "on demand"),
    "SCRT_ROD_FAULT": ("rod_fault_cmd_t", "sc-rt fault --rod", "on demand"),
    "SCRT_CONFIG": ("controller_config_t", "sc-rt hil", "once at start (controller --config-channel)"),
    "SCRT_GUIDANCE": ("guidance_t", "emulator", "one per plant state, just before it (same seq)"),
    "SCRT_CTRL_INFO": ("controller_info_t", "controller",
                       "optional: at start and at each new plant session"),
    "SCRT_GYRO": ("gyro_t", "emulator", "[sensors.gyro] rate_hz, before the state of its step"),
    "SCRT_STAR": ("star_tracker_t", "emulator",
                  "[sensors.star_tracker] rate_hz, at delivery (exposure + latency)"),
    "SCRT_TACH": ("tachometer_t", "emulator", "[sensors.tachometer] rate_hz"),
    "SCRT_MAG": ("magnetometer_t", "emulator",
                 "magnetic control: the field at each state's instant, just before it (same seq)"),
    "SCRT_ROD_CMD": ("rod_cmd_t", "controller",
                     "magnetic control: one per command, just before its wheel_cmd_t (same seq)"),
    "SCRT_LOG_ACK": ("log_ack_t", "sc-rt-logger",
                     "sc-rt hil: after every 8 states written to the log (not logged, not authenticated)"),
}


def channel(name: str, prefix: str = "") -> str:
    if name not in CHANNELS:
        raise KeyError(f"unknown sc-rt channel {name!r}")
    return prefix + name


def lcm_prefix() -> Path:
    """The folder of the lcm wheel holding bin/, lib/, share/java."""
    return Path(lcm.__file__).resolve().parent.parent


def lcm_binary(name: str) -> str:
    """The real binary inside the wheel (the venv's bin/ has Python wrappers
    that orphan the tool on SIGTERM)."""
    p = lcm_prefix() / "bin" / name
    if not p.exists():
        raise FileNotFoundError(f"{name} not found in the lcm wheel at {p}")
    return str(p)


#: Socket receive buffer asked for on the URLs the bench makes [bytes]: a
#: lockstep run publishes ~20,000 messages/s, and lcm-logger on a loaded
#: machine falls behind a default 208 kB buffer (seen: 50 of 201 states lost).
#: The kernel caps it at net.core.rmem_max.
RECV_BUF_SIZE = 4_194_304


def free_port_url(ttl: int = 0, group: str = "239.255.76.67") -> str:
    """A udpm URL on a port free on this machine, so parallel runs never
    cross, with room in every subscriber's socket buffer."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        port = s.getsockname()[1]
    return f"udpm://{group}:{port}?ttl={ttl}&recv_buf_size={RECV_BUF_SIZE}"


def open_lcm(url: str) -> lcm.LCM:
    try:
        return lcm.LCM(url)
    except RuntimeError as e:
        raise RuntimeError(
            f"cannot start LCM on {url}: {e}. LCM needs a multicast route: as root, "
            "`ip route add 224.0.0.0/4 dev lo` (the tests do it in a private network "
            "namespace)") from e


def env_url() -> str:
    return os.environ.get("SCRT_LCM_URL", DEFAULT_URL)
