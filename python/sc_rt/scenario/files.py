"""Reading the files a scenario is made of (the TOML file, a ``[guidance]``
reference file) in bounded time and memory: a regular file (after following
symlinks; a symlink loop is named as one), at most :data:`MAX_FILE_BYTES`,
read with a bounded read; and the TOML's nesting depth checked before
tomllib (which recurses per level) parses it, and the parsed values' depth
after (dotted keys nest too) (docs/SCENARIOS.md, "Errors").
"""

from __future__ import annotations

import errno
import os
import re
import stat
from pathlib import Path
from typing import Any

__all__ = ["MAX_FILE_BYTES", "MAX_NESTING", "FileProblem", "read_bounded", "nesting_problem", "deep_key"]

#: The largest scenario file, or reference file, read [bytes]: 1 MiB. The
#: largest shipped scenario is under 20 kB, and a reference file at its
#: sample limit (2000 rows of 11 numbers at full precision) under 0.6 MB.
MAX_FILE_BYTES = 1 << 20
#: The deepest nesting accepted: of arrays and inline tables as written
#: (tomllib recurses per level and fails near a few hundred), and of the
#: parsed values, tables and dotted keys included (the reader walks them).
#: The shipped scenarios nest 4 levels at most (``laws.pd.kp``, a matrix).
MAX_NESTING = 32

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))


class FileProblem(ValueError):
    """Why a file was not read (one line, without the path)."""


def _kind(mode: int) -> str:
    return next((what for test, what in _KINDS if test(mode)), "not a regular file")


def _mib(n: int) -> str:
    return f"{n / (1 << 20):g} MiB"


def read_bounded(path: str | Path, limit: int = MAX_FILE_BYTES) -> bytes:
    """The bytes of the regular file at ``path`` (symlinks followed), at
    most ``limit`` of them; FileProblem otherwise: missing, a symlink loop,
    not a regular file (a FIFO is never opened for a blocking read, a
    device never read), larger than ``limit``, unreadable."""
    path = os.fspath(path)
    try:
        st = os.stat(path)
    except OSError as e:
        raise FileProblem(_os_problem(e)) from None
    if not stat.S_ISREG(st.st_mode):
        raise FileProblem(f"{_kind(st.st_mode)}, not a regular file")
    if st.st_size > limit:
        raise FileProblem(f"{st.st_size} bytes, larger than the limit of {_mib(limit)} ({limit} bytes)")
    try:  # O_NONBLOCK: if the path was swapped for a FIFO since, opening does not wait
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as e:
        raise FileProblem(_os_problem(e)) from None
    try:
        st = os.fstat(fd)  # the file opened is the one judged
        if not stat.S_ISREG(st.st_mode):
            raise FileProblem(f"{_kind(st.st_mode)}, not a regular file")
        chunks, n = [], 0
        while n <= limit:
            b = os.read(fd, min(1 << 16, limit + 1 - n))
            if not b:
                break
            chunks.append(b)
            n += len(b)
    except OSError as e:
        raise FileProblem(_os_problem(e)) from None
    finally:
        os.close(fd)
    if n > limit:  # it grew after the stat
        raise FileProblem(f"more than the limit of {_mib(limit)} ({limit} bytes)")
    return b"".join(chunks)


def _os_problem(e: OSError) -> str:
    if e.errno == errno.ELOOP:
        return "a symlink loop (too many levels of symbolic links)"
    if e.errno == errno.ENOENT:
        return "no such file"
    return e.strerror or str(e)


# the tokens that matter for nesting: strings (their brackets do not count), comments, brackets, newlines
_TOKEN = re.compile(r'"""|\'\'\'|"|\'|#|[\[\]{}]|\n')
_END = {'"""': re.compile(r'(?:[^"\\]|\\.|"(?!""))*"""', re.S),
        "'''": re.compile(r"(?:[^']|'(?!''))*'''", re.S),
        '"': re.compile(r'(?:[^"\\\n]|\\.)*"'),
        "'": re.compile(r"[^'\n]*'")}


def nesting_problem(text: str, limit: int = MAX_NESTING) -> tuple[int, str] | None:
    """(line, message) of the first place where arrays and inline tables nest
    deeper than ``limit``, or None. Brackets in strings and comments do not
    count; a string that does not end is left to the TOML parser."""
    depth, line, pos = 0, 1, 0
    while (m := _TOKEN.search(text, pos)) is not None:
        tok, pos = m.group(), m.end()
        if tok == "\n":
            line += 1
        elif tok == "#":
            end = text.find("\n", pos)
            pos = len(text) if end < 0 else end
        elif tok in _END:
            s = _END[tok].match(text, pos)
            if s is None:
                return None
            line += text.count("\n", pos, s.end())
            pos = s.end()
        elif tok in "[{":
            depth += 1
            if depth > limit:
                return line, f"arrays and inline tables nest more than {limit} levels deep"
        else:
            depth = max(depth - 1, 0)
    return None


def deep_key(data: Any, limit: int = MAX_NESTING) -> list[str | int] | None:
    """The path (keys, and list indices as ints) to the first value of the
    parsed ``data`` that lies more than ``limit`` tables or arrays deep, or
    None. Iterative: a deep value is found without recursing."""
    stack: list[tuple[Any, list[str | int]]] = [(data, [])]
    while stack:
        value, path = stack.pop()
        if len(path) > limit:
            return path
        if isinstance(value, dict):
            stack.extend((v, [*path, k]) for k, v in reversed(value.items()))
        elif isinstance(value, list):
            stack.extend((v, [*path, i]) for i, v in reversed(list(enumerate(value))))
    return None
