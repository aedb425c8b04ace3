"""A law spec is parsed where it is resolved, not below (issue 38 item 2):
``sc_rt.pylaw.is_python_law`` (whether a spec string names a Python class)
is called only by pylaw itself (the owner of the format: ``python_law``,
``registry_spec``), the plan's resolver (sc_rt.plan.law.law_ref), the
scenario reader's spec form (sc_rt.scenario.lawspec.law_spec: a file made
absolute, the ``python:`` prefix added) and the command line's parsing of
``--law``. Everything else reads the plan's typed law (``RunPlan.law``) or
asks pylaw. Fails on the old main, where sim/, scenario/tables/laws.py,
scenario/model.py and sim/isolated.py each read the spec again."""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parent.parent / "python" / "sc_rt"

#: module (relative to python/sc_rt) -> how many calls it may make, and why
ALLOWED = {
    "pylaw.py": 2,  # python_law, registry_spec: the format's owner answers for it
    "plan/law.py": 1,  # law_ref: the plan resolves a spec to its typed LawRef
    "scenario/lawspec.py": 1,  # law_spec: the reader's resolved form of the file's spec
    "cli/validate.py": 1,  # law_choice: --law of the commands that plan a run
    "cli/controller.py": 1,  # sc-rt controller --law: the command line
}


def calls(tree: ast.AST, name: str) -> int:
    """Calls of ``name(...)`` or ``x.name(...)`` in ``tree``."""
    n = 0
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            if (isinstance(f, ast.Name) and f.id == name) or (isinstance(f, ast.Attribute) and f.attr == name):
                n += 1
    return n


def call_sites(root: Path, name: str) -> dict[str, int]:
    out = {}
    for f in sorted(root.rglob("*.py")):
        text = f.read_text()
        if name not in text:  # parsed only where the name is written at all
            continue
        n = calls(ast.parse(text, str(f)), name)
        if n:
            out[f.relative_to(root).as_posix()] = n
    return out


def test_is_python_law_is_called_only_where_a_spec_is_resolved():
    sites = call_sites(PKG, "is_python_law")
    extra = {m: n for m, n in sites.items() if n > ALLOWED.get(m, 0)}
    assert extra == {}, f"a law spec re-read below the plan: {extra}; read RunPlan.law or ask sc_rt.pylaw"


def test_a_new_call_below_the_plan_is_caught(tmp_path):
    # the check itself: a module of sim/ that reads the spec again is found, in a function and by attribute
    (tmp_path / "sim").mkdir()
    (tmp_path / "sim" / "x.py").write_text("from sc_rt import pylaw\n\ndef f(s):\n"
                                           "    return pylaw.is_python_law(s)\n")
    (tmp_path / "pylaw.py").write_text("def is_python_law(s):\n    return ':' in s\n\n"
                                       "def g(s):\n    return is_python_law(s)\n")
    assert call_sites(tmp_path, "is_python_law") == {"sim/x.py": 1, "pylaw.py": 1}
