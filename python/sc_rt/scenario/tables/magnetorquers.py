"""The scenario's ``[magnetorquers]`` table: the plant's magnetorquer rods
and their faults (sc_rt.model.rods.Magnetorquers; docs/SCENARIOS.md,
docs/MODEL.md sections 13 and 16). Without the table the plant has none,
exactly as before.

The rod axes are given once: ``axes``, one unit vector in B per rod, or
``G_B``, the 3xN matrix (3 rows of N numbers, one column per rod). An axis
within 1e-2 of unit length is normalised (one unit to 1e-12 is kept as
given); ``max_dipole`` is one number for every rod or a list of N.
``[[magnetorquers.faults]]``: ``rod`` (1-based), ``kind`` ("dead", "stuck",
"reversed"), ``dipole`` (a stuck rod's, A m^2), ``onset`` and ``end`` (s),
one fault per rod.
"""

from __future__ import annotations

import math

import numpy as np

from sc_rt.model.rods import MAX_RODS, ROD_FAULTS, Magnetorquers, RodFault
from sc_rt.scenario.schema import Spec, Table

__all__ = ["read_magnetorquers"]


def _numbers(v) -> bool:
    return isinstance(v, list) and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)


def _read_axes(t: Table) -> np.ndarray | None:
    if t.has("axes") == t.has("G_B"):
        t.fail("axes", "give the rod axes once: axes (one unit vector per rod) or G_B (3 rows of N), not both"
               if t.has("axes") else "the rod axes are required: axes (one unit vector per rod) or G_B (3xN)")
        t.used.update(("axes", "G_B"))
        return None
    key = "axes" if t.has("axes") else "G_B"
    t.used.add(key)
    raw = t.raw(key)
    if key == "axes":
        ok = isinstance(raw, list) and 1 <= len(raw) <= MAX_RODS and all(_numbers(r) and len(r) == 3 for r in raw)
        G = np.array(raw, dtype=float).T if ok else None
        shape = f"a list of 1 to {MAX_RODS} vectors of 3 numbers"
    else:
        ok = (isinstance(raw, list) and len(raw) == 3 and all(_numbers(r) for r in raw)
              and len({len(r) for r in raw}) == 1 and 1 <= len(raw[0]) <= MAX_RODS)
        G = np.array(raw, dtype=float) if ok else None
        shape = f"3 rows of N numbers, 1 <= N <= {MAX_RODS}"
    if G is None or not np.all(np.isfinite(G)):
        t.fail(key, f"{key} must be {shape}")
        return None
    norms = np.linalg.norm(G, axis=0)
    bad = [i + 1 for i, n in enumerate(norms) if abs(n - 1.0) > 1e-2]
    if bad:
        t.fail(key, f"the axis of rod {bad[0]} is not a unit vector (norm {norms[bad[0] - 1]:.6g})")
        return None
    # normalised where it is not unit already: a file written from a scenario reads back to the same bits
    return np.where(np.abs(norms - 1.0) > 1e-12, G / norms, G)


def _read_faults(t: Table, n: int | None, lim) -> tuple[RodFault, ...] | None:
    """The rods' faults (``lim``: the rods' limits [A m^2], one or N; None: unread)."""
    t.used.add("faults")
    raw = t.raw("faults") if t.has("faults") else []
    if not (isinstance(raw, list) and all(isinstance(f, dict) for f in raw)):
        t.fail("faults", "faults must be an array of tables ([[magnetorquers.faults]])")
        return None
    faults, seen = [], set()
    for i, entry in enumerate(raw):
        f = Table(t.doc, f"{t.key}.faults[{i}]", entry)
        rod = f.read("rod", Spec("int", ge=1, le=MAX_RODS))
        kind = f.read("kind", Spec("str", choices=tuple(ROD_FAULTS)))
        dipole = f.read("dipole", Spec("number"), default=0.0)
        onset = f.read("onset", Spec("number", ge=0), default=0.0)
        end = f.read("end", Spec("number"), default=math.inf)
        f.finish()
        if None in (rod, kind, dipole, onset, end):
            continue
        if n is not None and rod > n:
            f.fail("rod", f"rod must be 1 to {n} (the rods given), got {rod}")
        elif rod in seen:
            f.fail("rod", f"rod {rod} already has a fault: one fault per rod")
        elif not end > onset:
            f.fail("end", f"end must be > onset ({onset:g} s)")
        elif f.has("dipole") and kind != "stuck":
            f.fail("dipole", f'dipole is a stuck rod\'s value: kind = "{kind}" takes none')
        elif lim is not None and abs(dipole) > (limit := float(np.broadcast_to(lim, (n,))[rod - 1])):
            f.fail("dipole", f"a rod sticks within its limit: |dipole| <= max_dipole = {limit:g} A m^2")
        else:
            seen.add(rod)
            faults.append(RodFault(rod=rod - 1, kind=kind, dipole=float(dipole), onset=float(onset),
                                   end=float(end)))
    return tuple(faults) if len(faults) == len(raw) else None


def read_magnetorquers(root: Table, field_model: str | None) -> Magnetorquers | None | bool:
    """The Magnetorquers of the scenario's ``[magnetorquers]`` table; None
    when it has none; False after reporting a problem. Rods act through the
    field: they need ``[environment] field`` other than "none"."""
    if not root.has("magnetorquers"):
        root.used.add("magnetorquers")
        return None
    t = root.sub("magnetorquers")
    if t.data is None:
        return False
    G = _read_axes(t)
    n = None if G is None else G.shape[1]
    lim = t.read("max_dipole", Spec("vector", shape=(n or 1,), scalar_ok=True, gt=0)) if n else None
    if not n:
        t.used.add("max_dipole")
    faults = _read_faults(t, n, lim)
    t.finish()
    if G is None or lim is None or faults is None:
        return False
    if field_model == "none":  # (None: [environment] was refused, reported)
        t.fail("max_dipole" if t.has("max_dipole") else "axes",
               'magnetorquers act through the field: give [environment] field = "igrf", "wmm2025" or "dipole"')
        return False
    try:
        return Magnetorquers(axes=G, max_dipole=np.asarray(lim, float), faults=faults)
    except ValueError as err:
        t.fail("axes" if t.has("axes") else "G_B", str(err))
        return False
