"""The run columns of a Python-stepped closed loop: the plant rows and the
packed telemetry rows (``_core.step_packed``'s layout) split into run fields,
once for the plain and the sensed loop."""

from __future__ import annotations

import numpy as np

__all__ = ["loop_columns", "LAW_FAILURES", "TELEMETRY_NAMES", "INT_FIELDS"]

#: The packed integer fields of the magnetic part besides flags and ctrl_mode (fields.hpp)
INT_FIELDS = ("unloading", "detumble_mode")


def loop_columns(T, X, ACC, D2, OUT, packed: dict[str, slice], recorded: dict[str, str]) -> dict[str, np.ndarray]:
    """t, the plant state, wheel_accel, delta2, the recorded telemetry, flags
    and ctrl_mode (-1 where no step ran)."""
    cols = {"t": T, "sigma_BN": X[:, 0:3], "omega_BN_B": X[:, 3:6], "wheel_speed": X[:, 6:10],
            "wheel_accel": ACC, "delta2": D2}
    for name, p in recorded.items():
        col = OUT[:, packed[p]]
        cols[name] = col[:, 0] if col.shape[1] == 1 else col  # a scalar field: one column
    for name in INT_FIELDS:  # the controller's integer fields: -1 where no step ran or none is kept
        if name in cols:
            cols[name] = np.nan_to_num(cols[name], nan=-1).astype(np.int64)
    cols["flags"] = np.nan_to_num(OUT[:, packed["flags"]][:, 0]).astype(np.int64)
    cols["ctrl_mode"] = np.nan_to_num(OUT[:, packed["ctrl_mode"]][:, 0], nan=-1).astype(np.int64)
    return cols


#: The key under which an engine hands the law's contained failures
#: (``_core.Controller.law_failures``: counts per call and the newest) to
#: ``simulate`` beside its columns; ``simulate`` moves them to the run's
#: metrics (``law_failures``). Not a run field.
LAW_FAILURES = "_law_failures"

#: The key under which an engine hands the law's telemetry names
#: (``Controller.telemetry_names``: what the run's ``telemetry`` columns hold)
#: to ``simulate``, which puts them in the run's meta. Not a run field.
TELEMETRY_NAMES = "_telemetry_names"
