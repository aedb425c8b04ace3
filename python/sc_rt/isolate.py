"""A call in a forked child process, for native code the bench does not own
(a law plugin) that may kill the process it runs in.

``call_in_child(fn, *args)`` returns ``fn(*args)`` computed in a child; an
exception there comes back as itself; a child that dies (a signal such as
SIGSEGV, an abort, an exit) raises ``ChildDied`` naming how; with
``timeout=`` a child that has not answered in time is killed (SIGKILL) and
``ChildTimedOut`` (a ChildDied) is raised. A law's probe (constructed and
stepped once at rest, sc_rt.plan.law.probe_law) gets
:func:`probe_timeout` seconds. With ``stall=`` the child beats
(:func:`beat`: a step done, and its time) into memory shared with the
parent; a child that has not beaten for ``stall`` seconds (a law that
never returns) is killed and ``ChildStalled`` raised, naming the last time
it reached: a run of any length goes on as long as it makes progress.
Depends on nothing else of sc_rt (the bottom layer).
"""

from __future__ import annotations

import math
import mmap
import os
import pickle
import select
import signal
import struct
import time
from typing import Any, Callable

__all__ = ["ChildDied", "ChildInterrupted", "ChildStalled", "ChildTimedOut", "INTERRUPT_GRACE_S",
           "PROBE_TIMEOUT_ENV", "PROBE_TIMEOUT_S", "STALL_TIMEOUT_ENV", "STALL_TIMEOUT_S", "beat", "beat_done",
           "beating", "call_in_child", "exit_how", "forward_signal", "probe_timeout", "stall_timeout"]

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
    if pid is None:  # before the child is forked: call_in_child passes it on as soon as it is
        _WAITING["pending"] = signum
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


#: How long a contained run's law may go without finishing a step [s]
#: (docs/LAWS.md): a law that never returns is killed after it, its run
#: failed and named; a run of any length goes on while its steps return.
STALL_TIMEOUT_S = 30.0
#: The environment variable that sets another stall timeout [s].
STALL_TIMEOUT_ENV = "SCRT_STALL_TIMEOUT"


def _seconds(var: str, default: float) -> float:
    raw = os.environ.get(var)
    if raw is None or raw == "":
        return default
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{var}={raw}: must be a number of seconds > 0")
    return value


def probe_timeout() -> float:
    """The probe timeout [s]: $SCRT_PROBE_TIMEOUT when set, else
    PROBE_TIMEOUT_S. ValueError (naming the variable and its value) unless
    it is a finite number > 0."""
    return _seconds(PROBE_TIMEOUT_ENV, PROBE_TIMEOUT_S)


def stall_timeout() -> float:
    """The stall timeout [s]: $SCRT_STALL_TIMEOUT when set, else
    STALL_TIMEOUT_S; ValueError as probe_timeout's."""
    return _seconds(STALL_TIMEOUT_ENV, STALL_TIMEOUT_S)


#: this process's beat: memory shared with the parent that waits for it
#: (call_in_child with ``stall``), None when nobody watches
_BEAT: dict[str, Any] = {"map": None, "n": 0}
_BEAT_LAYOUT = struct.Struct("<qd")  # beats, the time of the last [s]


def beating() -> bool:
    """Whether a parent watches this process's beats (call_in_child's stall)."""
    return _BEAT["map"] is not None


def beat_done() -> None:
    """The steps are over (what follows, the metrics and the hand-over, is
    the bench's own work, not a law's): the parent stops watching."""
    m = _BEAT["map"]
    if m is not None:
        _BEAT_LAYOUT.pack_into(m, 0, -1, math.nan)


def beat(t: float) -> None:
    """A step done, at time ``t`` [s] of the run: for the parent that
    watches (call_in_child's ``stall``); nothing when nobody does."""
    m = _BEAT["map"]
    if m is not None:
        _BEAT["n"] += 1
        _BEAT_LAYOUT.pack_into(m, 0, _BEAT["n"], t)


class ChildDied(RuntimeError):
    """The child died before it answered; ``how``: "signal SIGSEGV", "exit code 3"."""

    def __init__(self, how: str):
        super().__init__(how)
        self.how = how


class ChildStalled(ChildDied):
    """The child had not beaten for ``stall`` seconds and was killed; ``t``:
    the time of its last beat (None: it never beat)."""

    def __init__(self, stall: float, t: float | None):
        at = f"after t = {t:g} s" if t is not None else "before its first step"
        super().__init__(f"no step returned for {stall:g} s ({at}; {STALL_TIMEOUT_ENV} sets the limit): killed")
        self.stall, self.t = stall, t


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


def call_in_child(fn: Callable[..., Any], *args: Any, timeout: float | None = None,
                  stall: float | None = None, **kwargs: Any) -> Any:
    """``fn(*args, **kwargs)`` in a forked child: its result, its exception,
    or ChildDied. A plain fork (os.fork), so that it works in any process,
    a pool's daemonic worker included; the child never returns into the
    caller's code (os._exit). ``timeout`` [s] (not passed to ``fn``; None:
    none): a child that has not answered by then is killed and
    ChildTimedOut raised. ``stall`` [s] (None: none): a child whose
    :func:`beat` has not changed for that long is killed and ChildStalled
    raised. A child left behind by an exception here (an interrupt while
    waiting) is killed too, never waited for unbounded."""
    shared = mmap.mmap(-1, _BEAT_LAYOUT.size) if stall is not None else None
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child
        code = 0
        try:
            os.close(r)
            _BEAT["map"], _BEAT["n"] = shared, 0
            _answer(w, fn, args, kwargs)
        except BaseException:  # noqa: BLE001
            code = 1
        finally:
            os._exit(code)
    os.close(w)
    deadline = None if timeout is None else time.monotonic() + timeout
    beats, beat_at = 0, time.monotonic()
    chunks, answered = [], False
    outer = _WAITING["pid"], _WAITING["kill_at"]
    _WAITING["pid"], _WAITING["kill_at"] = pid, None
    pending = _WAITING.pop("pending", None)
    if pending is not None:  # an interrupt that came while the child was being started
        forward_signal(pending)
    try:
        while True:
            now = time.monotonic()
            kill_at = _WAITING["kill_at"]
            if kill_at is not None and now >= kill_at:
                raise ChildInterrupted(f"it did not stop within {INTERRUPT_GRACE_S:g} s of the interrupt: killed")
            if deadline is not None and now >= deadline:
                raise ChildTimedOut(timeout)
            if shared is not None:
                n, t = _BEAT_LAYOUT.unpack_from(shared, 0)
                if n != beats:
                    beats, beat_at = n, now
                elif n >= 0 and now - beat_at >= stall:
                    raise ChildStalled(stall, t if n else None)
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
        if shared is not None:
            shared.close()
    data = b"".join(chunks)
    if not data:
        raise ChildDied(exit_how(os.waitstatus_to_exitcode(status)))
    kind, value = pickle.loads(data)
    if kind == "error":
        raise value
    return value
