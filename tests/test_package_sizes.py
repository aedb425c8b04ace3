"""Packages and modules of python/sc_rt stay small (issue 38, "Acceptance"):
no package has more than :data:`MAX_MODULES` modules, no module more than
:data:`MAX_LINES` lines, and the modules over :data:`AIM_LINES` lines are
exactly those of :data:`OVER_AIM`, an allow-list that may only shrink (an
entry whose module came back under the aim fails until it is removed; a new
module over the aim fails until it is split, or named here in review).

A package is a folder holding an ``__init__.py`` (python/sc_rt itself
included); its modules are its own ``.py`` files except ``__init__.py`` and
``__main__.py``, which hold no job of their own (the package's docstring and
exports, ``python -m``). Lines are counted as ``wc -l`` does (newlines).
Generated tables are exempt by name (:data:`GENERATED`).

Fails on the main before issue 38's moves: scenario/ had 20 modules there.
"""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "python" / "sc_rt"

MAX_MODULES = 15  # modules per package (issue 38)
MAX_LINES = 600  # lines per module, a hard limit (issue 38)
AIM_LINES = 400  # lines per module aimed at (issue 38)
NOT_MODULES = ("__init__.py", "__main__.py")

#: Generated data, exempt from the line limits: path under python/sc_rt -> its generator.
GENERATED = {
    "model/igrf14_table.py": "tools/gen_igrf14.py (the IGRF-14 coefficients as data)",
    "model/wmm2025_table.py": "tools/gen_wmm2025.py (the WMM2025 coefficients as data)",
}

#: Modules over AIM_LINES, each waiting for its split: path under python/sc_rt -> why it is still here.
#: May only shrink.
OVER_AIM: dict[str, str] = {}


def _lines(path: Path) -> int:
    return path.read_bytes().count(b"\n")


def size_problems(pkg: Path, over_aim: dict[str, str] = OVER_AIM) -> list[str]:
    """What breaks the limits in the package tree rooted at ``pkg``, given
    the allow-list ``over_aim`` of modules over the aim."""
    bad: list[str] = []
    for init in sorted(pkg.rglob("__init__.py")):
        if "__pycache__" in init.parts:
            continue
        folder = init.parent
        mods = [m for m in folder.glob("*.py") if m.name not in NOT_MODULES]
        if len(mods) > MAX_MODULES:
            rel = folder.relative_to(pkg).as_posix()
            bad.append(f"{rel or '.'}/: {len(mods)} modules, more than {MAX_MODULES}")
    for mod in sorted(pkg.rglob("*.py")):
        rel = mod.relative_to(pkg).as_posix()
        if "__pycache__" in mod.parts or rel in GENERATED:
            continue
        n = _lines(mod)
        if n > MAX_LINES:
            bad.append(f"{rel}: {n} lines, more than {MAX_LINES}")
        elif n > AIM_LINES and rel not in over_aim:
            bad.append(f"{rel}: {n} lines, more than {AIM_LINES} and not in OVER_AIM")
    for rel in sorted(over_aim):
        if not (pkg / rel).is_file():
            bad.append(f"{rel}: in OVER_AIM, no such module (remove the entry)")
        elif _lines(pkg / rel) <= AIM_LINES:
            bad.append(f"{rel}: in OVER_AIM but {_lines(pkg / rel)} lines now (remove the entry)")
    return bad


def test_no_package_or_module_is_over_its_limit():
    assert size_problems(PKG) == []


def test_generated_modules_exist():
    """An exemption names a real generated file (else it would exempt nothing)."""
    assert [p for p in GENERATED if not (PKG / p).is_file()] == []


def _tree(tmp: Path, modules: dict[str, int]) -> Path:
    """A package tree of ``modules`` (relative path -> line count), every folder a package."""
    pkg = tmp / "sc_rt"
    for rel, n in modules.items():
        path = pkg / rel
        for folder in [path.parent, *path.parent.parents]:
            folder.mkdir(parents=True, exist_ok=True)
            (folder / "__init__.py").touch()
            if folder == pkg:
                break
        path.write_text("x = 1\n" * n)
    return pkg


def test_sixteen_modules_in_a_package_fail_and_init_and_main_do_not_count(tmp_path):
    mods = {f"scenario/m{i}.py": 1 for i in range(MAX_MODULES)} | {"scenario/__main__.py": 1}
    assert size_problems(_tree(tmp_path / "a", mods), {}) == []
    mods["scenario/one_more.py"] = 1
    assert size_problems(_tree(tmp_path / "b", mods), {}) == [f"scenario/: 16 modules, more than {MAX_MODULES}"]


def test_long_modules_fail_unless_generated_or_allowed(tmp_path):
    pkg = _tree(tmp_path, {"a/long.py": MAX_LINES + 1, "a/aim.py": AIM_LINES + 1, "a/ok.py": AIM_LINES,
                           "model/igrf14_table.py": 5 * MAX_LINES})
    problems = size_problems(pkg, {})
    assert f"a/long.py: {MAX_LINES + 1} lines, more than {MAX_LINES}" in problems
    assert f"a/aim.py: {AIM_LINES + 1} lines, more than {AIM_LINES} and not in OVER_AIM" in problems
    assert len(problems) == 2  # the module at the aim and the generated table pass
    assert size_problems(pkg, {"a/aim.py": "allowed"}) == [f"a/long.py: {MAX_LINES + 1} lines, more than {MAX_LINES}"]


def test_an_allowed_module_back_under_the_aim_or_gone_must_leave_the_list(tmp_path):
    pkg = _tree(tmp_path, {"a/split.py": AIM_LINES})
    assert size_problems(pkg, {"a/split.py": "", "a/gone.py": ""}) == [
        "a/gone.py: in OVER_AIM, no such module (remove the entry)",
        f"a/split.py: in OVER_AIM but {AIM_LINES} lines now (remove the entry)",
    ]
