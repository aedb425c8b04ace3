"""The declared per-row fields of a run (``FIELDS``): name, shape of one
row, unit, where the value comes from, and what it means; the table every
producer fills and every reader reads (results/record/run.py ``Run``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Field", "FIELDS", "FIELD", "CORE_FIELDS", "COLUMNS", "SOURCES", "empty_arrays", "packed_layout"]

SOURCES = ("plant", "controller", "truth", "timing", "derived", "estimator")


@dataclass(frozen=True)
class Field:
    """One per-row array of a run.

    ``FIELDS`` (public as ``sc_rt.FIELDS``) is the tuple of every one, in the
    order trajectory.npz lists them; ``FIELD`` maps name -> Field.

    Attributes
    ----------
    name : str
        The array's name (``run[name]``).
    shape : tuple of int
        The shape of one row (``()``: a scalar per row).
    unit : str
        Its unit ("s", "rad/s", "rad/s^2", "us", "-" for none).
    source : str
        Where the value comes from: one of ``SOURCES``.
    doc : str
        What it means (the equation numbers are docs/MODEL.md's).
    dtype : str
        Its numpy dtype ("f8", "i8", "?").
    fill : Any
        The value of a row the producer did not fill (NaN; -1, 0 or False
        for the integer and boolean fields).
    core : bool
        Part of the trajectory every producer fills (checked for finiteness
        by the metrics).
    """

    name: str
    shape: tuple[int, ...]  # of one row
    unit: str
    source: str  # one of SOURCES
    doc: str
    dtype: str = "f8"
    fill: Any = math.nan
    #: part of the trajectory every producer fills (checked for finiteness by the metrics)
    core: bool = False


def _f(name, shape, unit, source, doc, core=False, dtype="f8", fill=math.nan) -> Field:
    return Field(name, shape, unit, source, doc, dtype, fill, core)


#: Every per-row array of a run, in the order trajectory.npz lists them.
FIELDS: tuple[Field, ...] = (
    _f("t", (), "s", "plant", "control instant t_k = k / rate", True),
    _f("sigma_BN", (3,), "-", "plant", "MRP attitude of the body B relative to N at t_k", True),
    _f("omega_BN_B", (3,), "rad/s", "plant", "body rate relative to N, body frame", True),
    _f("wheel_speed", (4,), "rad/s", "plant", "wheel speeds relative to the body", True),
    _f("sigma_DN", (3,), "-", "controller", "desired attitude (guidance) at t_k", True),
    _f("sigma_BD", (3,), "-", "controller", "attitude tracking error, MRP of B relative to D (8)", True),
    _f("omega_BD_B", (3,), "rad/s", "controller", "rate tracking error, body frame (8)", True),
    _f("u_cmd", (4,), "rad/s^2", "controller",
       "wheel acceleration command before saturation (what the law asked for)", True),
    _f("u_sat", (4,), "rad/s^2", "controller", "the command after the controller's saturation (15)", True),
    _f("wheel_accel", (4,), "rad/s^2", "truth", "actual wheel acceleration, faults applied (15)", True),
    _f("z1", (3,), "rad/s", "controller", "NESO estimate of the rate error state", True),
    _f("z2", (3,), "rad/s^2", "controller", "NESO estimate of the lumped disturbance", True),
    _f("delta2", (3,), "rad/s^2", "truth", "true lumped disturbance (20),(21)", True),
    _f("chi", (3,), "-", "controller", "prescribed envelope chi(t) the controller used (29)", True),
    _f("lam", (3,), "-", "controller", "normalised error lambda = sigma_BD / chi (30)", True),
    _f("bound_ok", (3,), "-", "derived",
       "-dmin chi(t) < sigma_BD < dmax chi(t) per axis, from the scenario's envelope", True, "?", False),
    _f("e1", (3,), "-", "controller", "transformed error of the PPC (34)"),
    _f("e2", (3,), "rad/s", "controller", "second DSC surface error (27)"),
    _f("vs", (4,), "rad/s^2", "controller", "anti-windup auxiliary state (42)"),
    _f("x2d", (3,), "rad/s", "controller",
       "the law's filtered virtual control, DSC's filter output (LawOutput.x2d; 0 unused)"),
    _f("rho_hat", (), "rad/s^2", "controller", "the law's adaptive gain (LawOutput.rho_hat: RFT's; 0 unused)"),
    _f("telemetry", (8,), "-", "controller",
       "the law's named telemetry (LawOutput.telemetry): column i is the run's telemetry_names[i], "
       "unit as its name gives it ('name [unit]'); 0 unused"),
    _f("flags", (), "-", "controller", "controller flags bit set (safety, bound, invalid input)",
       dtype="i8", fill=0),
    _f("ctrl_mode", (), "-", "controller", "controller mode: 0 INIT, 1 NORMAL, 2 SAFE; -1 unknown",
       dtype="i8", fill=-1),
    _f("cmd_seq_applied", (), "-", "truth", "seq of the wheel_cmd_t the plant applied (-1: none)",
       dtype="i8", fill=-1),
    _f("cmd_stale", (), "-", "truth", "1 when the watchdog applied zero (no valid command)",
       dtype="i8", fill=0),
    _f("fault_Y", (4,), "-", "truth", "fault evolution Y_i(t) (16)"),
    _f("fault_effectiveness", (4,), "-", "truth", "wheel effectiveness L_i of the active fault"),
    _f("fault_bias", (4,), "rad/s^2", "truth", "wheel bias of the active fault"),
    _f("fault_stuck", (4,), "-", "truth", "1 when the wheel is stuck", dtype="i8", fill=0),
    # With [sensors] (sc_rt.sim.sensed; the MEKF of cpp/include/sc_rt/mekf.hpp), NaN otherwise:
    _f("sigma_BN_est", (3,), "-", "estimator",
       "MEKF attitude estimate at t_k (what the law gets with measurement = estimate)"),
    _f("bias_est", (3,), "rad/s", "estimator", "MEKF gyro bias estimate"),
    _f("bias_true", (3,), "rad/s", "truth", "the gyro's true bias (bias0 + Gauss-Markov + random walk)"),
    _f("P_diag", (6,), "rad^2, (rad/s)^2", "estimator",
       "MEKF covariance diagonal: attitude error (3, body) then bias error (3)"),
    _f("att_est_error", (3,), "rad", "truth",
       "estimation error: rotation vector of the true attitude relative to the estimate, body frame"),
    _f("innovation", (3,), "rad", "estimator",
       "star tracker residual of the last update since the previous row (NaN: none)"),
    _f("nis", (), "-", "estimator", "normalised innovation squared z' S^-1 z of that update (NaN: none)"),
    _f("sigma_BD_true", (3,), "-", "derived",
       "true tracking error mrp_subtract(sigma_BN, sigma_DN) (sensor runs: the bound is judged on it)"),
    _f("omega_BD_B_true", (3,), "rad/s", "derived",
       "true rate tracking error omega_BN_B - [BD] omega_DN_D(t), [BD] of sigma_BD_true (sensor runs)"),
    _f("latency_us", (), "us", "timing", "state publish to receipt of the command answering it"),
    _f("tick_lateness_us", (), "us", "timing", "real time: the emulator's tick behind its deadline"),
    _f("wake_lateness_us", (), "us", "timing", "the controller's wake behind its schedule"),
    _f("compute_us", (), "us", "timing", "the controller's compute time for this state"),
    _f("state_age_us", (), "us", "timing", "age of the state when the controller used it"),
    _f("state_log_us", (), "us", "timing", "logger receive time of the state (log rebuilds)"),
)
FIELD: dict[str, Field] = {f.name: f for f in FIELDS}
#: The fields as the columns of a run's file (results/record/store.py ``Column``: name, row shape, dtype, fill).
COLUMNS: tuple[tuple[str, tuple[int, ...], str, Any], ...] = tuple((f.name, f.shape, f.dtype, f.fill) for f in FIELDS)
#: The trajectory every producer fills (checked for finiteness by the metrics).
CORE_FIELDS: tuple[str, ...] = tuple(f.name for f in FIELDS if f.core)
assert all(f.source in SOURCES for f in FIELDS)


def empty_arrays(n: int) -> dict[str, np.ndarray]:
    """Every field of ``n`` rows at its fill value."""
    return {f.name: np.full((n, *f.shape), f.fill, dtype=f.dtype) for f in FIELDS}


def packed_layout(fields, size: int) -> dict[str, slice]:
    """name -> slice of a packed row of the core (``_core.PACKED_FIELDS``,
    ``_core.NAV_FIELDS``: (name, width) in the order the C++ writes them);
    ValueError when the widths do not add up to ``size``."""
    out: dict[str, slice] = {}
    at = 0
    for name, n in fields:
        out[name] = slice(at, at + n)
        at += n
    if at != size:
        raise ValueError(f"the packed fields add up to {at}, not {size}")
    return out
