"""The README's map and its layer line cannot drift from the tree (issue 38):
every package and top-level module of python/sc_rt has a row, every nested
package is named in its parent's row, every module a row names exists, every
path in the map exists, and the stated import order is pyproject.toml's
contract. Shown to fail on a tree with a module the map does not name."""

from __future__ import annotations

import re
import shutil
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PKG_REL = "python/sc_rt"


def map_rows(readme: str) -> dict[str, str]:
    """The ``## Map`` table: each path of the first column -> its row's text."""
    sec = readme[readme.index("## Map"):]
    sec = sec[: sec.index("\n## ", 5)] if "\n## " in sec[5:] else sec
    rows: dict[str, str] = {}
    for line in sec.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 2 or cells[0] in ("path", "---"):
            continue
        for path in re.findall(r"`([^`]+)`", cells[0]):
            rows[path] = cells[1]
    return rows


def map_problems(readme: str, root: Path) -> list[str]:
    """What the map of ``readme`` gets wrong about the tree at ``root``."""
    rows = map_rows(readme)
    pkg = root / PKG_REL
    bad = [f"{p}: in the map, not in the tree" for p in rows
           if p.startswith(PKG_REL) and not (root / p.rstrip("/")).exists()]
    for entry in sorted(pkg.iterdir()):
        if entry.is_dir() and (entry / "__init__.py").exists():
            key = f"{PKG_REL}/{entry.name}/"
        elif entry.suffix == ".py" and entry.name != "__init__.py":
            key = f"{PKG_REL}/{entry.name}"
        else:
            continue
        if key not in rows:
            bad.append(f"{key}: no row in the map")
            continue
        if entry.is_dir():
            for sub in sorted(entry.iterdir()):
                if sub.is_dir() and (sub / "__init__.py").exists() and f"`{sub.name}/`" not in rows[key]:
                    bad.append(f"{key}{sub.name}/: not named in its package's row")
            for mod in re.findall(r"`([\w/]+\.py)`", rows[key]):
                if not (entry / mod).exists() and not any(entry.rglob(mod)):
                    bad.append(f"{key}: names `{mod}`, which is not in the package")
    return bad


def stated_order(readme: str) -> str:
    m = re.search(r"Imports run one way, bottom to top: `([^`]+)`", readme)
    assert m, "the README states no import order"
    return m.group(1)


def contract_order() -> str:
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"][0]
    return " -> ".join(layer.replace("sc_rt.", "") for layer in reversed(cfg["layers"]))


def test_the_map_names_every_package_and_module_of_the_tree():
    readme = (ROOT / "README.md").read_text()
    assert map_problems(readme, ROOT) == []
    assert [p for p in map_rows(readme) if not (ROOT / p.rstrip("/")).exists()] == []


def test_the_stated_import_order_is_the_contract():
    assert stated_order((ROOT / "README.md").read_text()) == contract_order()


def _tree_copy(tmp: Path) -> Path:
    shutil.copytree(ROOT / PKG_REL, tmp / PKG_REL, ignore=shutil.ignore_patterns("*.so", "__pycache__"))
    return tmp


def test_a_module_added_without_a_row_fails_the_map(tmp_path):
    root = _tree_copy(tmp_path)
    readme = (ROOT / "README.md").read_text()
    assert map_problems(readme, root) == []
    (root / PKG_REL / "newthing.py").write_text('"""A module nobody mapped."""\n')
    (root / PKG_REL / "results" / "extra").mkdir()
    (root / PKG_REL / "results" / "extra" / "__init__.py").write_text("")
    problems = map_problems(readme, root)
    assert f"{PKG_REL}/newthing.py: no row in the map" in problems
    assert f"{PKG_REL}/results/extra/: not named in its package's row" in problems


def test_a_row_naming_a_removed_module_fails_the_map(tmp_path):
    root = _tree_copy(tmp_path)
    (root / PKG_REL / "hil" / "procs.py").unlink()
    problems = map_problems((ROOT / "README.md").read_text(), root)
    assert f"{PKG_REL}/hil/: names `procs.py`, which is not in the package" in problems


def test_a_changed_contract_fails_the_stated_order():
    readme = (ROOT / "README.md").read_text()
    swapped = readme.replace("-> export -> live ->", "-> live -> export ->")
    assert swapped != readme and stated_order(swapped) != contract_order()
