"""The law interface's ABI rule is checked, not a comment (issue #26, item 5):
"bump SC_RT_LAW_API_VERSION whenever a type of this file changes". The
declarations a plugin shares with the core (cpp/include/sc_rt/law.hpp and
types.hpp, comments and whitespace removed) are hashed and the hash is
pinned per interface version here: a change of any declaration without a
version bump fails this test; a bump needs its new pin. A plugin built
against another version is refused at load (tests/test_laws.py)."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
HEADERS = ("cpp/include/sc_rt/law.hpp", "cpp/include/sc_rt/types.hpp")

#: interface version -> sha256 of its declarations (declarations())
PINS = {
    1: "d593e58814b643bfb78a09388437b6f1915f50926b0eb19928b794b66e245e09",
    # issue #26: the setup without the core config (the built-ins read LawParams), the wheel interface in LawModel
    2: "fed39dccadd317d5bc25d4bbbeefb314669f1c550dc173b6ef1f9ffe2beaf4de",
    # issue 39: LawModel::wheel_command gives a on acceleration wheels and Jw a on torque wheels (was inverted)
    3: "c58c5f9427d8a5743fc161b9706d3edff685e3ae1b19a7a2c0b18edcf91d816e",
    # issue 39 item 3, revision 1 (additive: plugins of 3 still load): LawCommand, SC_RT_LAW_COMMAND
    (3, 1): "56a6d9cea1ace4eec4d80dd2372d5c0233bb675c82c687253053678af525026b",
}


def declarations(texts: list[str]) -> str:
    """The headers' code without comments, tokens joined by one space."""
    out = []
    for t in texts:
        t = re.sub(r"/\*.*?\*/", " ", t, flags=re.S)
        t = re.sub(r"//[^\n]*", " ", t)
        out.append(" ".join(t.split()))
    return "\n".join(out)


def version_and_hash(texts: list[str]) -> tuple[int | tuple[int, int], str]:
    """(the interface's version, or (version, revision) from revision 1 on, sha256 of its declarations)."""
    m = re.search(r"#define SC_RT_LAW_API_VERSION (\d+)", texts[0])
    assert m, "no SC_RT_LAW_API_VERSION"
    r = re.search(r"#define SC_RT_LAW_API_REVISION (\d+)", texts[0])
    version = int(m.group(1)) if r is None or int(r.group(1)) == 0 else (int(m.group(1)), int(r.group(1)))
    return version, hashlib.sha256(declarations(texts).encode()).hexdigest()


def problem(texts: list[str]) -> str | None:
    version, h = version_and_hash(texts)
    pin = PINS.get(version)
    if pin is None:
        return f"SC_RT_LAW_API_VERSION {version} has no pinned layout: pin {h} in tests/test_law_abi.py"
    if pin != h:
        return (f"the law interface's declarations changed (sha256 {h}) but SC_RT_LAW_API_VERSION is still "
                f"{version} (pinned {pin}): bump the version (plugins built before must be refused) and pin it")
    return None


def _texts() -> list[str]:
    return [(ROOT / h).read_text() for h in HEADERS]


def test_the_interface_matches_the_layout_pinned_for_its_version():
    assert problem(_texts()) is None, problem(_texts())


def test_a_changed_field_without_a_bump_fails_and_a_bump_needs_a_pin():
    law, types = _texts()
    changed = law.replace("struct LawInput {", "struct LawInput {\n  double extra = 0.0;", 1)
    assert changed != law
    why = problem([changed, types])
    assert why is not None and "bump the version" in why
    bumped = re.sub(r"#define SC_RT_LAW_API_VERSION \d+", "#define SC_RT_LAW_API_VERSION 999", changed)
    assert "has no pinned layout" in problem([bumped, types])
    # comments and whitespace are not the layout
    reformatted = law.replace("struct LawInput {", "struct   LawInput   {  // a comment", 1)
    assert problem([reformatted, types]) is None
