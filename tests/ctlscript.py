"""Pieces for tests that drive sc-rt-controller by hand in a shell script
(tests/lcmnet.py runs the script in a private network namespace)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def controller_config(scenario: str, out: Path) -> Path:
    """The scenario's controller_config_t written to ``out`` (sc-rt config)."""
    subprocess.run([sys.executable, "-m", "sc_rt.cli", "config", scenario, "--out", str(out)], check=True,
                   capture_output=True, cwd=ROOT)
    return out


def wait_for_line(pattern: str, err: Path | str) -> str:
    """A script line that polls ``err`` until it holds ``pattern`` (a
    process's start line), 60 s at most: an event, not a fixed sleep."""
    return f"for i in $(seq 600); do grep -q '{pattern}' {err} && break; sleep 0.1; done"
