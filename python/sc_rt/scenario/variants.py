"""Variants of a scenario: the same scenario with one group of parameters changed.

Each function returns a new, frozen :class:`Scenario`; the original is not
touched. Nothing is re-validated (the values are taken as given), so these
are for studies that vary a parameter around a validated scenario (the
reproduction's chiinf bisection, its fault-free copies).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from sc_rt.scenario.tables.laws import with_items
from sc_rt.scenario.model import Scenario

__all__ = ["with_law_params", "with_ppc", "without_faults"]


def with_ppc(scn: Scenario, **ppc: Any) -> Scenario:
    """The scenario with prescribed-performance fields (29) replaced, each as a float array
    (``with_ppc(scn, chiinf=[4e-6, 2e-6, 1.4e-6])``)."""
    c = scn.controller
    return dataclasses.replace(scn, controller=dataclasses.replace(
        c, ppc=dataclasses.replace(c.ppc, **{k: np.asarray(v, float) for k, v in ppc.items()})))


def with_law_params(scn: Scenario, law: str, **values: Any) -> Scenario:
    """The scenario with parameters of law ``law``'s table replaced as given
    (``with_law_params(scn, "dsc-ppc", k2=16.0)``)."""
    c = scn.controller
    return dataclasses.replace(scn, controller=dataclasses.replace(c, laws=with_items(c.laws, law, **values)))


def without_faults(scn: Scenario) -> Scenario:
    """The scenario with no wheel faults (its fault-free copy)."""
    return dataclasses.replace(scn, actuators=dataclasses.replace(scn.actuators, faults=()))
