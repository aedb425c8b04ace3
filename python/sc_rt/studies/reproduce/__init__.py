"""``sc-rt reproduce``: the paper's claims (MODEL.md section 8) checked with numbers.

Runs both paper scenarios (the shipped ``paper_fault_free`` and
``paper_faults``) with all four laws at the scenarios' 10 Hz zero-order hold
and 0.1 s plant step (or the overrides given), writes paper-style figures per
scenario and ``claims.json`` / ``claims.md``: one row per claim, the measured
numbers, a verdict and the command that made it.

- ``cases``: the cases, the laws, the shipped scenarios by name, all runs;
- ``verdicts``: the verdict rule (``case_holds``, ``verdict_of``);
- ``claims``: the claims measured on the runs and their markdown table;
- ``figures``: the paper-style figures (returned as Figures, then saved);
- ``sensitivity``: the verdicts at other control rates and plant steps;
- ``root_cause``: the sampled loop's spectral radius against the runs;
- ``search``: the tightest chiinf that holds (bisection), the feasible designs;
- ``report``: ``reproduce``, which runs all of it and writes the files.

The scenario variants the studies use (``with_ppc``, ``with_law_params``,
``without_faults``) are ``sc_rt.scenario.variants``.
"""

from __future__ import annotations

from sc_rt.studies.reproduce.cases import CASES, LAWS, Runs, load_cases, run_all, shipped_scenario
from sc_rt.studies.reproduce.claims import CLAIM_IDS, claims_of, format_claims_md
from sc_rt.studies.reproduce.figures import claim_figures
from sc_rt.studies.reproduce.report import reproduce
from sc_rt.studies.reproduce.root_cause import root_cause
from sc_rt.studies.reproduce.search import chiinf_min, feasible_search, holds, tightest_chiinf
from sc_rt.studies.reproduce.sensitivity import sensitivity
from sc_rt.studies.reproduce.verdicts import case_holds, verdict_of

__all__ = [
    "CASES",
    "CLAIM_IDS",
    "LAWS",
    "Runs",
    "case_holds",
    "chiinf_min",
    "claim_figures",
    "claims_of",
    "feasible_search",
    "format_claims_md",
    "holds",
    "load_cases",
    "reproduce",
    "root_cause",
    "run_all",
    "sensitivity",
    "shipped_scenario",
    "tightest_chiinf",
    "verdict_of",
]
