"""The bench's child processes (``sc-rt hil``): where its binaries are, how a
child is started (its own process group, SIGTERM when sc-rt dies) and
stopped, ``Stopper`` (why a run should stop early: a signal, the logger or
the controller gone), and lcm-logger's start probe, priority and end marker."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from sc_rt.plan.timing import CONTROLLER_MEMORY_LIMIT_MB  # [MB] (its home: the run's plan)

from sc_rt.isolate import exit_how
from sc_rt.wire.lcmio import open_lcm

__all__ = ["CONTROLLER_MEMORY_LIMIT_MB", "Drain", "LOGGER_FIFO_PRIORITY", "OUTPUT_CAP_BYTES", "Stopper",
           "bench_binary", "child_kwargs", "controller_binary", "lift_logger", "probe_logger", "rss_mb",
           "stop_child", "wait_logged"]


def bench_binary(name: str) -> str:
    """One of sc-rt's executables next to this interpreter (the venv's bin), else PATH."""
    here = Path(sys.executable).parent / name
    if here.exists():
        return str(here)
    found = shutil.which(name)
    if not found:
        raise FileNotFoundError(f"{name} not found: install sc-rt (make install)")
    return found


def controller_binary() -> str:
    """sc-rt-controller next to this interpreter (the venv's bin), else PATH."""
    return bench_binary("sc-rt-controller")



def probe_logger(url: str, path: Path, payload: bytes, timeout: float, name: str) -> bool:
    """Publish ``payload`` on ``name`` until lcm-logger has written something to
    ``path`` (it listens), for at most ``timeout`` s."""
    lc = open_lcm(url)
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        lc.publish(name, payload)
        time.sleep(0.02)
        if path.exists() and path.stat().st_size > 0:
            return True
    return False


def _pdeathsig():
    """prctl(PR_SET_PDEATHSIG, SIGTERM) for a child, looked up in the parent
    (the child, between fork and exec, only calls it); None off Linux."""
    try:
        import ctypes

        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    return lambda: prctl(1, int(signal.SIGTERM))  # 1: PR_SET_PDEATHSIG


def child_kwargs() -> dict[str, Any]:
    """Popen arguments of the bench's children: their own process group (a
    Ctrl-C at the terminal reaches sc-rt alone, which stops them in order:
    controller, then the logger after its last flush) and SIGTERM when sc-rt
    dies, even by SIGKILL (Linux)."""
    if sys.platform != "linux":
        return {}
    hook = _pdeathsig()
    return {"process_group": 0, **({"preexec_fn": hook} if hook else {})}


#: [bytes] what a child's stdout or stderr file keeps; the rest is counted and dropped
OUTPUT_CAP_BYTES = 1 << 20


class Drain:
    """A child's output pipe read continuously, on a thread of its own, into
    ``path`` (created at once, so a message can name it), which keeps the
    first ``cap`` bytes and a last line counting the rest: a child that
    writes without end neither blocks on a full pipe nor fills the disk.
    ``wait_for`` waits, bounded, until the child has written ``watch`` (a
    controller says when it has subscribed; a law may have printed before)."""

    def __init__(self, pipe: Any, path: Path, cap: int = OUTPUT_CAP_BYTES, watch: bytes = b""):
        self.path, self.cap, self.watch = Path(path), int(cap), watch
        self.total = 0
        self._kept = 0
        self._tail = b""  # the last bytes, to find ``watch`` across two reads
        self.seen = threading.Event()  # ``watch`` written, or the output closed
        self.found = False
        self._file = open(self.path, "wb")  # noqa: SIM115 (closed by the thread)
        self._thread = threading.Thread(target=self._run, args=(pipe,), name=f"drain {self.path.name}",
                                        daemon=True)
        self._thread.start()

    def _run(self, pipe: Any) -> None:
        fd = pipe.fileno()
        try:
            while chunk := os.read(fd, 65536):
                self.total += len(chunk)
                if self.watch and not self.found:
                    self._tail = self._tail[-len(self.watch):] + chunk
                    if self.watch in self._tail:
                        self.found = True
                        self.seen.set()
                room = self.cap - self._kept
                if room > 0:
                    self._file.write(chunk[:room])
                    self._file.flush()
                    self._kept += min(room, len(chunk))
        except OSError:
            pass
        finally:
            if self.dropped:
                self._file.write(f"\n[sc-rt: {self.dropped} more bytes dropped: this file keeps the first "
                                 f"{self.cap} bytes]\n".encode())
            self._file.close()
            pipe.close()
            self.seen.set()

    @property
    def dropped(self) -> int:
        """Bytes the child wrote past the cap."""
        return max(0, self.total - self.cap)

    def wait_for(self, timeout: float) -> bool:
        """Whether the child wrote ``watch`` within ``timeout`` s (False: not
        in time, or its output closed without it)."""
        self.seen.wait(timeout)
        return self.found

    def close(self, timeout: float = 5.0) -> str:
        """Wait for the end of the output (the child has exited): what the file keeps."""
        self._thread.join(timeout)
        return self.path.read_text(errors="replace") if self.path.exists() else ""


def rss_mb(pid: int) -> float | None:
    """[MB] a process's resident memory (VmRSS of /proc; None: gone or not Linux)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        return None
    return None


class Stopper:
    """Why a bench run should stop early, asked by the emulator every step:
    SIGINT or SIGTERM received (handled while the run lasts, main thread
    only), ``lcm-logger`` gone, or the controller under test gone (polled at
    most every ``poll_s``: a dead child is noticed within a second and the
    run stops, partial, rather than go on with a log that no longer grows or
    with the watchdog's zero commands standing in for a dead law)."""

    def __init__(self, logger: subprocess.Popen | None = None, poll_s: float = 0.25,
                 memory_limit_mb: float = CONTROLLER_MEMORY_LIMIT_MB):
        self.logger, self.poll_s, self.memory_limit_mb = logger, poll_s, memory_limit_mb
        #: [MB] the controller's largest resident memory seen
        self.controller_peak_mb: float | None = None
        self.signum: int | None = None
        self.logger_rc: int | None = None
        #: the controller process under test, and its name in messages
        self.controller: subprocess.Popen | None = None
        self.controller_name = "the controller"
        #: how the controller died ("sc-rt-controller died (signal SIGSEGV)"), None while it lives
        self.died: str | None = None
        self._next = 0.0
        self._old: dict[int, Any] = {}

    def __enter__(self) -> Stopper:
        if threading.current_thread() is threading.main_thread():
            for s in (signal.SIGINT, signal.SIGTERM):
                self._old[s] = signal.signal(s, self._on_signal)
        return self

    def __exit__(self, *exc: Any) -> None:
        for s, h in self._old.items():
            signal.signal(s, h)

    def _on_signal(self, signum: int, _frame: Any) -> None:
        if self.signum is None:
            self.signum = signum

    def __call__(self) -> str | None:
        if self.signum is not None:
            return f"interrupted by {signal.Signals(self.signum).name}"
        now = time.monotonic()
        if now >= self._next:
            self._next = now + self.poll_s
            if self.logger is not None:
                self.logger_rc = self.logger.poll()
            if self.controller is not None and self.died is None and (rc := self.controller.poll()) is not None:
                self.died = f"{self.controller_name} died ({exit_how(rc)}) during the run"
            elif self.controller is not None and self.died is None:
                self._watch_memory()
        if self.logger_rc is not None:
            return f"sc-rt-logger exited (code {self.logger_rc}) during the run: the log ends there"
        return self.died

    def _watch_memory(self) -> None:
        """The controller's resident memory against the limit: beyond it the
        controller is killed and the run stops, invalid, naming both numbers."""
        mb = rss_mb(self.controller.pid)
        if mb is None:
            return
        self.controller_peak_mb = max(self.controller_peak_mb or 0.0, mb)
        if mb > self.memory_limit_mb:
            self.controller.kill()
            self.died = (f"{self.controller_name} used {mb:.0f} MB of memory, over the limit of "
                         f"{self.memory_limit_mb:g} MB (--controller-memory-limit): killed during the run")


#: lcm-logger's real-time priority when permitted: above every ordinary
#: process, below the bench's own real-time processes (controller 80, emulator).
LOGGER_FIFO_PRIORITY = 10


def lift_logger(pid: int) -> str:
    """SCHED_FIFO for lcm-logger when this process may set it (root): its LCM
    subscription queue holds 30 messages, a lockstep run publishes ~20,000
    a second, and a logger descheduled for a millisecond by other load drops
    the overflow silently. Returns the policy it runs with."""
    lifted = 0
    for task in Path(f"/proc/{pid}/task").glob("*"):  # the policy is per thread on Linux
        try:
            os.sched_setscheduler(int(task.name), os.SCHED_FIFO, os.sched_param(LOGGER_FIFO_PRIORITY))
            lifted += 1
        except (PermissionError, OSError, AttributeError, ValueError):
            pass
    return f"SCHED_FIFO {LOGGER_FIFO_PRIORITY} ({lifted} threads)" if lifted else "SCHED_OTHER"


def wait_logged(url: str, path: Path, logger: subprocess.Popen, channel_name: str, payload: bytes,
                 timeout_s: float = 10.0) -> bool:
    """Publish an end marker and wait until lcm-logger has written it: the
    logger receives in send order, so everything the run published is in the
    log before it (a loaded machine can leave the logger seconds behind a
    lockstep run; stopping it at once lost the last states). False when the
    marker did not appear within ``timeout_s`` (said in timing.json)."""
    lc = open_lcm(url)
    needle = channel_name.encode()
    end = time.monotonic() + timeout_s
    next_pub = 0.0
    while time.monotonic() < end and logger.poll() is None:
        if time.monotonic() >= next_pub:  # again now and then: a datagram can be lost
            lc.publish(channel_name, payload)
            next_pub = time.monotonic() + 1.0
        if path.exists():
            with open(path, "rb") as f:
                f.seek(max(0, path.stat().st_size - 4096))
                if needle in f.read():
                    return True
        time.sleep(0.01)
    return False


def stop_child(proc: subprocess.Popen, sig: int = signal.SIGTERM, timeout: float = 5.0) -> int:
    """Signal a child and wait ``timeout`` s for it, then kill it: its exit code."""
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return proc.returncode
