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

A run's draw is its values (:class:`RunDraw`: every key the shortcuts
write, the table's keys and the sensor seed, as the scenario's data holds
them); its scenario is the base with those values, read back through the
file's checks (``sc_rt.scenario.overrides.with_draws``), in the campaign as
in a replay. The campaign records the values (the row's ``draws``), and
``--rerun`` replays them without drawing again.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from sc_rt.scenario.dispersions import draw
from sc_rt.scenario.keys import element_names, get_key, scenario_data, set_key
from sc_rt.scenario.model import Scenario, ScenarioError
from sc_rt.scenario.overrides import with_draws

__all__ = ["Dispersion", "NO_SHORTCUTS", "RunDraw", "disperse", "draw_run", "draw_scenario", "plan_draw",
           "run_scenario",
           "run_seed_sequence", "value_columns", "value_keys"]


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


def value_keys(scn: Scenario, d: Dispersion) -> list[str]:
    """The dispersed keys of a campaign, whose elements are the row's value columns."""
    return _keys(scn, d)


def value_columns(scn: Scenario, d: Dispersion) -> list[str]:
    """Names of the dispersed-value columns of a campaign (one per element)."""
    data = scenario_data(scn)
    return [c for k in _keys(scn, d) for c in element_names(k, np.shape(get_key(data, k)))]


class RunDraw(NamedTuple):
    """What run ``run`` of a campaign drew: its values, recorded as its inputs
    (the run's dataset row, column ``draws``; its plan's overrides) and
    replayed by ``--rerun`` without drawing again."""

    values: tuple  # ((dotted key, value as the scenario's data holds it), ...)
    redraws: int  # invalid draws before this one (all of them: a run with no valid draw)
    message: str  # why the last draw was invalid ("" when this one is valid)

    def columns(self, keys: list[str] | None = None) -> dict[str, float]:
        """The dispersed-value columns of the row (one per element of
        ``keys``; None: every drawn key but the sensors' seed)."""
        drawn = dict(self.values)
        out: dict[str, float] = {}
        for k in ([k for k in drawn if k != SENSORS_SEED] if keys is None else keys):
            v = np.asarray(drawn[k], float)
            out.update(zip(element_names(k, v.shape), (float(x) for x in v.flat)))
        return out

    def to_json(self) -> str:
        """The values as the row's ``draws`` column (JSON: floats written exactly)."""
        return json.dumps([[k, v] for k, v in self.values])

    @classmethod
    def from_row(cls, row: dict[str, Any]) -> RunDraw:
        """The draw a dataset row recorded (its ``draws``, ``redraws``, ``message``)."""
        return cls(tuple((k, v) for k, v in json.loads(row["draws"])), int(row["redraws"]),
                   str(row.get("message") or "") if row.get("status") == "invalid" else "")


#: the key of a run's own sensor seed among its drawn values
SENSORS_SEED = "sensors.seed"


def _all_shortcut_keys(scn: Scenario) -> list[str]:
    """Every key ``disperse`` writes, whatever its widths (a width of 0 still
    writes: the inertia's diagonal form, the fault's clipped values)."""
    keys = ["spacecraft.dJ"]
    for i, f in enumerate(scn.actuators.faults):
        keys += [f"faults[{i}].onset"] + ([f"faults[{i}].end"] if f.end is not None else [])
        keys += [] if f.stuck else [f"faults[{i}].effectiveness"]
    return keys + ["initial.sigma_BN", "initial.omega_BN_B"]


def _pairs(data: dict[str, Any], keys: list[str]) -> tuple:
    def plain(v: Any) -> Any:
        return np.asarray(v).tolist() if isinstance(v, (np.ndarray, np.generic)) else v

    return tuple((k, plain(get_key(data, k))) for k in keys)


def _sensor_seed(scn: Scenario, seed: int, run: int) -> tuple:
    if scn.sensors is None:
        return ()
    ss = np.random.SeedSequence([int(seed), int(scn.sensors.seed)], spawn_key=(int(run), 2))
    return ((SENSORS_SEED, int(ss.generate_state(1, np.uint64)[0] >> np.uint64(1))),)


def draw_scenario(scn: Scenario, d: Dispersion, seed: int, run: int) -> tuple[RunDraw, Scenario | None, str]:
    """Run ``run``'s draw, from (seed, run) alone: the shortcut dispersions
    (when any is set), then the table's, redrawn while the scenario they
    make is invalid (``on_invalid``, ``max_redraws``), and the run's sensor
    seed; with the scenario the values make (``run_scenario``: None when
    they make none) and why not ("" when they do)."""
    s = scn
    keys: list[str] = []
    if d != NO_SHORTCUTS:
        s = disperse(scn, np.random.default_rng(run_seed_sequence(seed, run)), d)
        keys = _all_shortcut_keys(scn)
    table = scn.montecarlo
    sensor = _sensor_seed(scn, seed, run)
    if table is None or not table.disperse:
        rd = RunDraw(_pairs(scenario_data(s), keys) + sensor, 0, "")
        return (rd, *run_scenario(scn, rd, run))
    keys = list(dict.fromkeys(keys + [e.key for e in table.disperse]))
    rng = np.random.default_rng(run_seed_sequence(seed, run, 1))
    base = scenario_data(s)
    attempts = table.max_redraws if table.on_invalid == "redraw" else 1
    for attempt in range(attempts):
        data = scenario_data(s)  # a fresh copy: set_key writes into it
        for e in table.disperse:
            set_key(data, e.key, draw(e, get_key(base, e.key), rng))
        rd = RunDraw(_pairs(data, keys) + sensor, attempt, "")
        out, message = run_scenario(scn, rd, run)
        if out is not None:
            return rd, out, ""
    return RunDraw(rd.values, attempts, message), None, message


def plan_draw(scn: Scenario, d: Dispersion, seed: int, run: int) -> RunDraw:
    """Run ``run``'s draw (:func:`draw_scenario`), its values only."""
    return draw_scenario(scn, d, seed, run)[0]


def run_scenario(scn: Scenario, rd: RunDraw, run: int) -> tuple[Scenario | None, str]:
    """(run ``run``'s scenario: ``scn`` with the draw's values, or None when
    they make an invalid scenario; the first line of why, else "")."""
    try:
        return with_draws(scn, rd.values, f" (run {run})"), ""
    except ScenarioError as err:
        return None, str(err).splitlines()[0]


def draw_run(scn: Scenario, d: Dispersion, seed: int, run: int
             ) -> tuple[Scenario | None, dict[str, float], int, str]:  # fmt: skip
    """Run ``run``'s scenario: (scenario or None if no valid draw, dispersed
    values by column, redraws used, message of the last invalid draw)."""
    rd, s, message = draw_scenario(scn, d, seed, run)
    return s, rd.columns(value_keys(scn, d)), rd.redraws, message
