"""Bitwise comparison of two runs' per-row fields (a trajectory.npz, a
simulate result): every field both produced, and the core trajectory always
(shared by the HIL tests)."""

from __future__ import annotations

import numpy as np

#: The trajectory both a lockstep run and the offline simulator produce.
CORE_FIELDS = ("t", "sigma_BN", "omega_BN_B", "sigma_DN", "sigma_BD", "omega_BD_B", "wheel_speed",
               "u_cmd", "u_sat", "wheel_accel", "z1", "z2", "delta2", "chi", "lam", "bound_ok")


def _produced(v: np.ndarray) -> bool:
    """Whether a producer filled v (not all NaN, not one constant fill value)."""
    if v.size == 0:
        return False
    if v.dtype.kind == "f":
        return not np.all(np.isnan(v))
    return v.dtype.kind == "b" or not np.all(v == v.flat[0])


def compared_fields(hil, sim) -> list[str]:
    """Every field of the HIL run's trajectory.npz that the simulator also
    produced, each required bit-identical; the core trajectory always."""
    done = []
    for k in hil.files:
        try:
            b = sim[k]
        except KeyError:  # HIL-only (latencies, controller timing)
            continue
        a = hil[k]
        if k not in CORE_FIELDS and not (_produced(a) and _produced(b)):
            continue
        assert a.shape == b.shape, (k, a.shape, b.shape)
        if not np.array_equal(a, b, equal_nan=a.dtype.kind == "f"):
            rows = np.flatnonzero(np.any((a != b).reshape(len(a), -1), axis=1))
            raise AssertionError(f"{k} differs in {rows.size} rows, the first {rows[0]}: "
                                 f"{a[rows[0]]} != {b[rows[0]]}")
        done.append(k)
    missing = set(CORE_FIELDS) - set(done)
    assert not missing, f"not compared: {sorted(missing)}"
    return done


class _Columns(dict):
    """A run's columns by name, read like a trajectory.npz (``.files``)."""

    @property
    def files(self) -> list[str]:
        return list(self)


def load_traj(out):
    """The per-row arrays a run wrote into ``out``: its trajectory.npz, or
    (a run written to disk as it ran) its trajectory.arrow's columns."""
    from pathlib import Path

    out = Path(out)
    if (out / "trajectory.npz").exists():
        return np.load(out / "trajectory.npz")
    from sc_rt.results.record.run import Run

    return _Columns(Run.load(out).trajectory)
