"""The sources pass ruff with the rule set of pyproject.toml ([tool.ruff]:
pycodestyle E/W, pyflakes F, bugbear B, 120 columns), and that check bites:
a file with an unused import, a mutable default argument and a too-long
line, linted with the same configuration, is refused."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RUFF = Path(sys.executable).with_name("ruff")
PATHS = ("python", "tests", "bench", "examples")


def _ruff(config: Path, cwd: Path, *paths: str) -> subprocess.CompletedProcess:
    assert RUFF.is_file(), f"{RUFF} is missing: pip install -e '.[test]' (ruff is in the test extra)"
    return subprocess.run([str(RUFF), "check", "--no-cache", "--output-format", "concise", "--config", str(config),
                           *paths], cwd=cwd, capture_output=True, text=True, timeout=120)


def _ruff_sections(pyproject: str) -> str:
    """The [tool.ruff] table and its sub-tables, as they are written."""
    out, keep = [], False
    for line in pyproject.splitlines():
        header = re.match(r"\s*\[\[?([^\]]+)\]", line)
        if header:
            keep = header.group(1).strip() == "tool.ruff" or header.group(1).strip().startswith("tool.ruff.")
        if keep:
            out.append(line)
    return "\n".join(out) + "\n"


def test_the_sources_pass_ruff():
    r = _ruff(ROOT / "pyproject.toml", ROOT, *PATHS)
    assert r.returncode == 0, r.stdout + r.stderr


def test_ruff_reports_a_deliberate_finding(tmp_path):
    text = _ruff_sections((ROOT / "pyproject.toml").read_text())
    # the copy is the whole configuration, not a part of it
    assert tomllib.loads(text)["tool"]["ruff"] == tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["ruff"]
    (tmp_path / "pyproject.toml").write_text(text)
    (tmp_path / "bad.py").write_text(
        "import os\n"
        "\n"
        "\n"
        "def add(x, acc=[]):\n"
        "    acc.append(x)\n"
        f"    return acc  # {'words ' * 20}end\n"  # 141 columns
        f"# {'y' * 95}\n")  # 97 columns: within the 120 of the configuration
    r = _ruff(tmp_path / "pyproject.toml", tmp_path, "bad.py")
    assert r.returncode == 1, r.stdout + r.stderr
    found = re.findall(r"^bad\.py:(\d+):\d+: ([A-Z]+\d+)", r.stdout, flags=re.MULTILINE)
    assert sorted(found) == [("1", "F401"), ("4", "B006"), ("6", "E501")], r.stdout + r.stderr
