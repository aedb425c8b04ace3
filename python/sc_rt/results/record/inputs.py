"""What a run was made from, for its record (issue 41 item 5, traceability):
the scenario file and its SHA-256, the law and its parameters as run (its
declared defaults filled in), and which sc-rt made it (version and, in a
git checkout, the commit). ``run_inputs(scn)`` is stored in ``RunMeta.inputs``
and so in metrics.json, the trajectory's meta and report.html."""

from __future__ import annotations

import functools
import hashlib
import subprocess
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["run_inputs", "sc_rt_commit"]


@functools.lru_cache(maxsize=1)
def sc_rt_commit() -> str | None:
    """The commit of the sc-rt sources this process runs (``git describe
    --always --dirty`` of the checkout holding the package; None when the
    package is not in a git checkout, e.g. an installed wheel)."""
    here = Path(__file__).resolve().parent
    if not any((p / ".git").exists() for p in here.parents):
        return None
    try:
        r = subprocess.run(["git", "-C", str(here), "describe", "--always", "--dirty", "--abbrev=40"],
                           capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return r.stdout.strip() or None if r.returncode == 0 else None


def _sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


def _plain(v: Any) -> Any:
    return [float(x) for x in np.ravel(v)] if isinstance(v, np.ndarray) else v


def run_inputs(scn: Any, law_name: str) -> dict[str, Any]:
    """What ``scn`` (a Scenario, overrides applied) was made from: its file
    and that file's SHA-256 now, the overrides it records (``scn.overrides``),
    the parameters of the law ``law_name`` as it runs them, and sc-rt's
    version and commit."""
    from sc_rt import __version__
    from sc_rt.scenario.tables.laws import resolved

    path = getattr(scn, "path", None)
    laws = getattr(getattr(scn, "controller", None), "laws", ())
    try:
        params = {k: _plain(v) for k, v in resolved(laws, law_name).items()}
    except (ValueError, RuntimeError):
        params = None
    return {"scenario_file": None if path is None else str(path),
            "scenario_sha256": None if path is None else _sha256(path),
            "overrides": {k: v for k, v in getattr(scn, "overrides", ())},
            "law_params": params,
            "sc_rt_version": __version__, "sc_rt_commit": sc_rt_commit()}
