"""The shipped type stub of sc_rt._core names exactly what the module has."""

import ast
from pathlib import Path

from sc_rt import _core

STUB = Path(__file__).resolve().parent.parent / "python" / "sc_rt" / "_core.pyi"


def test_stub_lists_every_public_name():
    tree = ast.parse(STUB.read_text())
    declared = None
    for node in tree.body:
        if isinstance(node, ast.AnnAssign) and getattr(node.target, "id", "") == "__all__":
            declared = set(ast.literal_eval(node.value))
    assert declared is not None, "no __all__ in the stub"
    public = {n for n in dir(_core) if not n.startswith("_")}
    assert declared == public, f"stale stub (make stubs): missing {public - declared}, extra {declared - public}"


def test_stub_defines_every_class_and_function():
    tree = ast.parse(STUB.read_text())
    defined = {n.name for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef))}
    for name in dir(_core):
        obj = getattr(_core, name)
        if name.startswith("_") or not callable(obj):
            continue
        assert name in defined, name
