"""``sc-rt new-law NAME [--lang cpp|python]``: its options, their checks and
the call that writes the law project (sc_rt.lawproject.scaffold); and
``sc-rt --cmake-dir``."""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from sc_rt.cli.validate import out_dir
from sc_rt.lawproject import scaffold

__all__ = ["add_parser", "cmd_new_law", "CmakeDirAction"]

_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_-]{0,63}$")


class CmakeDirAction(argparse.Action):
    """``sc-rt --cmake-dir``: print the installed package config's directory, exit."""

    def __init__(self, option_strings, dest, **kw):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        from sc_rt.cmake import cmake_dir

        try:
            print(cmake_dir())
        except FileNotFoundError as e:
            parser.exit(2, f"sc-rt: --cmake-dir: {e}\n")
        parser.exit(0)


def add_parser(sub) -> None:
    n = sub.add_parser("new-law", help="scaffold a control-law project (C++ plugin or Python class) with a test")
    n.add_argument("name", help="the law's name (letters, digits, - and _; e.g. my-pd)")
    n.add_argument("--lang", choices=("cpp", "python"), default="cpp", help="cpp: a plugin built with CMake (default); "
                   "python: a Python law class (docs/LAWS.md)")
    n.add_argument("--out", metavar="DIR", type=out_dir, help="the project directory to create (default: ./NAME)")
    n.set_defaults(func=cmd_new_law)


def cmd_new_law(args: argparse.Namespace) -> int:
    if not _NAME_RE.match(args.name):
        print(f"sc-rt new-law: name {args.name!r}: must start with a letter and hold only letters, "
              "digits, - and _ (at most 64)", file=sys.stderr)
        return 2
    out = Path(args.out or args.name)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        print(f"sc-rt new-law: --out {out}: exists and is not an empty directory", file=sys.stderr)
        return 2
    files = scaffold(args.name, out, args.lang)
    print(f"sc-rt new-law: {args.name} ({args.lang}) -> {out}/: " + ", ".join(p.name for p in files))
    print(f"next: see {out / 'README.md'}")
    return 0
