"""Bitwise comparison of two runs' per-row fields (a trajectory.arrow, a
simulate result): every field both produced, and the core trajectory always
(shared by the HIL tests); ``load_traj``, a run's trajectory.arrow read with
pyarrow alone (not through sc_rt's reader)."""

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
    """Every field of the HIL run's trajectory that the simulator also
    produced, each required bit-identical; the core trajectory always."""
    done = []
    for k in hil.files:
        if k == "meta_json":
            continue
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
    """A run's columns by name, read like the npz files runs were once
    written as (``.files``, ``["meta_json"]``, ``with ... as z``)."""

    @property
    def files(self) -> list[str]:
        return list(self)

    def __enter__(self) -> _Columns:
        return self

    def __exit__(self, *exc) -> None:
        return None


def load_traj(out):
    """The per-row arrays a run wrote into ``out`` (its trajectory.arrow, read
    with pyarrow: a vector field's fixed-size list reshaped by the file's
    ``sc-rt:shapes``), and its meta as ``"meta_json"`` (the JSON string of the
    schema metadata's ``sc-rt:meta``)."""
    import json
    from pathlib import Path

    import pyarrow as pa

    path = Path(out) / "trajectory.arrow"
    with pa.OSFile(str(path), "rb") as f:
        table = pa.ipc.open_file(f).read_all()
    md = {k.decode(): v.decode() for k, v in table.schema.metadata.items()}
    shapes = json.loads(md["sc-rt:shapes"])
    cols = _Columns()
    for name in table.column_names:
        shape, dtype = shapes[name]
        col = table.column(name).combine_chunks()
        flat = col.flatten() if shape else col
        cols[name] = np.asarray(flat.to_numpy(zero_copy_only=False), dtype=dtype).reshape(-1, *shape)
    cols["meta_json"] = np.array(md["sc-rt:meta"])
    return cols


def lockstep_equals_sim(path, out, duration: float, engine: str = "python", rate_hz: float = 10.0):
    """Run the scenario file ``path`` with ``sc-rt hil --mode lockstep`` for
    ``duration`` [s] into ``out`` (in the test's network namespace, lcmnet),
    and the offline engine ``engine`` on the same file: the same number of
    rows and every field both produced bit-identical (compared_fields).
    Returns (hil columns, sim run)."""
    import lcmnet

    from sc_rt.scenario.reader import load_scenario
    from sc_rt.sim.engines import simulate

    lcmnet.require()
    r = lcmnet.run_cli(["hil", str(path), "--mode", "lockstep", "--duration", str(duration), "--out", str(out),
                        "--no-plots"])
    assert r.returncode == 0, r.stderr + r.stdout
    hil = load_traj(out)
    sim = simulate(load_scenario(path), engine=engine, duration=duration)
    assert len(hil["t"]) == len(sim["t"]) == round(duration * rate_hz) + 1
    compared_fields(hil, sim)
    return hil, sim
