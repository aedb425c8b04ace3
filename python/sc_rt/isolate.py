"""A call in a forked child process, for native code the bench does not own
(a law plugin) that may kill the process it runs in.

``call_in_child(fn, *args)`` returns ``fn(*args)`` computed in a child; an
exception there comes back as itself; a child that dies (a signal such as
SIGSEGV, an abort, an exit) raises ``ChildDied`` naming how. Depends on
nothing else of sc_rt (the bottom layer).
"""

from __future__ import annotations

import os
import pickle
import signal
from typing import Any, Callable

__all__ = ["ChildDied", "call_in_child", "exit_how"]


class ChildDied(RuntimeError):
    """The child died before it answered; ``how``: "signal SIGSEGV", "exit code 3"."""

    def __init__(self, how: str):
        super().__init__(how)
        self.how = how


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


def call_in_child(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """``fn(*args, **kwargs)`` in a forked child: its result, its exception,
    or ChildDied. A plain fork (os.fork), so that it works in any process,
    a pool's daemonic worker included; the child never returns into the
    caller's code (os._exit)."""
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
    chunks = []
    try:
        while True:
            b = os.read(r, 1 << 20)
            if not b:
                break
            chunks.append(b)
    finally:
        os.close(r)
        _, status = os.waitpid(pid, 0)
    data = b"".join(chunks)
    if not data:
        raise ChildDied(exit_how(os.waitstatus_to_exitcode(status)))
    kind, value = pickle.loads(data)
    if kind == "error":
        raise value
    return value
