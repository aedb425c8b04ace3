"""Monte Carlo campaigns (``sc-rt montecarlo``): dispersed runs of a scenario
on a local pool or a Dask cluster, streamed to a resumable Parquet dataset,
with exact confidence intervals and tolerance bounds.

- draws.py: one run's drawn values from (seed, run id), O(1) seeding, and its scenario;
- backends.py: serial, process pool, Dask (LocalCluster or a scheduler);
- store.py: the dataset (one Parquet file per completed batch);
- stats.py: Clopper-Pearson (two- and one-sided), Wilks, the runs a statement needs;
- requirements.py: the scenario's requirements across the runs (docs/REQUIREMENTS.md);
- runner.py: the campaign planned once (a base plan, its dispersions and seed), a run
  alone (--rerun: the recorded draw replayed), the summary;
- figure.py: montecarlo.json and montecarlo.png.
"""

from sc_rt.studies.campaign.backends import SchedulerUnreachable, make_backend
from sc_rt.studies.campaign.draws import (NO_SHORTCUTS, Dispersion, RunDraw, disperse, draw_run, plan_draw,
                                          run_seed_sequence)
from sc_rt.studies.campaign.figure import write_summary
from sc_rt.studies.campaign.runner import (Campaign, CampaignExists, plan_campaign, rerun, run_campaign,
                                           run_one, summarize)
from sc_rt.studies.campaign.stats import clopper_pearson, tolerance_bound, wilks_order, wilks_runs
from sc_rt.studies.campaign.store import RunStore

__all__ = ["Campaign", "CampaignExists", "Dispersion", "NO_SHORTCUTS", "RunDraw", "RunStore", "plan_campaign",
           "plan_draw",
           "SchedulerUnreachable", "clopper_pearson", "disperse", "draw_run", "make_backend",
           "rerun", "run_campaign", "run_one", "run_seed_sequence", "summarize",
           "tolerance_bound", "wilks_order", "wilks_runs", "write_summary"]
