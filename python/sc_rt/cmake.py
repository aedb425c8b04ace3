"""Where the installed law interface is, for plugins built out of tree
(docs/LAWS.md), the way ``python -m pybind11 --cmakedir`` does it:

    python -m sc_rt.cmake            # the directory of sc_rtConfig.cmake
    python -m sc_rt.cmake --include  # the include directory (sc_rt/law.hpp)

``cmake -S . -B build -DCMAKE_PREFIX_PATH="$(python -m sc_rt.cmake)"``.
"""

from __future__ import annotations

import sys
from pathlib import Path

__all__ = ["cmake_dir", "include_dir", "main"]


def _find(rel: str) -> Path:
    import sc_rt

    for base in list(sc_rt.__path__):  # an editable install maps the package over two folders
        p = Path(base) / rel
        if p.exists():
            return p.resolve()
    raise FileNotFoundError(f"sc_rt/{rel} is not installed with the package (rebuild: make install)")


def cmake_dir() -> Path:
    """The directory holding sc_rtConfig.cmake."""
    return _find("share/cmake/sc_rt")


def include_dir() -> Path:
    """The include directory with sc_rt/law.hpp."""
    return _find("include")


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv not in ([], ["--cmakedir"], ["--include"]):
        print("usage: python -m sc_rt.cmake [--cmakedir | --include]", file=sys.stderr)
        return 2
    try:
        print(include_dir() if argv == ["--include"] else cmake_dir())
    except FileNotFoundError as e:
        print(f"sc_rt.cmake: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
