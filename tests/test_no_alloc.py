"""No heap allocation on the controller's step path (issue #31, item 5).

sc-rt-controller-alloc is sc-rt-controller linked with a counting allocator
(cpp/app/alloc_counter.cpp): it replaces the process's malloc family, so
operator new, the statically linked LCM, GLib and a law plugin all go
through it. The shell arms it after a warm-up of 100 steps and reads it at
the end of every later step (cpp/app/alloc_probe.hpp): the count covers
receive, decode, the gate, the sensor intake and its MEKF, the law, encode,
HMAC and publish of every step after the warm-up, in lockstep and in real
time (the receive thread too). Each run here must count zero; a law that
allocates per step proves the counter bites (and that it sees a plugin's
operator new)."""

from __future__ import annotations

import json
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

import lcmnet
from ctlscript import controller_config as _config, wait_for_line as _wait_for

pytestmark = [pytest.mark.slow, pytest.mark.lcm]

ROOT = Path(__file__).resolve().parent.parent
HERE = Path(__file__).resolve().parent
PY = shlex.quote(sys.executable)
CTL = Path(sys.executable).parent / "sc-rt-controller-alloc"
WARMUP = 100  # cpp/app/alloc_probe.hpp: kAllocWarmupSteps


def _run(tmp: Path, scn: str, port: int, *, ctl_args: str = "", emu_args: str = "", duration: float = 10,
         fuzz: int = 0) -> dict:
    """The counting controller against the Python emulator (and a hostile
    publisher when fuzz > 0), in a private network namespace; its summary."""
    lcmnet.require()
    url = f"udpm://239.255.76.67:{port}?ttl=0&recv_buf_size=4194304"
    cfg = _config(scn, tmp / "cfg.bin")
    emu = (f"{PY} -m sc_rt.cli emulator {scn} --lcm-url '{url}' --duration {duration} {emu_args} "
           f"--out {tmp}/emu > {tmp}/emu.log 2>&1")
    if fuzz:
        emu = (f"{emu} &\nEMU=$!\nSCRT_WAIT_PID=$EMU {PY} {HERE / 'fuzz_lcm.py'} '{url}' {fuzz} {tmp}/sent.json 7 "
               f"SCRT_STATE,SCRT_GYRO,SCRT_STAR,SCRT_TACH\nwait $EMU")
    script = f"""
set -e
{shlex.quote(str(CTL))} --config {cfg} --lcm-url '{url}' --summary {tmp}/sum.json {ctl_args} \\
    > /dev/null 2> {tmp}/ctl.err &
CTL=$!
{_wait_for('mode on', tmp / 'ctl.err')}
{emu}
kill -TERM $CTL
wait $CTL
"""
    r = lcmnet.run_script(script, timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:] + (tmp / "ctl.err").read_text()[-3000:]
    return json.loads((tmp / "sum.json").read_text())


def _allocations(s: dict) -> dict:
    a = s["allocations"]
    assert a["after_step"] == WARMUP and a["steps"] == s["steps"] - WARMUP, s
    return a


def _exported(exe: Path) -> set[str]:
    out = subprocess.run(["nm", "-D", "--defined-only", str(exe)], capture_output=True, text=True, check=True)
    return {line.split()[-1] for line in out.stdout.splitlines() if line.strip()}


def test_only_the_alloc_variant_replaces_malloc():
    """The variant exports the malloc family (so the dynamic linker binds
    every library's calls to it); sc-rt-controller does not."""
    family = {"malloc", "calloc", "realloc", "free", "posix_memalign", "aligned_alloc"}
    assert family <= _exported(CTL)
    assert not family & _exported(CTL.parent / "sc-rt-controller")


def test_lockstep_steps_allocate_nothing(tmp_path):
    """A 100 Hz lockstep run of the paper's law: 2,001 steps, none after the
    warm-up allocates."""
    s = _run(tmp_path, "ppc_feasible_100hz", 7761, duration=20)
    assert s["steps"] == 2001, s
    assert _allocations(s)["count"] == 0, s


def test_lockstep_with_sensors_auth_and_a_hostile_publisher_allocates_nothing(tmp_path):
    """The MEKF on the sensor messages (intake queue, propagation, updates),
    every message tagged and verified, and 5,000 malformed, foreign, replayed
    and non-finite messages on the state and sensor channels while it runs."""
    key = tmp_path / "key"
    key.write_bytes(b"the allocation bench's key, 32 b")
    s = _run(tmp_path, "ppc_feasible_100hz_sensors", 7762, ctl_args=f"--auth-key {key}",
             emu_args=f"--auth-key {key}", duration=20, fuzz=5000)
    assert s["auth"] and s["nav"]["gyro_used"] > 0 and s["nav"]["star_used"] > 0, s
    sent = json.loads((tmp_path / "sent.json").read_text())
    assert sent["n"] == 5000, sent
    assert s["auth_failed"] > 0, "the hostile messages reached the controller's checks"
    assert _allocations(s)["count"] == 0, s


def test_lockstep_with_the_magnetometers_samples_and_the_rods_allocates_nothing(tmp_path):
    """Magnetic control fed a magnetometer's samples (SCRT_MAG into the intake, its field
    held, the manager, rod_cmd_t) beside the MEKF: day_hold with [sensors.magnetometer]
    (tests/test_mag_sensor_bus.py's file), 600 steps, none after the warm-up allocates."""
    from test_mag_sensor_bus import _day_hold_sensed

    s = _run(tmp_path, str(_day_hold_sensed(tmp_path)), 7765, duration=60)
    assert s["steps"] == 601 and s["nav"]["mag_used"] == 301, s
    assert s["magnetic"]["field_missing"] == 0, s
    assert _allocations(s)["count"] == 0, s


@pytest.mark.parametrize("trigger, port", [("timer", 7763), ("event", 7764)])
def test_realtime_steps_and_the_receive_thread_allocate_nothing(tmp_path, trigger, port):
    """Real time, both triggers: with the timer, the receive thread fills the
    mailbox and the intake while the step thread steps on its deadlines;
    with the event trigger (the default), each state's arrival steps at once
    in the receiving thread (issue 42 item 6: it ran under no counter)."""
    s = _run(tmp_path, "ppc_feasible_100hz_sensors", port, ctl_args=f"--mode realtime --trigger {trigger}",
             emu_args="--mode realtime", duration=4)
    assert s["mode"] == "realtime" and s["trigger"] == trigger and s["steps"] > 2 * WARMUP, s
    assert _allocations(s)["count"] == 0, s


def test_the_counter_bites_on_a_law_that_allocates(tmp_path, plugins):
    """The same lockstep run with a law that builds a vector and a long
    string at each step (tests/law_plugins/allocates.cpp): at least two
    allocations per counted step."""
    s = _run(tmp_path, "ppc_feasible_100hz", 7764, ctl_args=f"--law-plugin {plugins['allocates']}", duration=5)
    a = _allocations(s)
    assert s["law"] == "t-allocates" and a["steps"] == 401, s
    assert a["count"] >= 2 * a["steps"], s
