"""``sc-rt montecarlo``: how robust is a design? Dispersed copies of a
scenario run on all cores (C++ engine), reproducible from one seed.

Dispersions (each run independently, uniform):
- true inertia error dJ: each diagonal element of J0 + dJ scaled by
  1 +- ``inertia`` (default 20 %), off-diagonal products of inertia
  +- ``products`` (default 2 %) of sqrt(J_ii J_jj); redrawn until the inertia
  is physical (positive definite, triangle inequality);
- wheel faults: each scenario fault's onset (and end) shifted by
  +- ``onset`` s (default 2 s, onset kept >= 0), its effectiveness moved by
  +- ``effectiveness`` (default 0.2, kept in [0, 1]);
- initial attitude: rotated by up to ``attitude`` rad (default 0.01) about a
  random axis; initial rate: +- ``rate`` rad/s per axis (default 0.002).

Run i uses the i-th child of ``numpy.random.SeedSequence(seed)``: the result
does not depend on the number of workers.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.scenario.model import Scenario

__all__ = ["Dispersion", "disperse", "run_montecarlo"]


@dataclass(frozen=True)
class Dispersion:
    inertia: float = 0.2  # [-] relative, diagonal of J0 + dJ
    products: float = 0.02  # [-] off-diagonal, relative to sqrt(J_ii J_jj)
    onset: float = 2.0  # [s] fault onset (and end) shift
    effectiveness: float = 0.2  # [-] fault effectiveness shift
    attitude: float = 0.01  # [rad] initial attitude rotation
    rate: float = 0.002  # [rad/s] initial rate, per axis


def _physical(J: np.ndarray) -> bool:
    ev = np.linalg.eigvalsh(J)
    return bool(ev.min() > 0 and ev[0] + ev[1] >= ev[2])


def disperse(scn: Scenario, rng: np.random.Generator, d: Dispersion) -> Scenario:
    """One dispersed copy of ``scn`` (the controller's J0 is unchanged)."""
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
    # compose: sigma = dsigma (+) sigma0, via (8)'s inverse: sub(sigma, sigma0) = dsigma
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


@functools.lru_cache(maxsize=4)
def _load(path: str) -> Scenario:
    from sc_rt.scenario.model import load_scenario

    return load_scenario(path)


def _one(args) -> dict[str, Any]:
    # the scenario travels as its path: its parameter objects hold compiled
    # closures that do not pickle; each worker loads it once
    path, i, seed, d, law, rate = args
    from sc_rt.sim.engines import simulate

    scn = _load(path)
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(i + 1)[i])
    s = disperse(scn, rng, d)
    res = simulate(s, law=law, engine="cpp", control_rate_hz=rate)
    m = res.metrics
    tr = res.trajectory
    return {
        "run": i,
        "holds_bound": m["first_bound_violation_s"] is None and m["finite"],
        "first_bound_violation_s": m["first_bound_violation_s"],
        "final_sigma_BD": float(np.linalg.norm(tr["sigma_BD"][-1])),
        "final_omega_BD_B": float(np.linalg.norm(tr["omega_BD_B"][-1])),
        "max_abs_sigma_BD_after_100s": float(np.max(np.abs(tr["sigma_BD"][tr["t"] >= 100]), initial=0.0)),
        "finite": m["finite"],
        "J_diag": np.diag(s.plant.J).tolist(),
    }


def run_montecarlo(scn: Scenario, runs: int, *, workers: int | None = None, seed: int = 0,
                   dispersion: Dispersion = Dispersion(), law: str | None = None,
                   control_rate_hz: float | None = None, progress: bool = True) -> dict[str, Any]:
    workers = workers or os.cpu_count() or 1
    jobs = [(str(scn.path), i, seed, dispersion, law, control_rate_hz) for i in range(runs)]
    t0 = time.perf_counter()
    results: list[dict[str, Any]] = []
    if workers == 1:
        it = map(_one, jobs)
        for r in it:
            results.append(r)
            _progress(progress, len(results), runs)
    else:
        with ProcessPoolExecutor(workers) as ex:
            for r in ex.map(_one, jobs, chunksize=max(1, runs // (8 * workers))):
                results.append(r)
                _progress(progress, len(results), runs)
    wall = time.perf_counter() - t0
    if progress:
        print(file=sys.stderr)
    held = [r for r in results if r["holds_bound"]]
    fin = np.array([r["final_sigma_BD"] for r in results])
    return {
        "scenario": scn.name, "law": law or scn.run.controller,
        "control_rate_hz": control_rate_hz or scn.run.control_rate_hz,
        "runs": runs, "seed": seed, "workers": workers, "dispersion": dataclasses.asdict(dispersion),
        "fraction_holding_bound": len(held) / runs if runs else None,
        "runs_breaking_bound": [r["run"] for r in results if not r["holds_bound"]],
        "worst_final_sigma_BD": float(fin.max()) if runs else None,
        "median_final_sigma_BD": float(np.median(fin)) if runs else None,
        "worst_final_omega_BD_B": float(max(r["final_omega_BD_B"] for r in results)) if runs else None,
        "wall_s": wall, "runs_per_s": runs / wall if wall > 0 else None,
        "per_run": results,
    }


def _progress(on: bool, done: int, total: int) -> None:
    if on:
        bar = "#" * int(30 * done / total)
        print(f"\rmontecarlo [{bar:<30}] {done}/{total}", end="", file=sys.stderr, flush=True)


def write_montecarlo(res: dict[str, Any], out: Path) -> None:
    from sc_rt.results import figures  # noqa: F401  (Agg backend)
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    (out / "montecarlo.json").write_text(json.dumps(res, indent=2) + "\n")
    fin = np.array([r["final_sigma_BD"] for r in res["per_run"]])
    viol = [r["first_bound_violation_s"] for r in res["per_run"] if r["first_bound_violation_s"] is not None]
    fig, axs = plt.subplots(1, 2, figsize=(10, 4))
    axs[0].hist(np.log10(np.maximum(fin, 1e-16)), bins=30)
    axs[0].set_xlabel("log10 |sigma_BD| at the end of the run")
    axs[0].set_ylabel("runs")
    axs[1].hist(viol if viol else [0], bins=30, color="C3" if viol else "0.8")
    axs[1].set_xlabel("first bound violation [s]" + ("" if viol else " (none)"))
    fig.suptitle(f"{res['scenario']}, {res['law']}, {res['runs']} runs: "
                 f"{100 * res['fraction_holding_bound']:.1f} % hold the bound")
    fig.tight_layout()
    fig.savefig(out / "montecarlo.png", dpi=90)
    plt.close(fig)
