"""``sc-rt check SCENARIO``: everything that can be said about a scenario
before running it, each finding with the key and value involved.

The checks follow the law checked (the scenario's, or ``law=``): the
observer condition only for the laws with a NESO, Theorem 1 and the
transform (31) only for DSC+PPC.

Levels and exit code (``exit_code``, the one policy): errors 2 (the file
does not load, B is rank-deficient, DSC+PPC's initial attitude error
outside the prescribed bound (29) at t = 0, where (31) has no value);
warnings that concern the law and the run 1 (the observer condition (26),
the Theorem 1 gain conditions with r's bound estimated along a run,
saturation limits that cannot produce the feed-forward the desired
trajectory needs, a fault scheduled at or after the run's end); notes 0
(Cbar not a proper rotation of the paper's wheel layout, used as given; a
non-PPC run that starts outside the bound; a law whose command the
controller converts to the wheels' unit, ``wheels.command``), warnings with
``strict``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sc_rt import _core
from sc_rt.studies.lawparams import dsc_gains, neso_core, neso_params
from sc_rt.scenario.model import Scenario, ScenarioError
from sc_rt.scenario.reader import load_scenario, with_run
from sc_rt.scenario.tables.laws import command_of, stray_tables, wheels_command
from sc_rt.plan.law import resolve_law

__all__ = ["Finding", "check_scenario", "exit_code", "LEVELS", "PAPER_C"]

#: Finding levels, most severe first.
LEVELS = ("error", "warning", "note", "ok")
#: Laws with the NESO observer (condition (26) applies).
OBSERVER_LAWS = ("dsc-ppc", "dsc")

#: The paper's service-frame wheel layout: three orthogonal wheels and a
#: skewed fourth (docs/MODEL.md section 8). Used for the Cbar check when the
#: scenario gives Cbar directly (a [spacecraft.capture] table builds Cbar from
#: its own C, which is then a rotation by construction).
PAPER_C = np.column_stack([np.eye(3), np.ones(3) / math.sqrt(3)])


@dataclass(frozen=True)
class Finding:
    level: str  # one of LEVELS
    key: str
    value: str
    message: str

    def __str__(self) -> str:
        v = f" = {self.value}" if self.value else ""
        return f"{self.level.upper():7s} {self.key}{v}: {self.message}"


def _fmt(v) -> str:
    return np.array2string(np.asarray(v, float), precision=4, separator=", ") if np.ndim(v) else f"{v:.4g}"


def check_scenario(path: str | Path, *, run_estimate: bool = True, law: str | None = None,
                   sets: tuple = ()) -> list[Finding]:
    """The findings on the scenario at ``path`` for ``law`` (default: the
    scenario's), with the ``--set`` pairs ``sets`` applied."""
    try:
        scn = load_scenario(path, sets)
        if law is not None:
            scn = with_run(scn, controller=law)
        scn, ref = resolve_law(scn, overridden=law is not None)  # the law loaded and probed at rest
    except ScenarioError as e:  # a problem of no key (the file itself): named by file[:line]
        return [Finding("error", i.key or (f"{e.path}:{i.line}" if i.line else e.path),
                        "" if i.value is None else str(i.value), i.message)
                for i in e.errors] or [Finding("error", "", "", str(e))]
    # a [laws.NAME] table no law reads (a misspelling: the law would run its defaults)
    stray, notes = stray_tables(scn, names=(ref.name,))
    if stray:
        return [Finding("error", i.key, "", f"{i.message} ({scn.path}:{i.line})" if i.line else i.message)
                for i in stray]
    law = scn.run.controller
    out: list[Finding] = [Finding("note", "laws", "", note) for note in notes]
    out += _check_model(scn)
    if any(f.level == "error" for f in out):
        return out
    out += _check_command(scn, law)
    out += _check_initial_bound(scn, law)
    if law in OBSERVER_LAWS:
        out += _check_observer(scn)
    if law == "dsc-ppc":
        out += _check_theorem1(scn, run_estimate)
    out += _check_feedforward(scn)
    out += _check_fault_times(scn)
    out += _check_noise_floor(scn, law)
    return out


#: what each command kind is, for a finding
_KINDS = {"acceleration": "wheel accelerations [rad/s^2]", "torque": "motor torques [N m]"}


def _check_command(scn: Scenario, law: str) -> list[Finding]:
    """What the law commands, what the wheels take, and whether the controller
    converts (a note) or passes the command through (ok)."""
    try:
        law_kind = command_of(law)
    except ValueError:  # a law that does not load: the scenario's own check said so
        return []
    wheels = wheels_command(scn)
    text = f"law {law} commands {_KINDS[law_kind]}; the wheels take {_KINDS[wheels]}"
    if law_kind == wheels:
        return [Finding("ok", "wheels.command", wheels, text + ": no conversion")]
    rule = "torque = Jw a" if law_kind == "acceleration" else "a = torque / Jw"
    return [Finding("note", "wheels.command", wheels, text + f": converted by the controller ({rule}, per wheel, "
                    "before saturation)")]


def _check_noise_floor(scn: Scenario, law: str) -> list[Finding]:
    """chiinf against the sensors' noise floor (sc_rt.studies.design.noise)."""
    if scn.sensors is None:
        return []
    from sc_rt.studies.design.noise import NOISE_SIGMAS, noise_floor

    nf = noise_floor(scn, law=law)
    key, value = "controller.ppc.chiinf", _fmt(scn.controller.ppc.chiinf)
    if nf is None:
        return [Finding("note", "sensors", "", f"no noise floor for law {law!r} (no linear model)")]
    if not nf.stable:
        out = [Finding("warning", key, value, "the linearised loop is unstable at this chiinf: no noise floor")]
        est_mrp = nf.est_rms_arcsec * (math.pi / 180 / 3600) / 4.0  # the estimate's own error, as MRP
        low = np.flatnonzero(nf.bound_mrp < NOISE_SIGMAS * est_mrp)
        if low.size:
            out.append(Finding("warning", key, value, "chiinf is below the noise of the attitude estimate itself "
                               f"on axis {', '.join('xyz'[i] for i in low)}: bound min(dmin, dmax) chiinf "
                               f"{_fmt(nf.bound_mrp)} MRP against {NOISE_SIGMAS:g} x the estimator's RMS "
                               f"{_fmt(nf.est_rms_arcsec)} arcsec (MRP {_fmt(est_mrp)})"))
        return out
    low = np.flatnonzero(nf.margin < 1)
    text = (f"noise floor from the sensors alone: RMS {_fmt(nf.rms_arcsec)} arcsec "
            f"(MRP {_fmt(nf.rms_mrp)}); bound min(dmin, dmax) chiinf / ({NOISE_SIGMAS:g} RMS) = {_fmt(nf.margin)}")
    out = []
    if low.size:
        out.append(Finding("warning", key, value, "chiinf is below the sensor noise floor on axis "
                           + ", ".join("xyz"[i] for i in low) + ": " + text))
    else:
        out.append(Finding("ok", key, value, text))
    if nf.u_rms is not None and np.any(nf.u_margin < 1):
        out.append(Finding("warning", "sensors", "", f"the sensor noise alone saturates the wheels: wheel "
                           f"command RMS {_fmt(nf.u_rms)} rad/s^2, limit / ({NOISE_SIGMAS:g} RMS) = "
                           f"{_fmt(nf.u_margin)} (the loop leaves its linear range; lower the gains or the noise)"))
    return out


def _check_model(scn: Scenario) -> list[Finding]:
    out = []
    cfg = scn.core_config()
    errs = _core.validate(cfg)
    for e in errs:
        out.append(Finding("error", "controller", "", e))
    try:
        model = _core.SpacecraftModel(cfg.spacecraft)
        sv = np.linalg.svd(np.asarray(model.B), compute_uv=False)
        out.append(Finding("ok", "spacecraft.Cbar", "", f"B = -J0^-1 Cbar Jw has rank 3 "
                           f"(singular values {_fmt(sv)}, condition {sv[0] / sv[-1]:.3g})"))
    except ValueError as e:
        out.append(Finding("error", "spacecraft.Cbar", _fmt(scn.plant.Cbar), str(e)))
        return out
    from sc_rt.model.combined import check_cbar_is_rotation

    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        fit = check_cbar_is_rotation(np.asarray(scn.plant.Cbar), PAPER_C)
    if fit.is_rotation:
        out.append(Finding("ok", "spacecraft.Cbar", "", "a proper rotation of the paper's wheel layout C"))
    else:
        msg = str(w[0].message) if w else f"residual {fit.residual:.3g}"
        out.append(Finding("note", "spacecraft.Cbar", "",
                           "compared with the paper's layout C = [e1, e2, e3, (1,1,1)/sqrt(3)]: " + msg))
    return out


def _check_initial_bound(scn: Scenario, law: str = "dsc-ppc") -> list[Finding]:
    x1 = _core.mrp_subtract(np.asarray(scn.initial.sigma_BN), np.asarray(scn.guidance.sigma_d0))
    p = scn.controller.ppc
    chi0, dmin, dmax = (np.asarray(v, float) for v in (p.chi0, p.dmin, p.dmax))
    inside = (x1 > -dmin * chi0) & (x1 < dmax * chi0)
    if np.all(inside):
        return [Finding("ok", "controller.ppc.chi0", _fmt(chi0),
                        f"the initial error sigma_BD(0) = {_fmt(x1)} is inside the bound (29)")]
    axes = [i + 1 for i in range(3) if not inside[i]]
    if law != "dsc-ppc":  # only DSC+PPC needs (31); the others start outside the bound's verdict
        return [Finding("note", "controller.ppc.chi0", _fmt(chi0),
                        f"the initial error sigma_BD(0) = {_fmt(x1)} is outside -dmin chi0 < x1 < dmax chi0 "
                        f"on axis {axes}: a {law} run starts outside the prescribed bound (29)")]
    return [Finding("error", "controller.ppc.chi0", _fmt(chi0),
                    f"the initial error sigma_BD(0) = {_fmt(x1)} is outside -dmin chi0 < x1 < dmax chi0 "
                    f"on axis {axes}: the transform (31) has no value there; widen chi0 or dmin/dmax")]


def _check_observer(scn: Scenario) -> list[Finding]:
    law = scn.run.controller
    m = np.asarray(_core.neso_condition_26(neso_core(scn, law)))
    n = neso_params(scn, law)
    if np.all(m > 0):
        return [Finding("ok", f"laws.{law}", "", f"condition (26) holds on every axis (margins {_fmt(m)})")]
    axes = [i + 1 for i in range(3) if m[i] <= 0]
    return [Finding("warning", f"laws.{law}.neso_k4", _fmt(n.k4),
                    f"observer condition (26) fails on axis {axes} (margins {_fmt(m)}): "
                    "k3 k4 > k2^2 k3 / alpha + (alpha + 1)^2 k1^2 k2^2 (stricter reading)")]


def _r_bound(scn: Scenario) -> float:
    """max ||r|| along an offline DSC+PPC run (C++ engine), r of (35)."""
    from sc_rt.sim.engines import simulate

    tr = simulate(scn, law="dsc-ppc", engine="cpp").trajectory
    p = scn.controller.ppc
    dmin, dmax = np.asarray(p.dmin), np.asarray(p.dmax)
    lam, chi = tr["lam"], tr["chi"]
    r = 0.5 / chi * (1.0 / (lam + dmin) - 1.0 / (lam - dmax))
    return float(np.nanmax(r))


def _check_theorem1(scn: Scenario, run_estimate: bool) -> list[Finding]:
    d = dsc_gains(scn, "dsc-ppc")
    cfg = scn.core_config()
    k5 = float(np.linalg.norm(np.asarray(_core.SpacecraftModel(cfg.spacecraft).B), 2))
    out = []
    p = scn.controller.ppc
    # r at x1 = 0 and t = 0: a lower bound of rM
    r0 = float(np.max(0.5 / np.asarray(p.chi0) * (1 / np.asarray(p.dmin) + 1 / np.asarray(p.dmax))))
    rM = _r_bound(scn) if run_estimate else r0
    src = "max along an offline DSC+PPC run" if run_estimate else "at x1 = 0, t = 0 (a lower bound)"
    conds = [
        ("laws.dsc-ppc.k1", d.k1, 16 * d.k1 > 3 * rM**2 * d.tau,
         f"16 k1 > 3 rM^2 tau with rM = {rM:.4g} ({src}; ||r|| at x1 = 0, t = 0 is {r0:.4g}, "
         f"the condition needs rM < {math.sqrt(16 * d.k1 / (3 * d.tau)):.4g}): "
         f"{16 * d.k1:.4g} vs {3 * rM**2 * d.tau:.4g}"),
        ("laws.dsc-ppc.k2", d.k2, 4 * d.k2 * d.k6 > 3,
         f"4 k2 k6 > 3: {4 * d.k2 * d.k6:.4g} vs 3"),
        ("laws.dsc-ppc.k3", d.k3, 8 * d.k2 * d.k4 > 9 * d.k3**2 * k5**2,
         f"8 k2 k4 > 9 k3^2 k5^2 with k5 = ||B|| = {k5:.4g}: {8 * d.k2 * d.k4:.4g} vs {9 * d.k3**2 * k5**2:.4g}"),
    ]
    for key, val, ok, msg in conds:
        out.append(Finding("ok" if ok else "warning", key, _fmt(val),
                           ("Theorem 1 condition holds: " if ok else "Theorem 1 condition fails: ") + msg))
    return out


def _check_feedforward(scn: Scenario) -> list[Finding]:
    """The wheel accelerations that hold the desired trajectory at zero error
    (u = B+ (-A); on torque wheels the motor torques Jw u), sampled every
    second, against the limits (in the wheels' unit)."""
    cfg = scn.core_config()
    model = _core.SpacecraftModel(cfg.spacecraft)
    g = _core.Guidance(cfg.guidance, 0.1)
    g.reset(0.0)
    wheel = np.asarray(scn.initial.wheel_speed, float)
    Bp = np.asarray(model.B_pinv)
    umin, umax = np.asarray(scn.actuators.umin), np.asarray(scn.actuators.umax)
    # the limits are in the wheels' unit: on torque wheels the feed-forward as motor torques, Jw u [N m]
    torque = wheels_command(scn) == "torque"
    to_wheels = np.asarray(scn.plant.Jw, float) if torque else np.ones(4)
    worst, worst_t, worst_u = -np.inf, 0.0, None
    for t in np.arange(0.0, scn.run.duration + 1e-9, 1.0):
        g.advance(t)
        sd = g.sigma_DN
        wd = _core.omega_d(cfg.guidance, t)
        m = _core.Measurement(t, sd, wd, wheel)
        e = _core.tracking_errors(model, m, sd, wd, _core.omega_d_dot(cfg.guidance, t))
        u = to_wheels * (Bp @ (-np.asarray(e.A)))
        use = np.max(np.maximum(u / umax, u / umin))  # fraction of the limit on its side
        if use > worst:
            worst, worst_t, worst_u = use, t, u
    if worst < 1.0:
        return [Finding("ok", "spacecraft.umax", "",
                        f"the feed-forward of the desired trajectory uses at most {100 * worst:.3g} % of the "
                        f"wheel limits (at t = {worst_t:g} s, initial wheel speeds)")]
    return [Finding("warning", "spacecraft.umax", _fmt(umax),
                    f"the feed-forward of the desired trajectory needs {_fmt(worst_u)} "
                    f"{'N m' if torque else 'rad/s^2'} at t = {worst_t:g} s: "
                    "beyond the wheel limits, no law can track it exactly")]


def _check_fault_times(scn: Scenario) -> list[Finding]:
    """A scheduled fault at or after the run's end never happens in it."""
    out = []
    end = float(scn.run.duration)
    for i, f in enumerate(scn.actuators.faults):
        if f.onset >= end:
            out.append(Finding("warning", f"faults[{i}].onset", f"{f.onset:g}",
                               f"wheel {f.wheel + 1}'s fault starts at or after the run's end "
                               f"(run.duration = {end:g} s): the run never sees it"))
    if scn.actuators.faults and not out:
        out.append(Finding("ok", "faults", "", f"every scheduled fault starts within the run ({end:g} s)"))
    return out


def exit_code(findings: list[Finding], strict: bool = False) -> int:
    """The exit code of ``sc-rt check``: 2 errors, 1 warnings (and notes with
    ``strict``), else 0."""
    levels = {f.level for f in findings}
    if "error" in levels:
        return 2
    return 1 if "warning" in levels or (strict and "note" in levels) else 0
