"""Commands run in bounded time and memory for the tests of bad input
(tests/test_bad_scenario_files.py, test_plugin_file_check.py,
test_probe_timeout.py): ``sc_rt(ARGS)`` runs sc_rt.cli.main in a forked
child of its own session and ``sc_rt_process(ARGS)`` the installed entry
point in a process of its own, each with an address-space limit and a
timeout, so that a regression (a file read whole, a FIFO waited on, a
SIGBUS, a law that never returns) fails its test in bounded time and memory
instead of growing, hanging or killing the test session. A helper of its
own: the code under test is not trusted to bound itself."""

from __future__ import annotations

import contextlib
import io
import os
import pickle
import resource
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import sc_rt.cli.run_cmds  # noqa: F401  (imported once here, not in every forked child)
import sc_rt.studies.check  # noqa: F401
from sc_rt.cli.main import main

LIMIT_AS = 2 << 30  # bytes of address space for a command (it needs < 0.3 GiB)


def forked(fn, timeout: float):
    """fn() in a forked child of its own session, with LIMIT_AS more address
    space than this process has, killed whole after ``timeout`` s: its
    result, or pytest.fail naming how it died."""
    with open("/proc/self/status") as f:
        vm = next(int(ln.split()[1]) * 1024 for ln in f if ln.startswith("VmSize:"))
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:
        try:
            os.close(r)
            os.setsid()
            resource.setrlimit(resource.RLIMIT_AS, (vm + LIMIT_AS, vm + LIMIT_AS))
            data = pickle.dumps(fn())
            view = memoryview(data)
            while view:
                view = view[os.write(w, view):]
        finally:
            os._exit(0)
    os.close(w)
    deadline, chunks = time.monotonic() + timeout, []
    try:
        while select.select([r], [], [], max(deadline - time.monotonic(), 0))[0]:
            if not (b := os.read(r, 1 << 16)):
                break
            chunks.append(b)
        else:
            os.killpg(pid, signal.SIGKILL)
            pytest.fail(f"did not end within {timeout} s")
    finally:
        os.close(r)
        status = os.waitpid(pid, 0)[1]
    if not chunks:
        pytest.fail(f"died: exit status {os.waitstatus_to_exitcode(status)}")
    return pickle.loads(b"".join(chunks))


def sc_rt(args: list[str], cwd: Path, timeout: float = 60, env: dict | None = None) -> tuple[int, list[str], str]:
    """`sc-rt ARGS` (sc_rt.cli.main) in cwd, in a forked child (see forked):
    (exit code, stderr lines, stdout)."""
    def run():
        os.chdir(cwd)
        os.environ.update({"SCRT_LCM_URL": "memq://", **(env or {})})
        err, out = io.StringIO(), io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            try:
                rc = main(args)
            except SystemExit as e:
                rc = e.code
        return rc, err.getvalue(), out.getvalue()

    rc, err, out = forked(run, timeout)
    return rc, [ln for ln in err.splitlines() if ln.strip()], out


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT_AS, LIMIT_AS))


def sc_rt_process(args: list[str], cwd: Path, timeout: float = 60) -> tuple[int, list[str]]:
    """`sc-rt ARGS`, the real entry point in a process of its own, with
    LIMIT_AS of address space, killed whole after ``timeout`` s."""
    p = subprocess.Popen([sys.executable, "-m", "sc_rt.cli", *args], cwd=cwd, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True, preexec_fn=_limited,
                         env={**os.environ, "SCRT_LCM_URL": "memq://"})
    try:
        _, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        pytest.fail(f"sc-rt {' '.join(args)} did not end within {timeout} s")
    return p.returncode, [ln for ln in err.splitlines() if ln.strip()]
