"""One run's dispersed scenario, from (seed, run id) alone.

Seeding is O(1) in the run id: run i's generators are
``SeedSequence(seed, spawn_key=(i,))`` (the shortcut dispersions, the same
stream as ``SeedSequence(seed).spawn(i + 1)[i]`` of earlier versions, so old
campaigns keep their numbers) and ``SeedSequence(seed, spawn_key=(i, 1))``
(the scenario's ``[montecarlo]`` table). Nothing iterates over the ids before
i: a run can be drawn alone (``sc-rt montecarlo --rerun ID``), on any worker,
in any order.

Shortcut dispersions (the CLI flags; each run independently, uniform):
- true inertia J0 + dJ: each diagonal element scaled by 1 +- ``inertia``,
  off-diagonal products +- ``products`` of sqrt(J_ii J_jj); redrawn until the
  inertia is physical (positive definite, triangle inequality);
- wheel faults: each fault's onset (and end) shifted by +- ``onset`` s (onset
  kept >= 0), its effectiveness moved by +- ``effectiveness`` (kept in [0, 1]);
- initial attitude: rotated by up to ``attitude`` rad about a random axis;
  initial rate: +- ``rate`` rad/s per axis.

The table's draws apply after the shortcuts (their nominal is the shortcut's
result). A draw that makes the scenario invalid (the reader's checks: e.g. a
true inertia that is not positive definite, a fault end before its onset, a
gain out of bounds) is redrawn up to ``max_redraws`` times (``on_invalid =
"redraw"``, the default: the campaign samples the distributions conditioned
on a valid scenario) or counted at once (``"fail"``); a run whose attempts
all fail is a failed run (status "invalid") with the values of its last draw.

A scenario with ``[sensors]``: run i's sensors seed is drawn from
``SeedSequence([seed, sensors.seed], spawn_key=(i, 2))`` (63 bits), so every
run has its own sensor noise and initial estimation error.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sc_rt.scenario.dispersions import draw
from sc_rt.scenario.keys import element_names, get_key, scenario_data, set_key
from sc_rt.scenario.model import Scenario, ScenarioError
from sc_rt.scenario.reader import scenario_from_data

__all__ = ["Dispersion", "NO_SHORTCUTS", "disperse", "draw_run", "run_seed_sequence", "value_columns"]


@dataclass(frozen=True)
class Dispersion:
    """The shortcut dispersions (the CLI flags), half-widths of uniform draws."""

    inertia: float = 0.2  # [-] relative, diagonal of J0 + dJ
    products: float = 0.02  # [-] off-diagonal, relative to sqrt(J_ii J_jj)
    onset: float = 2.0  # [s] fault onset (and end) shift
    effectiveness: float = 0.2  # [-] fault effectiveness shift
    attitude: float = 0.01  # [rad] initial attitude rotation
    rate: float = 0.002  # [rad/s] initial rate, per axis

    def problems(self) -> list[tuple[str, float, str]]:
        """(field, value, what is wrong) of every bad field."""
        out = []
        rules = {"inertia": (0.0, 1.0, True), "products": (0.0, 0.5, False),
                 "onset": (0.0, math.inf, False), "effectiveness": (0.0, 1.0, False),
                 "attitude": (0.0, math.pi, False), "rate": (0.0, math.inf, False)}  # fmt: skip
        for name, (lo, hi, open_hi) in rules.items():
            v = getattr(self, name)
            ok = isinstance(v, (int, float)) and math.isfinite(v) and lo <= v and (v < hi if open_hi else v <= hi)
            if not ok:
                rng = f"in [{lo:g}, {hi:g}{')' if open_hi else ']'}" if math.isfinite(hi) else f">= {lo:g}"
                out.append((name, v, f"must be a finite number {rng}"))
        return out


#: No shortcut dispersion at all (a campaign of the [montecarlo] table alone).
NO_SHORTCUTS = Dispersion(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def run_seed_sequence(seed: int, run: int, stream: int | None = None) -> np.random.SeedSequence:
    """Run ``run``'s seed sequence, built directly from (seed, run): O(1) in the id."""
    key = (int(run),) if stream is None else (int(run), int(stream))
    return np.random.SeedSequence(int(seed), spawn_key=key)


def _physical(J: np.ndarray) -> bool:
    ev = np.linalg.eigvalsh(J)
    return bool(ev.min() > 0 and ev[0] + ev[1] >= ev[2])


def disperse(scn: Scenario, rng: np.random.Generator, d: Dispersion) -> Scenario:
    """One copy of ``scn`` with the shortcut dispersions (the controller's J0 is unchanged)."""
    from sc_rt import _core

    p = scn.plant
    J_nom = np.asarray(p.J0 + p.dJ, float)
    for _ in range(100):
        diag = np.diag(J_nom) * (1 + rng.uniform(-d.inertia, d.inertia, 3))
        J = np.diag(diag)
        for i, j in ((0, 1), (0, 2), (1, 2)):
            J[i, j] = J[j, i] = rng.uniform(-d.products, d.products) * math.sqrt(diag[i] * diag[j])
        if _physical(J):
            break
    else:  # pragma: no cover - 100 draws of a 2 % product never all fail
        raise RuntimeError("could not draw a physical inertia")
    plant = dataclasses.replace(p, dJ=J - np.asarray(p.J0, float))
    faults = []
    for f in scn.actuators.faults:
        shift = rng.uniform(-d.onset, d.onset)
        onset = max(0.0, f.onset + shift)
        end = None if f.end is None else max(onset + 1e-3, f.end + shift)
        eff = float(np.clip(f.effectiveness + rng.uniform(-d.effectiveness, d.effectiveness), 0, 1))
        faults.append(dataclasses.replace(f, onset=onset, end=end,
                                          effectiveness=f.effectiveness if f.stuck else eff))
    act = dataclasses.replace(scn.actuators, faults=tuple(faults))
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angle = rng.uniform(0, d.attitude)
    dsigma = axis * math.tan(angle / 4)  # MRP of the perturbation
    sigma0 = np.asarray(scn.initial.sigma_BN, float)
    sigma = _compose(dsigma, sigma0, _core)
    omega = np.asarray(scn.initial.omega_BN_B, float) + rng.uniform(-d.rate, d.rate, 3)
    initial = dataclasses.replace(scn.initial, sigma_BN=sigma, omega_BN_B=omega)
    return dataclasses.replace(scn, plant=plant, actuators=act, initial=initial)


def _compose(s_rel: np.ndarray, s0: np.ndarray, core) -> np.ndarray:
    """sigma with R(sigma) = R(s_rel) R(s0) (MRP addition), short rotation."""
    a, b = s_rel, s0
    aa, bb = a @ a, b @ b
    num = (1 - aa) * b + (1 - bb) * a - 2 * np.cross(a, b)
    den = 1 + aa * bb - 2 * a @ b
    return np.asarray(core.mrp_short(num / den))


def _shortcut_keys(scn: Scenario, d: Dispersion) -> list[str]:
    keys = []
    if d.inertia or d.products:
        keys.append("spacecraft.dJ")
    for i, f in enumerate(scn.actuators.faults):
        if d.onset:
            keys += [f"faults[{i}].onset"] + ([f"faults[{i}].end"] if f.end is not None else [])
        if d.effectiveness and not f.stuck:
            keys.append(f"faults[{i}].effectiveness")
    if d.attitude:
        keys.append("initial.sigma_BN")
    if d.rate:
        keys.append("initial.omega_BN_B")
    return keys


def _keys(scn: Scenario, d: Dispersion) -> list[str]:
    table = [e.key for e in scn.montecarlo.disperse] if scn.montecarlo is not None else []
    return list(dict.fromkeys(_shortcut_keys(scn, d) + table))


def value_columns(scn: Scenario, d: Dispersion) -> list[str]:
    """Names of the dispersed-value columns of a campaign (one per element)."""
    data = scenario_data(scn)
    return [c for k in _keys(scn, d) for c in element_names(k, np.shape(get_key(data, k)))]


def _values(data: dict[str, Any], keys: list[str]) -> dict[str, float]:
    out: dict[str, float] = {}
    for k in keys:
        v = np.asarray(get_key(data, k), float)
        out.update(zip(element_names(k, v.shape), (float(x) for x in v.flat)))
    return out


def _with_sensor_seed(s: Scenario | None, seed: int, run: int) -> Scenario | None:
    if s is None or s.sensors is None:
        return s
    ss = np.random.SeedSequence([int(seed), int(s.sensors.seed)], spawn_key=(int(run), 2))
    new = int(ss.generate_state(1, np.uint64)[0] >> np.uint64(1))
    return dataclasses.replace(s, sensors=dataclasses.replace(s.sensors, seed=new))


def draw_run(scn: Scenario, d: Dispersion, seed: int, run: int
             ) -> tuple[Scenario | None, dict[str, float], int, str]:  # fmt: skip
    """Run ``run``'s scenario: (scenario or None if no valid draw, dispersed
    values by column, redraws used, message of the last invalid draw)."""
    s, values, redraws, message = _draw_run(scn, d, seed, run)
    return _with_sensor_seed(s, seed, run), values, redraws, message


def _draw_run(scn: Scenario, d: Dispersion, seed: int, run: int
              ) -> tuple[Scenario | None, dict[str, float], int, str]:  # fmt: skip
    s = scn
    active = d != NO_SHORTCUTS
    if active:
        s = disperse(scn, np.random.default_rng(run_seed_sequence(seed, run)), d)
    table = scn.montecarlo
    keys = _keys(scn, d)
    if table is None or not table.disperse:
        return s, _values(scenario_data(s), keys), 0, ""
    rng = np.random.default_rng(run_seed_sequence(seed, run, 1))
    base = scenario_data(s)
    attempts = table.max_redraws if table.on_invalid == "redraw" else 1
    message = ""
    for attempt in range(attempts):
        data = scenario_data(s)  # a fresh copy: set_key writes into it
        for e in table.disperse:
            set_key(data, e.key, draw(e, get_key(base, e.key), rng))
        try:
            out = scenario_from_data(data, scn.path, f" (run {run})")
        except ScenarioError as err:
            message = str(err).splitlines()[0]
            continue
        return dataclasses.replace(out, path=scn.path), _values(data, keys), attempt, ""
    return None, _values(data, keys), attempts, message
