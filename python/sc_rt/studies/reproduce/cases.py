"""The reproduction's cases and runs: the two paper scenarios, the four laws,
and every run of one reproduction (``run_all``).

Scenarios are the shipped ones, by name (``sc_rt.scenario.shipped``):
:func:`shipped_scenario` is the one place that finds a scenario's file.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from sc_rt.scenario.model import LAWS as LAW_TABLE
from sc_rt.scenario.model import Scenario
from sc_rt.scenario.reader import load_scenario
from sc_rt.scenario.shipped import shipped
from sc_rt.sim.engines import simulate

__all__ = ["CASES", "LAWS", "LAW_LABEL", "Runs", "load_cases", "run_all", "scenario_label",
           "shipped_scenario"]

#: case -> shipped scenario name
CASES = {"fault_free": "paper_fault_free", "faults": "paper_faults"}
LAWS = tuple(LAW_TABLE)  # the law table, in the core's order
LAW_LABEL = {"dsc-ppc": "DSC+PPC", "dsc": "DSC", "pd": "PD", "rft": "RFT"}


def shipped_scenario(name: str) -> Scenario:
    """The shipped scenario ``name`` ("paper_faults"), whatever the working
    directory holds: a reproduction runs the scenarios sc-rt ships."""
    return load_scenario(shipped()[name][0])


def scenario_label(name: str) -> str:
    """How the outputs name a shipped scenario: its file in the source tree."""
    return f"scenarios/{name}.toml"


@dataclass
class Runs:
    """Every run of one reproduction: results[case][law] and the scenarios.

    A result is read only by name (``r["sigma_BD"]``) and through ``r.metrics``.
    """

    scenarios: dict[str, Scenario]
    results: dict[str, dict[str, Any]]
    engine: str
    control_rate_hz: float | None
    plant_step: float | None


def load_cases() -> dict[str, Scenario]:
    return {c: shipped_scenario(name) for c, name in CASES.items()}


def run_all(*, engine: str = "cpp", control_rate_hz: float | None = None,
            plant_step: float | None = None, duration: float | None = None,
            scenarios: dict[str, Scenario] | None = None) -> Runs:
    """All four laws in every case (default: both paper scenarios)."""
    scns = scenarios if scenarios is not None else load_cases()
    res = {c: {law: simulate(s, law=law, engine=engine, control_rate_hz=control_rate_hz,
                             plant_step=plant_step, duration=duration) for law in LAWS}
           for c, s in scns.items()}
    return Runs(scns, res, engine, control_rate_hz, plant_step)
