"""``sc-rt montecarlo``: how robust is a design? The campaign machinery is
the ``sc_rt.studies.campaign`` package; this module keeps the one-call API.

    res = run_montecarlo(scn, 200, workers=2, seed=1)   # summary + res["per_run"]
    write_montecarlo(res, Path("out/mc"))               # montecarlo.json, montecarlo.png
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

from sc_rt.scenario.model import Scenario
from sc_rt.studies.campaign import Campaign, Dispersion, disperse, run_campaign, write_summary
from sc_rt.studies.campaign.store import RunStore

__all__ = ["Dispersion", "disperse", "run_montecarlo", "write_montecarlo"]


def run_montecarlo(scn: Scenario, runs: int, *, workers: int | None = None, seed: int = 0,
                   dispersion: Dispersion = Dispersion(), law: str | None = None,
                   control_rate_hz: float | None = None, progress: bool = True,
                   out: Path | None = None, **campaign: Any) -> dict[str, Any]:
    """A campaign of ``runs`` runs; the summary with ``per_run`` (the dataset's
    rows by run id). The scenario itself goes to the workers (in-memory
    changes included). ``out``: where the dataset goes (default: a temporary
    directory, removed); ``campaign``: more options of ``run_campaign``."""
    c = Campaign(scn, dispersion, seed, law, control_rate_hz)
    with tempfile.TemporaryDirectory(prefix="sc-rt-mc-") as tmp:
        where = Path(out) if out is not None else Path(tmp)
        res = run_campaign(c, runs, where, workers=workers, progress=progress, **campaign)
        res["per_run"] = RunStore(where, c.columns()).read().to_pylist()
    return res


def write_montecarlo(res: dict[str, Any], out: Path) -> None:
    """montecarlo.json (without the rows) and montecarlo.png."""
    write_summary(res, res["per_run"], Path(out))
