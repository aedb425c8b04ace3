"""Where a bench run's numbers came from, for its metrics: the plant's and the
controller's LCM sessions and whether the run is valid (a run another bench
mixed into is not). The emulator, ``sc-rt hil`` and ``sc-rt report`` add
``provenance(...)`` to a run's metrics (metrics.json)."""

from __future__ import annotations

from typing import Any

__all__ = ["provenance"]


def provenance(plant_session: int | None, controller_session: int | None,
               invalid: str | None = None) -> dict[str, Any]:
    """The bench run's metrics keys saying where its numbers came from: the
    plant and controller sessions (LCM ids, None: none) and whether the run
    is valid (False, with the reason: another bench on the same channels
    mixed into it, emulator/collision.py)."""
    out: dict[str, Any] = {"valid": invalid is None, "plant_session": plant_session,
                           "controller_session": controller_session}
    if invalid is not None:
        out["invalid_reason"] = invalid
    return out
