"""The control law's own telemetry in a run's outputs: the fixed slots a law
may fill beside its command (x2d, rho_hat) and its named values (the run
field ``telemetry``, named by ``meta.telemetry_names``), summarised in
metrics.json (``law_telemetry``), listed in report.html
(sc_rt.results.present.html_telemetry) and drawn in law_telemetry.png
(sc_rt.results.present.telemetry_figure). A law that fills none of them
gets none of these."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sc_rt.pylaw import split_unit
from sc_rt.results.record.run import Run

__all__ = ["TelemetryAcc", "telemetry_summary"]


class TelemetryAcc:
    """Final, min and max of each named value, and whether the fixed slots
    were used, a chunk at a time (the metrics' pass over a run on disk)."""

    def __init__(self, run: Run):
        self.names = tuple(run.meta.telemetry_names)  # column i of the run's telemetry
        self.stats = [[math.nan, math.inf, -math.inf, 0] for _ in self.names]  # final, min, max, finite rows
        self.used = {"x2d": False, "rho_hat": False}

    def add(self, c: Run) -> None:
        if self.names:
            tel = np.asarray(c["telemetry"], float)
            for i, s in enumerate(self.stats):
                ok = tel[:, i][np.isfinite(tel[:, i])]
                if ok.size:
                    s[0] = float(ok[-1])
                    s[1], s[2] = min(s[1], float(ok.min())), max(s[2], float(ok.max()))
                    s[3] += int(ok.size)
        for slot in self.used:
            if slot in c:
                v = np.asarray(c[slot], float)
                self.used[slot] = self.used[slot] or bool(np.any(np.isfinite(v) & (v != 0.0)))

    def summary(self) -> dict[str, Any]:
        """``{"names": [...], "values": {name: {unit, final, min, max}}, "fixed_slots_used": [...]}``."""
        values = {name: {"unit": split_unit(name)[1], "final": final if n else None, "min": lo if n else None,
                         "max": hi if n else None}
                  for name, (final, lo, hi, n) in zip(self.names, self.stats)}
        return {"names": list(self.names), "values": values,
                "fixed_slots_used": [k for k, v in self.used.items() if v]}


def telemetry_summary(run: Run) -> dict[str, Any]:
    """The law's named values over the run's finite rows (final, min, max)
    and which fixed slots (x2d, rho_hat) it filled: ``TelemetryAcc.summary``."""
    acc = TelemetryAcc(run)
    for c in run.chunks():
        acc.add(c)
    return acc.summary()
