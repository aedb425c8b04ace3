"""The plant's magnetorquer rods (docs/MODEL.md sections 13 and 16): their
axes, limits and timed faults, and the body dipole ``m_B = G d`` they give
for rod commands ``d`` (the Python twin of ``rods_dipole_B`` in
cpp/src/plant.cpp, the same scalar operations in the same order).

Per rod, as the core's ``Magnetorquers.update``: the command clipped to
``+-max_dipole``, then its fault while active (``onset <= t < end``): dead
(0), stuck (a fixed dipole whatever the command), reversed (the clipped
command with its sign flipped). ``rods_applied`` gives each rod's dipole
and fault state (the emulator's plant_truth_t ``rod_dipole``,
``rod_fault``), ``rods_dipole_B`` the body dipole of them.

Examples
--------
>>> import numpy as np
>>> r = Magnetorquers(axes=np.eye(3), max_dipole=np.full(3, 5.0),
...                   faults=(RodFault(rod=1, kind="reversed"),))
>>> rods_dipole_B(r, 0.0, [10.0, 2.0, -1.0])  # rod 0 clipped, rod 1 reversed
(5.0, -2.0, -1.0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["MAX_RODS", "ROD_FAULTS", "RodFault", "Magnetorquers", "rods_applied", "rods_applied_B", "rods_dipole_B",
           "rods_to_cpp"]

MAX_RODS = 6  # the core's kMaxRods
#: a rod fault's kind -> the core's RodFault value
ROD_FAULTS = {"dead": 1, "stuck": 2, "reversed": 3}


@dataclass(frozen=True)
class RodFault:
    """One rod's fault, active on ``onset <= t < end`` [s]."""

    rod: int  # 0-based
    kind: str  # "dead", "stuck" or "reversed"
    dipole: float = 0.0  # [A m^2] a stuck rod's dipole
    onset: float = 0.0  # [s]
    end: float = math.inf  # [s]


@dataclass(frozen=True)
class Magnetorquers:
    """N rods (1 to 6): unit axes in B (3, N) and per-rod limits (N,) [A m^2].

    Validated on construction (ValueError naming the field and the value).
    """

    axes: np.ndarray  # [-] (3, N) unit rod axes in B, one column per rod
    max_dipole: np.ndarray  # [A m^2] (N,) per-rod limit, > 0
    faults: tuple = ()  # RodFault, at most one per rod

    def __post_init__(self) -> None:
        G = np.array(self.axes, dtype=float)
        lim = np.array(self.max_dipole, dtype=float).reshape(-1)
        errs: list[str] = []
        if G.ndim != 2 or G.shape[0] != 3 or not 1 <= G.shape[1] <= MAX_RODS:
            errs.append(f"Magnetorquers.axes must be 3xN with 1 <= N <= {MAX_RODS}, got shape {G.shape}")
        else:
            n = G.shape[1]
            if not np.all(np.isfinite(G)):
                errs.append(f"Magnetorquers.axes is not finite: {G.tolist()!r}")
            else:
                for i, norm in enumerate(np.linalg.norm(G, axis=0)):
                    if abs(norm - 1.0) > 1e-6:
                        errs.append(f"Magnetorquers.axes: rod {i + 1}'s axis is not a unit vector (norm {norm!r})")
            if lim.shape != (n,):
                errs.append(f"Magnetorquers.max_dipole has {lim.size} entries for {n} rods")
            elif not np.all(np.isfinite(lim) & (lim > 0.0)):
                errs.append(f"Magnetorquers.max_dipole must be finite and > 0, got {lim.tolist()!r}")
            seen = set()
            for f in self.faults:
                if not isinstance(f, RodFault) or not 0 <= f.rod < n or f.kind not in ROD_FAULTS:
                    errs.append(f"Magnetorquers.faults: not a fault of one of the {n} rods: {f!r}")
                elif f.rod in seen:
                    errs.append(f"Magnetorquers.faults: rod {f.rod + 1} has more than one fault")
                elif not (math.isfinite(f.dipole) and math.isfinite(f.onset) and f.end > f.onset):
                    errs.append(f"Magnetorquers.faults: rod {f.rod + 1}: dipole and onset finite, end > onset: {f!r}")
                elif lim.shape == (n,) and abs(f.dipole) > lim[f.rod]:  # a rod holds no more than its limit
                    errs.append(f"Magnetorquers.faults: rod {f.rod + 1} stuck at {f.dipole!r} A m^2, beyond "
                                f"its limit {float(lim[f.rod])!r} A m^2")
                seen.add(getattr(f, "rod", None))
        if errs:
            raise ValueError("invalid Magnetorquers: " + "; ".join(errs))
        G.setflags(write=False)
        lim.setflags(write=False)
        object.__setattr__(self, "axes", G)
        object.__setattr__(self, "max_dipole", lim)
        object.__setattr__(self, "faults", tuple(self.faults))

    @property
    def n_rods(self) -> int:
        return int(self.axes.shape[1])


def rods_applied(r: Magnetorquers, t: float, d_cmd=None) -> tuple[list[float], list[int]]:
    """Each rod's dipole [A m^2] for the rod commands ``d_cmd`` [A m^2]
    (None: all 0) at ``t`` [s], clipped then through its active fault, and
    each rod's fault state at ``t``: 0 none, the fault's ``ROD_FAULTS`` value
    while active (``onset <= t < end``), minus it outside that window
    (plant_truth_t ``rod_fault``).

    Examples
    --------
    >>> r = Magnetorquers(axes=np.eye(3), max_dipole=np.full(3, 5.0),
    ...                   faults=(RodFault(rod=2, kind="dead", onset=1.0),))
    >>> rods_applied(r, 0.0, [10.0, 2.0, -1.0])  # rod 2's fault not yet active
    ([5.0, 2.0, -1.0], [0, 0, -1])
    """
    n = r.n_rods
    d = [0.0] * n if d_cmd is None else [float(v) for v in d_cmd]
    if len(d) != n:
        raise ValueError(f"rods_dipole_B: {len(d)} dipole commands for {n} rods")
    lim = r.max_dipole.tolist()
    for i in range(n):
        d[i] = min(max(d[i], -lim[i]), lim[i])  # per-rod clip, as MtbEffector
    state = [0] * n
    for f in r.faults:
        i = f.rod
        if f.onset <= t < f.end:
            d[i] = 0.0 if f.kind == "dead" else f.dipole if f.kind == "stuck" else -d[i]
            state[i] = ROD_FAULTS[f.kind]
        else:
            state[i] = -ROD_FAULTS[f.kind]
    return d, state


def rods_dipole_B(r: Magnetorquers, t: float, d_cmd=None) -> tuple[float, float, float]:
    """The body dipole ``m_B = G d`` [A m^2] of the rod commands ``d_cmd``
    [A m^2] (None: all 0) at ``t`` [s]: each clipped, then its active fault
    (``rods_applied``)."""
    return rods_applied_B(r, t, d_cmd)[1]


def rods_applied_B(r: Magnetorquers, t: float, d_cmd=None) -> tuple[list[float], tuple[float, float, float]]:
    """Each rod's dipole [A m^2] (``rods_applied``'s) and the body dipole
    ``m_B = G d`` [A m^2] of them (``rods_dipole_B``'s, the same operations)
    for the rod commands ``d_cmd`` [A m^2] (None: all 0) at ``t`` [s]: what
    a row records as ``rod_dipole`` and ``m_B``."""
    n = r.n_rods
    d = rods_applied(r, t, d_cmd)[0]
    G = r.axes.tolist()
    m = []
    for row in G:
        s = row[0] * d[0]
        for i in range(1, n):
            s = s + row[i] * d[i]
        m.append(s)
    return d, (m[0], m[1], m[2])


def rods_to_cpp(r: Magnetorquers | None):
    """The C++ ``sc_rt._core.PlantRods`` of ``r`` (None: disabled)."""
    from sc_rt import _core

    c = _core.PlantRods()
    if r is None:
        return c
    c.enabled = True
    mp = _core.MagnetorquerParams()
    mp.G_B = np.array(r.axes)
    mp.dipole_max = np.array(r.max_dipole)
    c.params = mp
    for f in r.faults:
        c.set_fault(f.rod, _core.RodFault(ROD_FAULTS[f.kind]), f.dipole, f.onset, f.end)
    return c
