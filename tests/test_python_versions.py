"""The Python versions sc-rt installs on (issue 42 item 6): a tested cap.

The bindings call CPython's C API where it changed between versions
(``_Py_IsFinalizing`` until 3.12, ``Py_IsFinalizing`` from 3.13:
cpp/bindings/pylaw_bindings.cpp), so ``requires-python`` states the range
whose code paths the source has, and pip refuses a newer interpreter with
its own message instead of a compile error. Only 3.11 is installed here;
this checks the cap against the source, and the interpreter against the cap."""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path

from packaging.specifiers import SpecifierSet
from packaging.version import Version

ROOT = Path(__file__).resolve().parent.parent


def _spec() -> SpecifierSet:
    return SpecifierSet(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["requires-python"])


def test_requires_python_has_an_upper_bound_the_bindings_cover():
    spec = _spec()
    allowed = [m for m in range(11, 20) if Version(f"3.{m}") in spec]
    assert allowed and allowed[0] == 11 and allowed == list(range(11, allowed[-1] + 1)), allowed
    assert Version("3.19") not in spec, "requires-python has no upper bound"
    src = (ROOT / "cpp" / "bindings" / "pylaw_bindings.cpp").read_text()
    # every version-dependent branch of the bindings: the versions it names must cover the range
    hexes = {int(h, 16) for h in re.findall(r"PY_VERSION_HEX\s*>=\s*(0x[0-9A-Fa-f]+)", src)}
    newest_branch = max(((h >> 16) & 0xFF for h in hexes), default=11)
    # the cap ends at the newest version the source has a branch for: raising it means reading the C API again
    assert allowed[-1] == newest_branch == 13, (allowed, sorted(hexes))


def test_this_interpreter_is_in_the_range():
    v = f"{sys.version_info.major}.{sys.version_info.minor}"
    assert Version(v) in _spec(), (v, str(_spec()))
