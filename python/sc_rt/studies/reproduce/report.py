"""``reproduce``: every run, the claims, the options' studies, and the files
(claims.json, claims.md, the figures) written where ``out`` says."""

from __future__ import annotations

import json
import shlex
from pathlib import Path
from typing import Any

from sc_rt.results.judge.metrics import json_safe
from sc_rt.studies.reproduce.cases import run_all
from sc_rt.studies.reproduce.claims import claims_of, format_claims_md
from sc_rt.studies.reproduce.figures import DPI, claim_figures, write_figures
from sc_rt.studies.reproduce.root_cause import root_cause
from sc_rt.studies.reproduce.search import feasible_search, format_search_md
from sc_rt.studies.reproduce.sensitivity import format_sensitivity_md, sensitivity

__all__ = ["command_line", "reproduce"]


def command_line(out: Path, *, engine: str = "cpp", control_rate_hz: float | None = None,
                 plant_step: float | None = None, plots: bool = True, with_sensitivity: bool = False,
                 with_search: bool = False, dpi: int = DPI) -> str:
    """The canonical ``sc-rt reproduce`` command line of these options."""
    parts = ["sc-rt", "reproduce", "--out", str(out), "--engine", engine]
    if control_rate_hz is not None:
        parts += ["--control-rate", f"{control_rate_hz:g}"]
    if plant_step is not None:
        parts += ["--plant-step", f"{plant_step:g}"]
    parts += (["--sensitivity"] if with_sensitivity else []) + (["--search"] if with_search else [])
    parts += ([] if plots else ["--no-plots"]) + ([] if dpi == DPI else ["--dpi", str(dpi)])
    return " ".join(shlex.quote(p) for p in parts)


def reproduce(out: Path, *, engine: str = "cpp", control_rate_hz: float | None = None,
              plant_step: float | None = None, plots: bool = True, with_sensitivity: bool = False,
              with_search: bool = False, command: str | None = None, dpi: int = DPI) -> dict[str, Any]:
    """Run everything, write claims.json, claims.md and the figures into ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if command is None:
        command = command_line(out, engine=engine, control_rate_hz=control_rate_hz, plant_step=plant_step,
                               plots=plots, with_sensitivity=with_sensitivity, with_search=with_search,
                               dpi=dpi)
    runs = run_all(engine=engine, control_rate_hz=control_rate_hz, plant_step=plant_step)
    doc = claims_of(runs, command)
    md = ["# Claims of MODEL.md section 8", "", format_claims_md(doc)]
    if with_sensitivity:
        sens = sensitivity(engine=engine, scenarios=runs.scenarios)
        doc["sensitivity"] = sens
        md += ["## Sensitivity: verdicts by control rate and plant step", "", format_sensitivity_md(sens)]
        if plots:
            doc["root_cause"] = root_cause(out, engine=engine, scenarios=runs.scenarios, dpi=dpi)
    if with_search:
        doc["feasible"] = feasible_search(engine=engine)
        md += ["## Tightest chiinf that holds (bisection, both cases, 300 s) and the shipped designs", "",
               format_search_md(doc["feasible"])]
    if plots:
        doc["figures"] = [p.name for p in write_figures(claim_figures(runs), out, dpi=dpi)]
    (out / "claims.json").write_text(json.dumps(json_safe(doc), indent=2) + "\n")
    (out / "claims.md").write_text("\n".join(md))
    return doc
