"""``sc-rt montecarlo``: how robust is a design? The campaign machinery is
the ``sc_rt.studies.campaign`` package; this module keeps the one-call API.

    res = run_montecarlo(scn, 200, workers=2, seed=1)   # summary + res["per_run"]
    write_montecarlo(res, Path("out/mc"))               # montecarlo.json, montecarlo.png
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

from sc_rt.plan.run import RunPlan
from sc_rt.scenario.model import Scenario
from sc_rt.studies.campaign import Dispersion, disperse, plan_campaign, run_campaign, write_summary
from sc_rt.studies.campaign.store import RunStore

__all__ = ["Dispersion", "disperse", "run_montecarlo", "write_montecarlo"]


def run_montecarlo(scn: Scenario | RunPlan, runs: int, *, workers: int | None = None, seed: int = 0,
                   dispersion: Dispersion = Dispersion(), law: str | None = None,
                   control_rate_hz: float | None = None, progress: bool = True,
                   out: Path | None = None, **campaign: Any) -> dict[str, Any]:
    """A campaign of ``runs`` runs; the summary with ``per_run`` (the dataset's
    rows by run id). The scenario itself goes to the workers (in-memory
    changes included). ``out``: where the dataset goes (default: a temporary
    directory, removed); ``campaign``: more options of ``run_campaign``.

    Every run is simulated on the cpp engine; its draws depend on
    (``seed``, run id) only, so a campaign is the same for any ``workers``.

    Parameters
    ----------
    scn : Scenario or RunPlan
        The nominal scenario, planned once with ``law`` and
        ``control_rate_hz`` (sc_rt.studies.campaign.plan_campaign), or a
        base plan already made (``sc_rt.plan_run(..., engine="cpp")``; then
        ``law`` and ``control_rate_hz`` are not used). Its ``[montecarlo]``
        table, if any, adds its dispersions to the shortcut ones.
    runs : int
        The number of runs (ids 0 .. runs - 1).
    workers : int, optional
        Worker processes. None: one per CPU (the local backend).
    seed : int
        The campaign's seed.
    dispersion : Dispersion
        The shortcut dispersions, half-widths of uniform draws: inertia [-],
        products of inertia [-], fault onset and end shift [s], fault
        effectiveness [-], initial attitude [rad] and rate [rad/s].
    law : str, optional
        Override of the scenario's law (as ``sc_rt.with_overrides``).
    control_rate_hz : float, optional
        [Hz] override of the scenario's control rate.
    progress : bool
        A progress bar on stderr (when it is a terminal).
    out : Path, optional
        The dataset's directory (runs/, montecarlo.json), kept. None: a
        temporary directory, removed.
    **campaign
        More keyword options of ``run_campaign``: ``backend``,
        ``scheduler``, ``scheduler_file``, ``resume``, ``overwrite``,
        ``batch_size``, and for the requirements' statements
        ``confidence`` (default 0.95) and ``coverage`` (the fraction of
        runs a per-run requirement must hold in, default 0.95).

    Returns
    -------
    dict
        The campaign's summary (as montecarlo.json: runs, the fraction
        holding the bound with its 95 % interval, the failed runs, each
        requirement's statistics across the runs in ``requirements``
        (docs/REQUIREMENTS.md), ...) and ``per_run``: the dataset's rows (a
        dict per run: id, status, the drawn values, the metrics, the
        requirements' results ``req.NAME.*``).

    Raises
    ------
    CampaignExists
        ``out`` holds runs already (without ``resume`` or ``overwrite``), or
        a different campaign to resume.
    """
    c = plan_campaign(scn, dispersion, seed, law, control_rate_hz)
    with tempfile.TemporaryDirectory(prefix="sc-rt-mc-") as tmp:
        where = Path(out) if out is not None else Path(tmp)
        res = run_campaign(c, runs, where, workers=workers, progress=progress, **campaign)
        res["per_run"] = RunStore(where, c.columns()).read().to_pylist()
    return res


def write_montecarlo(res: dict[str, Any], out: Path) -> None:
    """montecarlo.json (without the rows) and montecarlo.png."""
    write_summary(res, res["per_run"], Path(out))
