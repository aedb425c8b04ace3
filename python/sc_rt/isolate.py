"""A call in a forked child process, for native code the bench does not own
(a law plugin) that may kill the process it runs in.

``call_in_child(fn, *args)`` returns ``fn(*args)`` computed in a child; an
exception there comes back as itself; a child that dies (a signal such as
SIGSEGV, an abort, an exit) raises ``ChildDied`` naming how; with
``timeout=`` a child that has not answered in time is killed (SIGKILL) and
``ChildTimedOut`` (a ChildDied) is raised. A law's probe (constructed and
stepped once at rest, sc_rt.plan.law.probe_law) gets
:func:`probe_timeout` seconds. Depends on nothing else of sc_rt (the bottom
layer).
"""

from __future__ import annotations

import math
import os
import pickle
import select
import signal
import time
from typing import Any, Callable

__all__ = ["ChildDied", "ChildInterrupted", "ChildTimedOut", "INTERRUPT_GRACE_S", "PROBE_TIMEOUT_ENV",
           "PROBE_TIMEOUT_S", "call_in_child", "exit_how", "forward_signal", "probe_timeout"]

#: [s] a child sent an interrupt (forward_signal) that has not answered by
#: then is killed: a law that never returns cannot hold the command
INTERRUPT_GRACE_S = 5.0

#: the child call_in_child waits for now, in this process (pid), and when it is
#: to be killed after an interrupt (monotonic s; None: not interrupted)
_WAITING: dict[str, Any] = {"pid": None, "kill_at": None}


def forward_signal(signum: int) -> None:
    """Pass an interrupt (SIGINT, SIGTERM) on to the child call_in_child waits
    for, if any (safe in a signal handler): it may stop cleanly (its rows
    so far) within INTERRUPT_GRACE_S, else it is killed."""
    pid = _WAITING["pid"]
    if pid is None:
        return
    try:
        os.kill(pid, signum)
    except ProcessLookupError:
        return
    if _WAITING["kill_at"] is None:
        _WAITING["kill_at"] = time.monotonic() + INTERRUPT_GRACE_S


class ChildInterrupted(RuntimeError):
    """The child did not stop within INTERRUPT_GRACE_S of an interrupt and was killed."""

#: How long a law may take to be constructed and stepped once at rest in its
#: probe [s] (docs/LAWS.md): generous for a law that designs its gains or
#: compiles itself, short enough that a law that never returns does not hang
#: ``sc-rt check`` or the planning of a run.
PROBE_TIMEOUT_S = 30.0
#: The environment variable that sets another probe timeout [s].
PROBE_TIMEOUT_ENV = "SCRT_PROBE_TIMEOUT"


def probe_timeout() -> float:
    """The probe timeout [s]: $SCRT_PROBE_TIMEOUT when set, else
    PROBE_TIMEOUT_S. ValueError (naming the variable and its value) unless
    it is a finite number > 0."""
    raw = os.environ.get(PROBE_TIMEOUT_ENV)
    if raw is None or raw == "":
        return PROBE_TIMEOUT_S
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{PROBE_TIMEOUT_ENV}={raw}: must be a number of seconds > 0")
    return value


class ChildDied(RuntimeError):
    """The child died before it answered; ``how``: "signal SIGSEGV", "exit code 3"."""

    def __init__(self, how: str):
        super().__init__(how)
        self.how = how


class ChildTimedOut(ChildDied):
    """The child had not answered within ``timeout`` seconds and was killed."""

    def __init__(self, timeout: float):
        super().__init__(f"no answer within {timeout:g} s: killed")
        self.timeout = timeout


def exit_how(code: int | None) -> str:
    """A process's exit code in words."""
    if code is None:
        return "it did not finish"
    if code < 0:
        try:
            return f"signal {signal.Signals(-code).name}"
        except ValueError:
            return f"signal {-code}"
    return f"exit code {code}"


def _answer(fd: int, fn, args, kwargs) -> None:
    try:
        out = ("ok", fn(*args, **kwargs))
    except BaseException as e:  # noqa: BLE001  (sent back and raised in the parent)
        out = ("error", e)
    try:
        data = pickle.dumps(out)
    except Exception as e:  # a result or exception that does not pickle: its text
        data = pickle.dumps(("error", RuntimeError(f"{type(e).__name__}: {e}")))
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def call_in_child(fn: Callable[..., Any], *args: Any, timeout: float | None = None, **kwargs: Any) -> Any:
    """``fn(*args, **kwargs)`` in a forked child: its result, its exception,
    or ChildDied. A plain fork (os.fork), so that it works in any process,
    a pool's daemonic worker included; the child never returns into the
    caller's code (os._exit). ``timeout`` [s] (not passed to ``fn``; None:
    none): a child that has not answered by then is killed and
    ChildTimedOut raised. A child left behind by an exception here (an
    interrupt while waiting) is killed too, never waited for unbounded."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child
        code = 0
        try:
            os.close(r)
            _answer(w, fn, args, kwargs)
        except BaseException:  # noqa: BLE001
            code = 1
        finally:
            os._exit(code)
    os.close(w)
    deadline = None if timeout is None else time.monotonic() + timeout
    chunks, answered = [], False
    outer = _WAITING["pid"], _WAITING["kill_at"]
    _WAITING["pid"], _WAITING["kill_at"] = pid, None
    try:
        while True:
            now = time.monotonic()
            kill_at = _WAITING["kill_at"]
            if kill_at is not None and now >= kill_at:
                raise ChildInterrupted(f"it did not stop within {INTERRUPT_GRACE_S:g} s of the interrupt: killed")
            if deadline is not None and now >= deadline:
                raise ChildTimedOut(timeout)
            # wake for the deadline, an interrupt's grace, or at least every half second
            wait = min(x - now for x in (deadline, kill_at, now + 0.5) if x is not None)
            if not select.select([r], [], [], max(wait, 0.0))[0]:
                continue
            b = os.read(r, 1 << 20)
            if not b:
                break
            chunks.append(b)
        answered = True
    finally:
        _WAITING["pid"], _WAITING["kill_at"] = outer
        os.close(r)
        if not answered:  # timed out or interrupted: the child goes, now
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        _, status = os.waitpid(pid, 0)
    data = b"".join(chunks)
    if not data:
        raise ChildDied(exit_how(os.waitstatus_to_exitcode(status)))
    kind, value = pickle.loads(data)
    if kind == "error":
        raise value
    return value
