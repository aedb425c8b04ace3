"""Sensitivity: the claims' verdicts at other control rates and plant steps."""

from __future__ import annotations

from typing import Any

from sc_rt.scenario.model import Scenario
from sc_rt.studies.reproduce.cases import load_cases, run_all
from sc_rt.studies.reproduce.claims import claims_of

__all__ = ["SENSITIVITY_CONFIGS", "format_sensitivity_md", "sensitivity"]

#: (label, control rate [Hz], plant step [s])
SENSITIVITY_CONFIGS = (
    ("10 Hz, plant step 0.1 s (paper)", 10.0, 0.1),
    ("10 Hz, plant step 0.01 s", 10.0, 0.01),
    ("100 Hz, plant step 0.01 s", 100.0, 0.01),
    ("1 kHz, plant step 0.001 s", 1000.0, 0.001),
)


def sensitivity(engine: str = "cpp", configs=SENSITIVITY_CONFIGS,
                scenarios: dict[str, Scenario] | None = None) -> list[dict[str, Any]]:
    """Per configuration: every claim's verdict and measured text (all eight runs rerun)."""
    scns = scenarios if scenarios is not None else load_cases()
    rows = []
    for label, rate, step in configs:
        runs = run_all(engine=engine, control_rate_hz=rate, plant_step=step, scenarios=scns)
        doc = claims_of(runs, "")
        rows.append({"config": label, "control_rate_hz": rate, "plant_step_s": step,
                     "claims": {c["id"]: {"verdict": c["verdict"], "measured": c["measured"]}
                                for c in doc["claims"]}})
    return rows


def format_sensitivity_md(rows: list[dict[str, Any]]) -> str:
    ids = list(rows[0]["claims"])
    lines = ["| config | " + " | ".join(ids) + " |", "|---|" + "---|" * len(ids)]
    for r in rows:
        lines.append(f"| {r['config']} | " + " | ".join(r["claims"][i]["verdict"] for i in ids) + " |")
    lines += ["", "Measured numbers per configuration:", ""]
    for r in rows:
        lines.append(f"- **{r['config']}**")
        for i in ids:
            lines.append(f"  - {i}: {r['claims'][i]['measured']}")
    return "\n".join(lines) + "\n"
