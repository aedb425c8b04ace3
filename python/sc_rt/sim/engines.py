"""Offline closed loop: the plant (plant.py, or its C++ twin) and a control
law of the C++ core, sampled at the control rate with a zero-order hold.

Loop (both engines, identical arithmetic order):

    x = x0; controller.reset(measurement(0, x))
    for k = 0..N:                       t_k = k / rate
        command = controller.step(measurement(t_k, x))
        record row k (state, command, actual wheel acceleration, true delta_2)
        if k == N: stop
        repeat n_sub times: x = rk4_step(x, h, command.u_cmd)   (plant saturates)
        stop early at the first non-finite state

``sc-rt hil --mode lockstep`` runs the same loop over LCM and must give the
same numbers to the last bit as ``engine="python"``.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt import _core
from sc_rt.model import actuators, plant
from sc_rt.results.metrics import TRAJECTORY_KEYS, bound_ok, compute_metrics, json_safe
from sc_rt.scenario.model import Scenario

__all__ = ["SimResult", "simulate", "with_overrides", "write_result", "PACKED"]

#: Layout of _core.step_packed's output (name -> slice).
PACKED: dict[str, slice] = {}
_o = 0
for _name, _n in (("u_cmd", 4), ("u_sat", 4), ("sigma_DN", 3), ("sigma_BD", 3), ("omega_BD_B", 3),
                  ("e1", 3), ("e2", 3), ("z1", 3), ("z2", 3), ("chi", 3), ("lam", 3), ("x2d", 3),
                  ("vs", 4), ("rho_hat", 1), ("mode", 1), ("flags", 1)):
    PACKED[_name] = slice(_o, _o + _n)
    _o += _n
assert _o == _core.PACKED_SIZE


@dataclass
class SimResult:
    """A run: the trajectory arrays, its metrics, and how it ended."""

    trajectory: dict[str, np.ndarray]
    metrics: dict[str, Any]
    diverged: bool = False
    message: str = ""
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.trajectory[name] if name in self.trajectory else self.extra[name]


def with_overrides(scn: Scenario, *, law: str | None = None, control_rate_hz: float | None = None,
                   duration: float | None = None, plant_step: float | None = None) -> Scenario:
    """The scenario with CLI-style overrides, validated like the file.

    When only the control rate changes, the plant step becomes the largest
    step that divides the new control period and does not exceed the
    scenario's (10 Hz -> 100 Hz with a 0.1 s plant step gives 0.01 s).
    """
    if control_rate_hz is not None and plant_step is None:
        period = 1.0 / control_rate_hz
        plant_step = period / math.ceil(period / scn.run.plant_step - 1e-9)
    return scn.with_run(controller=law, control_rate_hz=control_rate_hz, duration=duration,
                        plant_step=plant_step)


def _steps(scn: Scenario) -> tuple[int, int, float, float]:
    """(control periods, plant steps per period, plant step [s], rate [Hz])."""
    rate = scn.run.control_rate_hz
    n_sub = scn.run.plant_substeps
    return int(round(scn.run.duration * rate)), n_sub, 1.0 / (rate * n_sub), rate


def initial_state(scn: Scenario) -> np.ndarray:
    i = scn.initial
    return np.concatenate([i.sigma_BN, i.omega_BN_B, i.wheel_speed]).astype(float)


def _allocate(n: int) -> dict[str, np.ndarray]:
    shapes = {"t": (), "sigma_BN": (3,), "omega_BN_B": (3,), "sigma_DN": (3,), "sigma_BD": (3,),
              "omega_BD_B": (3,), "wheel_speed": (4,), "u_cmd": (4,), "u_sat": (4,),
              "wheel_accel": (4,), "z1": (3,), "z2": (3,), "delta2": (3,), "chi": (3,), "lam": (3,)}
    return {k: np.full((n, *s), np.nan) for k, s in shapes.items()}


def _run_python(scn: Scenario):
    n_ctrl, n_sub, h, rate = _steps(scn)
    ctl = _core.Controller(scn.core_config())
    pp, act = scn.plant, scn.actuators
    x = initial_state(scn)
    n = n_ctrl + 1
    # one row assignment per array and step; columns are split at the end
    T = np.full(n, np.nan)
    X = np.full((n, 10), np.nan)
    OUT = np.full((n, _core.PACKED_SIZE), np.nan)
    ACC = np.full((n, 4), np.nan)
    D2 = np.full((n, 3), np.nan)
    ctl.reset(_core.Measurement(0.0, x[0:3], x[3:6], x[6:10]))
    u_slice = PACKED["u_cmd"]
    rows = 0
    diverged = False
    step_packed, wheel_accel, lumped, rk4 = (_core.step_packed, actuators.wheel_accel,
                                              plant.lumped_disturbance, plant.rk4_step)
    isfinite = math.isfinite
    for k in range(n):
        t = k / rate
        out = step_packed(ctl, t, x)
        u_cmd = out[u_slice]
        u_sat, accel, _ = wheel_accel(act, t, u_cmd, x[6:10])
        T[k] = t
        X[k] = x
        OUT[k] = out
        ACC[k] = accel
        D2[k] = lumped(pp, t, x, u_sat, accel)
        rows = k + 1
        if k == n_ctrl:
            break
        for j in range(n_sub):
            x = rk4(pp, act, t + j * h, x, h, u_cmd)
        if not all(map(isfinite, x)):
            diverged = True
            break
    traj = {"t": T, "sigma_BN": X[:, 0:3], "omega_BN_B": X[:, 3:6], "wheel_speed": X[:, 6:10],
            "wheel_accel": ACC, "delta2": D2}
    for name in ("u_cmd", "u_sat", "sigma_DN", "sigma_BD", "omega_BD_B", "z1", "z2", "chi", "lam"):
        traj[name] = OUT[:, PACKED[name]]
    extra = {"flags": np.nan_to_num(OUT[:, PACKED["flags"]][:, 0]).astype(np.int64),
             "vs": OUT[:, PACKED["vs"]], "e1": OUT[:, PACKED["e1"]], "e2": OUT[:, PACKED["e2"]]}
    return traj, extra, rows, diverged


def _run_cpp(scn: Scenario):
    n_ctrl, n_sub, _, rate = _steps(scn)
    res = _core.simulate_closed_loop(
        scn.core_config(), plant.plant_params_to_cpp(scn.plant),
        actuators.actuator_params_to_cpp(scn.actuators), initial_state(scn), n_ctrl, n_sub, rate)
    rows = int(res.pop("rows"))
    diverged = bool(res.pop("diverged"))
    extra = {k: res.pop(k) for k in ("flags", "vs", "e1", "e2")}
    traj = {k: res[k] for k in _allocate(0)}
    return traj, extra, rows, diverged


def simulate(scn: Scenario, *, law: str | None = None, engine: str = "python",
             control_rate_hz: float | None = None, duration: float | None = None,
             plant_step: float | None = None) -> SimResult:
    """Run the scenario's closed loop offline.

    Parameters
    ----------
    scn : the scenario (sc_rt.scenario.model.load_scenario).
    law : "dsc-ppc", "dsc", "pd" or "rft" (default: the scenario's).
    engine : "python" (reference plant, plant.py), "cpp" (compiled twin, whole loop in C++)
        or "unsampled" (reference mode: the law inside every RK4 stage, no hold; unsampled.py).
    control_rate_hz : [Hz] override of the scenario's control rate.
    duration : [s] override of the scenario's duration.
    plant_step : [s] override of the plant step (see with_overrides).
    """
    scn = with_overrides(scn, law=law, control_rate_hz=control_rate_hz, duration=duration,
                         plant_step=plant_step)
    law, rate, duration = scn.run.controller, scn.run.control_rate_hz, scn.run.duration
    t0 = time.perf_counter()
    if engine == "python":
        traj, extra, rows, diverged = _run_python(scn)
    elif engine == "cpp":
        traj, extra, rows, diverged = _run_cpp(scn)
    elif engine == "unsampled":
        from sc_rt.sim.unsampled import run_unsampled

        n_ctrl, n_sub, _, _ = _steps(scn)
        traj, extra, rows, diverged = run_unsampled(scn, n_ctrl, n_sub, rate)
    else:
        raise ValueError(f"engine must be 'python', 'cpp' or 'unsampled', got {engine!r}")
    wall = time.perf_counter() - t0
    traj = {k: v[:rows] for k, v in traj.items()}
    extra = {k: v[:rows] for k, v in extra.items()}
    traj["bound_ok"] = bound_ok(scn.controller.ppc, traj["t"], traj["sigma_BD"])
    metrics = compute_metrics(traj, scenario=scn.name, controller=law, engine=engine,
                              control_rate_hz=rate, duration_s=duration, wall_s=wall)
    message = ""
    if diverged:
        message = (f"the plant state became non-finite after t = {traj['t'][-1]:.6g} s: "
                   f"the run stopped there ({rows} of {int(round(duration * rate)) + 1} rows)")
        metrics["diverged"] = True
        metrics["diverged_after_s"] = float(traj["t"][-1])
    metrics["finite"] = metrics["finite"] and not diverged
    return SimResult(traj, metrics, diverged, message, extra)


def write_result(res: SimResult, out: Path) -> None:
    """trajectory.npz and metrics.json into out/."""
    out.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out / "trajectory.npz", **{k: res.trajectory[k] for k in TRAJECTORY_KEYS},
                        **{f"ctrl_{k}": v for k, v in res.extra.items()})
    (out / "metrics.json").write_text(json.dumps(json_safe(res.metrics), indent=2) + "\n")
