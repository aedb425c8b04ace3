"""The run columns of a Python-stepped closed loop: the plant rows and the
packed telemetry rows (``_core.step_packed``'s layout) split into run fields,
once for the plain and the sensed loop."""

from __future__ import annotations

import math

import numpy as np

from sc_rt.model.rods import MAX_RODS, rods_applied_B

__all__ = ["loop_columns", "AppliedRods", "LAW_FAILURES", "TELEMETRY_NAMES", "INT_FIELDS"]

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


class AppliedRods:
    """The rods' truth of each row (``m_B``, ``rod_dipole``; docs/MODEL.md
    section 16) for the plant's rods ``rods`` (model.rods.Magnetorquers;
    None: no rods, both fields stay NaN) over ``n`` rows: the closed loop's
    ``m_B_app``/``rod_app`` of cpp/src/closed_loop.cpp, the same operations."""

    def __init__(self, rods, n: int):
        self.rods = rods
        self.m_B = np.full((n, 3), math.nan)  # [A m^2]
        self.rod_dipole = np.full((n, MAX_RODS), math.nan)  # [A m^2]

    def row(self, k: int, t: float, d_cmd=None) -> tuple | None:
        """Row k at t [s] with the rod commands ``d_cmd`` [A m^2] held (None:
        no magnetic control, a zero command): the body dipole [A m^2] the
        row's first plant step holds (None without rods), recorded."""
        if self.rods is None:
            return None
        d, m_B = rods_applied_B(self.rods, t, d_cmd)
        self.m_B[k] = m_B
        self.rod_dipole[k, :len(d)] = d
        return m_B

    def columns(self) -> dict[str, np.ndarray]:
        return {"m_B": self.m_B, "rod_dipole": self.rod_dipole}


#: The key under which an engine hands the law's contained failures
#: (``_core.Controller.law_failures``: counts per call and the newest) to
#: ``simulate`` beside its columns; ``simulate`` moves them to the run's
#: metrics (``law_failures``). Not a run field.
LAW_FAILURES = "_law_failures"

#: The key under which an engine hands the law's telemetry names
#: (``Controller.telemetry_names``: what the run's ``telemetry`` columns hold)
#: to ``simulate``, which puts them in the run's meta. Not a run field.
TELEMETRY_NAMES = "_telemetry_names"
