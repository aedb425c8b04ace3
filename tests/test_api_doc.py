"""docs/API.md's walk-through runs exactly as written: every python block, in
order, in one namespace (OUT is a temporary directory)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

import lcmnet

ROOT = Path(__file__).resolve().parent.parent
pytestmark = [pytest.mark.lcm, pytest.mark.slow]


def test_api_walkthrough_runs_as_written(tmp_path):
    text = (ROOT / "docs" / "API.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) >= 6
    script = tmp_path / "walkthrough.py"
    script.write_text("from pathlib import Path\nOUT = Path(%r)\n" % str(tmp_path) + "\n".join(blocks))
    lcmnet.require()
    r = lcmnet.run([sys.executable, str(script)], timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "paper DSC+PPC: left its prescribed bound at 4.10 s (axis z)" in r.stdout
    assert "k2 = 16, wider chiinf: bound held 300 s" in r.stdout
    assert (tmp_path / "compare.png").exists() and (tmp_path / "feasible" / "metrics.json").exists()
    assert (tmp_path / "hil" / "run.lcmlog").stat().st_size > 0
