"""``sc-rt hil --live [PORT]``: ``sc-rt live`` beside a run, as a child
process of its own (the run's loop never waits for a client).

It is started before the run (so it hears the run's configuration, sent
once at its start) and stopped after the run's outputs are written, in
its own process group like the bench's other children (SIGTERM when sc-rt
dies). A server that cannot start (the port in use, an address that cannot
be bound) is one line on stderr, and the run goes on without it.
"""

from __future__ import annotations

import contextlib
import select
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

from sc_rt.hil.procs import child_kwargs

__all__ = ["LiveChild", "beside_run", "READY"]

#: the first line ``sc-rt live`` prints on stdout once it serves
READY = "sc-rt live: serving"


class LiveChild:
    """One ``sc-rt live`` process serving the bus of a run.

    Parameters
    ----------
    url : str
        The run's LCM URL.
    port : int
        The WebSocket port on ``host``.
    prefix : str
        The run's channel prefix.
    auth_key : str or Path, optional
        The bus key file (the run's ``--auth-key``).
    host : str
        The address to listen on.
    """

    def __init__(self, url: str, port: int, *, prefix: str = "", auth_key: str | Path | None = None,
                 host: str = "127.0.0.1"):
        self.cmd = [sys.executable, "-m", "sc_rt.cli", "live", "--lcm-url", url, "--host", host,
                    "--port", str(port), "--prefix", prefix]
        if auth_key is not None:
            self.cmd += ["--auth-key", str(auth_key)]
        self.port = port
        self.proc: subprocess.Popen | None = None
        self.lines: list[str] = []
        self.ready = threading.Event()
        self._pump: threading.Thread | None = None

    def _forward(self) -> None:
        """The child's stderr: kept until it serves (the reason it could not), echoed after."""
        assert self.proc is not None and self.proc.stderr is not None
        for line in self.proc.stderr:
            if self.ready.is_set():
                sys.stderr.write(line)
            else:
                self.lines.append(line.rstrip())

    def start(self, timeout_s: float = 20.0) -> str | None:
        """Start it and wait (up to ``timeout_s``) until it serves: its
        address, or None after one line on stderr saying why not."""
        try:
            self.proc = subprocess.Popen(self.cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                         stdin=subprocess.DEVNULL, text=True, **child_kwargs())
        except OSError as e:
            return self._failed(f"cannot start sc-rt live: {e.strerror}")
        self._pump = threading.Thread(target=self._forward, name="sc-rt live stderr", daemon=True)
        self._pump.start()
        end = time.monotonic() + timeout_s
        line = ""
        while time.monotonic() < end and not line:
            ready, _, _ = select.select([self.proc.stdout], [], [], max(0.0, end - time.monotonic()))
            if not ready:
                break
            line = self.proc.stdout.readline()
            if not line:  # it exited
                break
        if line.startswith(READY):
            self.ready.set()
            where = line.split(" on ", 1)[-1].split()[0] if " on " in line else f"port {self.port}"
            print(f"sc-rt hil: live on {where} (Foxglove WebSocket; docs/LOGS.md, 'Live')", file=sys.stderr,
                  flush=True)
            return where
        self.stop()
        if self._pump is not None:
            self._pump.join(5)
        why = self.lines[-1] if self.lines else f"it did not serve within {timeout_s:g} s"
        return self._failed(why.removeprefix("sc-rt live: ").removeprefix("error: "))

    def _failed(self, why: str) -> None:
        print(f"sc-rt hil: --live {self.port}: not serving ({why}); the run goes on without it",
              file=sys.stderr, flush=True)
        return None

    def stop(self) -> None:
        """Stop it (SIGTERM, then SIGKILL after 5 s)."""
        p = self.proc
        if p is None or p.poll() is not None:
            return
        p.terminate()
        try:
            p.wait(5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


@contextlib.contextmanager
def beside_run(port: int | None, url: str | None, prefix: str = "",
               auth_key: str | Path | None = None) -> Iterator[LiveChild | None]:
    """``sc-rt live`` on ``port`` while the block runs (nothing when ``port`` is None).

    Parameters
    ----------
    port : int or None
        ``--live``'s port; None: no live server.
    url : str or None
        The run's LCM URL (required with a port).
    prefix : str
        The run's channel prefix.
    auth_key : str or Path, optional
        The run's key file.

    Yields
    ------
    LiveChild or None
        The child (whether it serves or not), None without a port.
    """
    if port is None or url is None:
        yield None
        return
    child = LiveChild(url, port, prefix=prefix, auth_key=auth_key)
    try:
        child.start()  # inside: an interrupt during its start-up still stops it
        yield child
    finally:
        child.stop()
