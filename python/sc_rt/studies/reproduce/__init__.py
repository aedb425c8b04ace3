"""``sc-rt reproduce``: the paper's claims (MODEL.md section 8) checked with numbers.

Runs both paper scenarios (``scenarios/paper_fault_free.toml``,
``scenarios/paper_faults.toml``) with all four laws at the scenario files'
10 Hz zero-order hold and 0.1 s plant step (or the overrides given), writes
paper-style figures per scenario and ``claims.json`` / ``claims.md``: one row
per claim, the measured numbers, a verdict and the command that made it.

Verdict rule (``verdict_of``): a claim is checked in every case it covers
(fault-free, faults). In each case it *holds* by a plain comparison of the
measured number with the claim (``case_holds``):

- ``inside``: the law has no bound violation in 300 s (first violation null);
- ``leaves``: the law has a bound violation (first violation not null);
- ``below``: the measured maximum is below the claim's threshold;
- ``within_limits``: every commanded wheel acceleration u_cmd (before the
  saturation the plant applies) lies in [umin, umax].

The verdict is "reproduced" when the claim holds in every case it covers,
"not reproduced" when it holds in none, "partly" otherwise.
"""

from __future__ import annotations

import json
import math
import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.results.metrics import json_safe, prescribed_chi
from sc_rt.scenario.model import Scenario, load_scenario
from sc_rt.sim.engines import SimResult, simulate

__all__ = [
    "CASES",
    "CLAIM_IDS",
    "LAWS",
    "case_holds",
    "claims_of",
    "format_claims_md",
    "reproduce",
    "run_all",
    "sensitivity",
    "verdict_of",
]

ROOT = Path(__file__).resolve().parents[4]
#: case name -> scenario file (relative to the repository)
CASES = {"fault_free": "scenarios/paper_fault_free.toml", "faults": "scenarios/paper_faults.toml"}
LAWS = ("dsc-ppc", "dsc", "pd", "rft")
LAW_LABEL = {"dsc-ppc": "DSC+PPC", "dsc": "DSC", "pd": "PD", "rft": "RFT"}
CLAIM_IDS = ("C1", "C2", "C3", "C4", "C5", "C6", "C7")
OMEGA_E_THRESHOLD = 1e-7  # [rad/s] MODEL.md s8, after 70 s, fault-free
OBSERVER_THRESHOLD = 2e-6  # [rad/s^2] MODEL.md s8, |z2 - delta_2| after 30 s, fault-free
DPI = 80


def case_holds(case: dict[str, Any]) -> bool:
    """Whether one case of a claim holds, from its numbers (the documented rule)."""
    kind = case["kind"]
    if kind == "inside":
        return case["first_bound_violation_s"] is None
    if kind == "leaves":
        return case["first_bound_violation_s"] is not None
    if kind == "below":
        return case["value"] is not None and case["value"] < case["threshold"]
    if kind == "within_limits":
        return case["u_cmd_min"] >= case["umin"] and case["u_cmd_max"] <= case["umax"]
    raise ValueError(f"unknown kind {kind!r}")


def verdict_of(cases: dict[str, dict[str, Any]]) -> str:
    held = [case_holds(c) for c in cases.values()]
    if all(held):
        return "reproduced"
    if not any(held):
        return "not reproduced"
    return "partly"


@dataclass
class Runs:
    """Every run of one reproduction: runs[case][law] and the scenarios."""

    scenarios: dict[str, Scenario]
    results: dict[str, dict[str, SimResult]]
    engine: str
    control_rate_hz: float | None
    plant_step: float | None


def load_cases(root: Path = ROOT) -> dict[str, Scenario]:
    return {c: load_scenario(root / f) for c, f in CASES.items()}


def run_all(*, engine: str = "cpp", control_rate_hz: float | None = None,
            plant_step: float | None = None, duration: float | None = None,
            scenarios: dict[str, Scenario] | None = None) -> Runs:
    scns = scenarios if scenarios is not None else load_cases()
    res = {c: {law: simulate(s, law=law, engine=engine, control_rate_hz=control_rate_hz,
                             plant_step=plant_step, duration=duration) for law in LAWS}
           for c, s in scns.items()}
    return Runs(scns, res, engine, control_rate_hz, plant_step)


def _f(v: Any) -> float | None:
    return None if v is None else float(v)


def _bound_case(r: SimResult, kind: str) -> dict[str, Any]:
    m = r.metrics
    return {"kind": kind, "first_bound_violation_s": _f(m["first_bound_violation_s"]),
            "first_bound_violation_axis": m["first_bound_violation_axis"],
            "sigma_e_norm_300s": _f(m["sigma_e_norm"]["300"]),
            "saturated_fraction": m["saturated_fraction"], "diverged": bool(r.diverged)}


def _cmd_case(r: SimResult, scn: Scenario) -> dict[str, Any]:
    tr = r.trajectory
    u, us = tr["u_cmd"], tr["u_sat"]
    umin, umax = float(np.min(scn.actuators.umin)), float(np.max(scn.actuators.umax))
    out_of = np.any((u < scn.actuators.umin) | (u > scn.actuators.umax), axis=1)
    return {"kind": "within_limits", "checked": "u_cmd (commanded, before saturation)",
            "umin": umin, "umax": umax, "u_cmd_min": float(np.min(u)), "u_cmd_max": float(np.max(u)),
            "fraction_of_steps_u_cmd_outside_limits": float(np.mean(out_of)),
            "u_sat_min": float(np.min(us)), "u_sat_max": float(np.max(us))}


def _fmt(v: Any) -> str:
    if v is None:
        return "none"
    if isinstance(v, float):
        return f"{v:.3g}"
    return str(v)


def _bound_text(c: dict[str, Any]) -> str:
    if c["first_bound_violation_s"] is None:
        return "inside for 300 s"
    return (f"leaves at {c['first_bound_violation_s']:.2f} s (axis "
            f"{'xyz'[c['first_bound_violation_axis'] - 1]})")


def claims_of(runs: Runs, command: str) -> dict[str, Any]:
    """The claims table of MODEL.md section 8 from the runs."""
    R, S = runs.results, runs.scenarios
    claims: list[dict[str, Any]] = []

    def add(cid, claim, source, checked, cases, measured):
        claims.append({"id": cid, "claim": claim, "source": source, "checked": checked,
                       "cases": cases, "measured": measured, "verdict": verdict_of(cases)})

    cases = {c: _bound_case(R[c]["dsc-ppc"], "inside") for c in R}
    add("C1", "DSC+PPC keeps the attitude error inside the prescribed bounds in both cases",
        "paper figs 4-6 (fault-free), 10-12 (faults)",
        "first time any axis of sigma_BD leaves -dmin chi(t) < x < dmax chi(t) (29), scenario envelope",
        cases, "; ".join(f"{c}: {_bound_text(v)}" for c, v in cases.items()))
    for cid, law in (("C2", "dsc"), ("C3", "rft"), ("C4", "pd")):
        cases = {c: _bound_case(R[c][law], "leaves") for c in R}
        add(cid, f"{LAW_LABEL[law]} leaves the prescribed bounds",
            "paper figs 4-6, 10-12", "first bound violation of the law's run (same envelope)",
            cases, "; ".join(f"{c}: {_bound_text(v)}" for c, v in cases.items()))
    if "fault_free" in R:
        r = R["fault_free"]["dsc-ppc"]
        v = r.metrics["max_abs_omega_e_after_70s"]
        cases = {"fault_free": {"kind": "below", "value": _f(v), "threshold": OMEGA_E_THRESHOLD,
                                "quantity": "max |omega_BD_B,i| over t >= 70 s [rad/s]"}}
        add("C5", "fault-free, DSC+PPC: |omega_e| < 1e-7 rad/s after 70 s", "paper fig 7",
            "max over components and t >= 70 s of |omega_BD_B|", cases,
            f"max |omega_e| after 70 s = {_fmt(_f(v))} rad/s")
        v = r.metrics["max_observer_error_after_30s"]
        cases = {"fault_free": {"kind": "below", "value": _f(v), "threshold": OBSERVER_THRESHOLD,
                                "quantity": "max |z2_i - delta_2,i| over t >= 30 s [rad/s^2]"}}
        add("C6", "fault-free, DSC+PPC: observer error on delta_2 < 2e-6 after 30 s", "paper fig 9",
            "max over components and t >= 30 s of |z2 - delta_2|, delta_2 from the true plant", cases,
            f"max |z2 - delta_2| after 30 s = {_fmt(_f(v))} rad/s^2")
    cases = {c: _cmd_case(R[c]["dsc-ppc"], S[c]) for c in R}
    add("C7", "DSC+PPC wheel commands respect the saturation limits (-7, +10 rad/s^2)",
        "paper figs 8, 14",
        "the COMMANDED u_cmd (before saturation); the applied u_sat is within the limits "
        "by construction (the plant saturates) and is reported for context", cases,
        "; ".join(f"{c}: u_cmd in [{_fmt(v['u_cmd_min'])}, {_fmt(v['u_cmd_max'])}], outside the "
                  f"limits in {100 * v['fraction_of_steps_u_cmd_outside_limits']:.1f} % of steps; "
                  f"u_sat in [{_fmt(v['u_sat_min'])}, {_fmt(v['u_sat_max'])}]"
                  for c, v in cases.items()))
    any_r = next(iter(next(iter(R.values())).values()))
    return {
        "command": command,
        "engine": runs.engine,
        "control_rate_hz": any_r.metrics["control_rate_hz"],
        "plant_step_s": _plant_step(S, runs),
        "duration_s": any_r.metrics["duration_s"],
        "scenarios": {c: CASES[c] for c in R},
        "rule": ("a case holds by comparing the measured number with the claim (inside: no bound "
                 "violation; leaves: a bound violation; below: value < threshold; within_limits: "
                 "umin <= u_cmd <= umax at every step); verdict: reproduced if every case holds, "
                 "not reproduced if none does, partly otherwise"),
        "claims": claims,
        "runs": {c: {law: json_safe(R[c][law].metrics) for law in R[c]} for c in R},
    }


def _plant_step(S: dict[str, Scenario], runs: Runs) -> float:
    from sc_rt.sim.engines import with_overrides

    s = with_overrides(next(iter(S.values())), control_rate_hz=runs.control_rate_hz,
                       plant_step=runs.plant_step)
    return float(s.run.plant_step)


def _cell(text: str) -> str:
    """Markdown table cell: a literal | is escaped."""
    return text.replace("|", "\\|")


def format_claims_md(doc: dict[str, Any]) -> str:
    lines = [(f"Command: `{doc['command']}` (engine {doc['engine']}, control rate "
             f"{doc['control_rate_hz']:g} Hz, plant step {doc['plant_step_s']:g} s, "
             f"{doc['duration_s']:g} s)"), "",
             "| id | claim (MODEL.md s8) | checked | measured | verdict |", "|---|---|---|---|---|"]
    for c in doc["claims"]:
        lines.append(f"| {c['id']} | {_cell(c['claim'])} ({c['source']}) | {_cell(c['checked'])} | "
                     f"{_cell(c['measured'])} | **{c['verdict']}** |")
    lines += ["", f"Rule: {doc['rule']}.", ""]
    return "\n".join(lines)


# --------------------------------------------------------------------------- #
# Figures


def _figures(runs: Runs, out: Path, dpi: int = DPI) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths: list[Path] = []

    def save(fig, name):
        fig.tight_layout()
        p = out / name
        fig.savefig(p, dpi=dpi)
        plt.close(fig)
        paths.append(p)

    colors = {"dsc-ppc": "C0", "dsc": "C1", "pd": "C2", "rft": "C3"}
    for case, R in runs.results.items():
        scn = runs.scenarios[case]
        ppc = scn.controller.ppc
        dmin, dmax = np.asarray(ppc.dmin), np.asarray(ppc.dmax)
        tag = f"{case}, {R['dsc-ppc'].metrics['control_rate_hz']:g} Hz"
        for log in (False, True):
            fig, axs = plt.subplots(3, 1, figsize=(8, 7.5), sharex=True)
            for i, ax in enumerate(axs):
                for law, r in R.items():
                    t, x = r.trajectory["t"], r.trajectory["sigma_BD"][:, i]
                    y = np.abs(x) + 1e-300 if log else x
                    ax.plot(t, y, color=colors[law], lw=0.9, label=LAW_LABEL[law])
                t = R["dsc-ppc"].trajectory["t"]
                chi = prescribed_chi(ppc, t)[:, i]
                if log:
                    ax.set_yscale("log")
                    ax.plot(t, dmax[i] * chi, "k--", lw=0.8, label="dmax chi (x > 0)")
                    ax.plot(t, dmin[i] * chi, "k:", lw=0.8, label="dmin chi (x < 0)")
                    ax.set_ylim(1e-9, 2.0)
                else:
                    ax.plot(t, dmax[i] * chi, "k--", lw=0.8, label="bounds")
                    ax.plot(t, -dmin[i] * chi, "k--", lw=0.8)
                    lim = 1.3 * max(dmax[i], dmin[i]) * ppc.chi0[i]
                    ax.set_ylim(-lim, lim)
                ax.set_ylabel(f"{'|sigma_e,' if log else 'sigma_e,'}{'xyz'[i]}{'|' if log else ''} [-]")
                ax.grid(alpha=0.3, which="both" if log else "major")
            axs[0].legend(fontsize=7, ncol=3, loc="upper right")
            axs[0].set_title(f"Attitude tracking error (MRP) and prescribed bounds, {tag}"
                             f"{', log scale' if log else ''}")
            axs[-1].set_xlabel("t [s]")
            save(fig, f"{case}_attitude_error{'_log' if log else ''}.png")

        fig, ax = plt.subplots(figsize=(8, 4))
        for law, r in R.items():
            ax.semilogy(r.trajectory["t"], np.linalg.norm(r.trajectory["omega_BD_B"], axis=1) + 1e-300,
                        color=colors[law], lw=0.9, label=LAW_LABEL[law])
        if case == "fault_free":
            ax.axhline(OMEGA_E_THRESHOLD, color="k", ls=":", lw=0.8, label="claim 1e-7 after 70 s")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("|omega_e| [rad/s]")
        ax.set_title(f"Angular-rate tracking error, {tag}")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, ncol=3)
        save(fig, f"{case}_rate_error.png")

        r = R["dsc-ppc"]
        t = r.trajectory["t"]
        fig, axs = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        for j in range(4):
            axs[0].plot(t, r.trajectory["u_sat"][:, j], lw=0.8, label=f"RW{j + 1}")
            axs[1].plot(t, r.trajectory["u_cmd"][:, j], lw=0.8, label=f"RW{j + 1}")
        umin, umax = float(np.min(scn.actuators.umin)), float(np.max(scn.actuators.umax))
        for ax in axs:
            ax.axhline(umax, color="k", ls="--", lw=0.8, label="umax, umin")
            ax.axhline(umin, color="k", ls="--", lw=0.8)
            ax.grid(alpha=0.3)
        axs[0].set_ylabel("applied u_sat [rad/s^2]")
        axs[0].set_title(f"DSC+PPC wheel commands and saturation limits, {tag}")
        axs[0].legend(fontsize=7, ncol=5)
        axs[1].set_yscale("symlog", linthresh=10.0)
        axs[1].set_yticks([-1e12, -1e8, -1e4, -10, 0, 10, 1e4, 1e8, 1e12])
        axs[1].set_ylabel("commanded u_cmd [rad/s^2]")
        axs[1].set_xlabel("t [s]")
        save(fig, f"{case}_wheel_commands.png")

        fig, axs = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        for law in ("dsc-ppc", "dsc"):
            rr = R[law]
            tt = rr.trajectory["t"]
            if law == "dsc-ppc":
                for i in range(3):
                    axs[0].plot(tt, rr.trajectory["delta2"][:, i], lw=0.9, label=f"delta_2,{'xyz'[i]}")
                    axs[0].plot(tt, rr.trajectory["z2"][:, i], "--", lw=0.9, label=f"z2,{'xyz'[i]}")
            err = np.max(np.abs(rr.trajectory["z2"] - rr.trajectory["delta2"]), axis=1)
            axs[1].semilogy(tt, err + 1e-300, color=colors[law], lw=0.9,
                            label=f"{LAW_LABEL[law]}: max_i |z2 - delta_2|")
        if case == "fault_free":
            axs[1].axhline(OBSERVER_THRESHOLD, color="k", ls=":", lw=0.8, label="claim 2e-6 after 30 s")
        axs[0].set_ylim(-1.0, 1.0)
        axs[0].set_ylabel("DSC+PPC [rad/s^2]")
        axs[0].set_title(f"Lumped disturbance delta_2 and observer estimate z2, {tag}")
        axs[0].legend(fontsize=7, ncol=3)
        axs[1].set_ylabel("observer error [rad/s^2]")
        axs[1].set_xlabel("t [s]")
        axs[1].legend(fontsize=7)
        for ax in axs:
            ax.grid(alpha=0.3, which="both")
        save(fig, f"{case}_disturbance_observer.png")
    return paths


# --------------------------------------------------------------------------- #
# Sensitivity: the verdicts at other rates and plant steps

#: (label, control rate [Hz], plant step [s])
SENSITIVITY_CONFIGS = (
    ("10 Hz, plant step 0.1 s (paper)", 10.0, 0.1),
    ("10 Hz, plant step 0.01 s", 10.0, 0.01),
    ("100 Hz, plant step 0.01 s", 100.0, 0.01),
    ("1 kHz, plant step 0.001 s", 1000.0, 0.001),
)


def sensitivity(engine: str = "cpp", configs=SENSITIVITY_CONFIGS,
                scenarios: dict[str, Scenario] | None = None) -> list[dict[str, Any]]:
    scns = scenarios if scenarios is not None else load_cases()
    rows = []
    for label, rate, step in configs:
        runs = run_all(engine=engine, control_rate_hz=rate, plant_step=step, scenarios=scns)
        doc = claims_of(runs, "")
        rows.append({"config": label, "control_rate_hz": rate, "plant_step_s": step,
                     "claims": {c["id"]: {"verdict": c["verdict"], "measured": c["measured"]}
                                for c in doc["claims"]}})
    return rows


def format_sensitivity_md(rows: list[dict[str, Any]]) -> str:
    ids = list(rows[0]["claims"])
    lines = ["| config | " + " | ".join(ids) + " |", "|---|" + "---|" * len(ids)]
    for r in rows:
        lines.append(f"| {r['config']} | " + " | ".join(r["claims"][i]["verdict"] for i in ids) + " |")
    lines += ["", "Measured numbers per configuration:", ""]
    for r in rows:
        lines.append(f"- **{r['config']}**")
        for i in ids:
            lines.append(f"  - {i}: {r['claims'][i]['measured']}")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- #


def reproduce(out: Path, *, engine: str = "cpp", control_rate_hz: float | None = None,
              plant_step: float | None = None, plots: bool = True, with_sensitivity: bool = False,
              with_search: bool = False, command: str | None = None, dpi: int = DPI) -> dict[str, Any]:
    """Run everything, write claims.json, claims.md and the figures into ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if command is None:  # the canonical command line of this call
        parts = ["sc-rt", "reproduce", "--out", str(out), "--engine", engine]
        if control_rate_hz is not None:
            parts += ["--control-rate", f"{control_rate_hz:g}"]
        if plant_step is not None:
            parts += ["--plant-step", f"{plant_step:g}"]
        parts += (["--sensitivity"] if with_sensitivity else []) + (["--search"] if with_search else [])
        parts += ([] if plots else ["--no-plots"]) + ([] if dpi == DPI else ["--dpi", str(dpi)])
        command = " ".join(shlex.quote(p) for p in parts)
    runs = run_all(engine=engine, control_rate_hz=control_rate_hz, plant_step=plant_step)
    doc = claims_of(runs, command)
    md = ["# Claims of MODEL.md section 8", "", format_claims_md(doc)]
    if with_sensitivity:
        sens = sensitivity(engine=engine, scenarios=runs.scenarios)
        doc["sensitivity"] = sens
        md += ["## Sensitivity: verdicts by control rate and plant step", "", format_sensitivity_md(sens)]
        if plots:
            doc["root_cause"] = root_cause(out, engine=engine, scenarios=runs.scenarios, dpi=dpi)
    if with_search:
        doc["feasible"] = feasible_search(engine=engine)
        md += ["## Tightest chiinf that holds (bisection, both cases, 300 s) and the shipped designs", "",
               format_search_md(doc["feasible"])]
    if plots:
        doc["figures"] = [p.name for p in _figures(runs, out, dpi=dpi)]
    (out / "claims.json").write_text(json.dumps(json_safe(doc), indent=2) + "\n")
    (out / "claims.md").write_text("\n".join(md))
    return doc


# --------------------------------------------------------------------------- #
# Root cause: sampled-loop spectral radius against the simulated runs

ROOT_CAUSE_RATES = (10.0, 100.0, 1000.0)


def root_cause(out: Path, *, engine: str = "cpp", scenarios: dict[str, Scenario] | None = None,
               dpi: int = DPI) -> dict[str, Any]:
    """``root_cause.png`` and the numbers behind it (fault-free scenario, DSC+PPC):
    the spectral radius of the linearised sampled loop (sc_rt.studies.design) over t per
    rate, its predicted loss of stability, the simulated growth onset and first
    violation; chi_x(t) against the critical chi per rate with the runs' |x1|;
    at 10 Hz the commanded wheel accelerations against the limits."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sc_rt.studies import design as D

    scns = scenarios if scenarios is not None else load_cases()
    scn = scns["fault_free"]
    times = np.arange(0.0, 60.0 + 1e-9, 0.25)
    info: dict[str, Any] = {"scenario": CASES["fault_free"], "rates": {}}
    fig, axs = plt.subplots(3, 1, figsize=(8, 9))
    for j, rate in enumerate(ROOT_CAUSE_RATES):
        c = f"C{j}"
        rho = D.spectral_radius(scn, "dsc-ppc", rate, times)
        lim = D.stability_limit(scn, "dsc-ppc", rate, horizon=60.0)
        res = simulate(scn, law="dsc-ppc", engine=engine, control_rate_hz=rate, duration=60.0)
        sim = D.simulated_loss_of_stability(scn, "dsc-ppc", rate, result=res)
        info["rates"][f"{rate:g}"] = {
            "t_loss_predicted_s": lim.t_loss_s, "axis": lim.axis, "mode_hz": lim.mode_hz,
            "r_crit": lim.r_crit, "r_crit_rule": lim.r_crit_rule_of_thumb, "chi_crit": lim.chi_crit,
            "growth_onset_s": sim["onset_s"], "lam_at_onset": sim["lam_at_onset"],
            "saturated_at_onset": sim["saturated_at_onset"],
            "first_bound_violation_s": sim["first_bound_violation_s"],
            "first_bound_violation_axis": sim["first_bound_violation_axis"]}
        axs[0].plot(times, rho, color=c, label=f"{rate:g} Hz")
        if lim.t_loss_s is not None:
            axs[0].axvline(lim.t_loss_s, color=c, ls=":", lw=0.9)
        on = sim["onset_s"][0]
        if on is not None and sim["saturated_at_onset"][0] is not None and sim["saturated_at_onset"][0] < 0.5:
            axs[0].plot([on], [1.0], "v", color=c, ms=8)
        if sim["first_bound_violation_s"] is not None:
            axs[0].plot([sim["first_bound_violation_s"]], [1.0], "x", color=c, ms=9, mew=2)
        t = res.trajectory["t"]
        axs[1].semilogy(t, np.abs(res.trajectory["sigma_BD"][:, 0]) + 1e-300, color=c, lw=0.7,
                        label=f"|sigma_e,x| at {rate:g} Hz")
        axs[1].axhline(lim.chi_crit[0], color=c, ls="--", lw=0.8)
        if rate == ROOT_CAUSE_RATES[0]:
            u = np.max(np.abs(res.trajectory["u_cmd"]), axis=1)
            axs[2].semilogy(t, u, color=c, lw=0.8, label="max_i |u_cmd,i| (commanded), 10 Hz")
            p = scn.controller.ppc
            xz, chz = res.trajectory["sigma_BD"][:, 2], prescribed_chi(p, t)[:, 2]
            ratio = np.where(xz > 0, xz / (p.dmax[2] * chz), -xz / (p.dmin[2] * chz))
            axs[2].semilogy(t, ratio, color="C3", lw=0.8,
                            label="sigma_e,z over its bound (dmax_z chi_z or dmin_z chi_z), 10 Hz")
    tt = np.linspace(0, 60, 601)
    axs[1].semilogy(tt, prescribed_chi(scn.controller.ppc, tt)[:, 0], "k", lw=1.2, label="chi_x(t)")
    axs[0].axhline(1.0, color="k", lw=0.8)
    axs[0].set_ylim(0.9, 1.3)
    axs[0].set_ylabel("spectral radius of the\nsampled loop (linearised)")
    axs[0].set_title("DSC+PPC, fault-free: dotted = predicted loss of stability, "
                     "v = simulated growth onset, x = first bound violation", fontsize=9)
    axs[0].legend(fontsize=8)
    axs[1].set_ylim(1e-10, 1.0)
    axs[1].set_ylabel("[-]")
    axs[1].set_title("chi_x(t) (black) vs the critical chi_x per rate (dashed): unstable below", fontsize=9)
    axs[1].legend(fontsize=7, ncol=2)
    axs[2].axhline(10.0, color="k", ls="--", lw=0.8, label="umax = 10")
    axs[2].axhline(1.0, color="C3", ls=":", lw=0.8, label="bound (ratio 1)")
    axs[2].set_xlim(0, 10)
    axs[2].set_xlabel("t [s]")
    axs[2].set_title("10 Hz: the wheels saturate and sigma_e,z meets its bound at 4.1 s, before the "
                     "linear loss (9.8 s)", fontsize=9)
    axs[2].legend(fontsize=7)
    for ax in axs[:2]:
        ax.set_xlim(0, 60)
    for ax in axs:
        ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    path = out / "root_cause.png"
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    info["figure"] = path.name
    return info


# --------------------------------------------------------------------------- #
# The tightest chiinf that holds, by bisection (C++ engine, both scenarios)


def with_ppc(scn: Scenario, **ppc: Any) -> Scenario:
    import dataclasses

    c = scn.controller
    return dataclasses.replace(scn, controller=dataclasses.replace(
        c, ppc=dataclasses.replace(c.ppc, **{k: np.asarray(v, float) for k, v in ppc.items()})))


def without_faults(scn: Scenario) -> Scenario:
    import dataclasses

    return dataclasses.replace(scn, actuators=dataclasses.replace(scn.actuators, faults=()))


def holds(scn: Scenario, chiinf, rate: float, *, engine: str = "cpp") -> dict[str, Any]:
    """DSC+PPC with this chiinf at this rate in both the scenario and its fault-free copy."""
    out = {}
    for case, s in (("faults", scn), ("fault_free", without_faults(scn))):
        r = simulate(with_ppc(s, chiinf=chiinf), law="dsc-ppc", engine=engine, control_rate_hz=rate)
        out[case] = r.metrics["first_bound_violation_s"]
    out["holds"] = all(v is None for k, v in out.items() if k != "holds")
    return out


def chiinf_min(scn: Scenario, rate: float) -> np.ndarray:
    """The predicted smallest stable chiinf (sc_rt.studies.design.stability_limit), the larger
    of the scenario with its faults and without them, per axis."""
    from sc_rt.studies import design as D

    return np.maximum(*(np.asarray(D.stability_limit(s, "dsc-ppc", rate, horizon=1.0).chiinf_min, float)
                        for s in (scn, without_faults(scn))))


def with_dsc(scn: Scenario, **dsc: Any) -> Scenario:
    import dataclasses

    c = scn.controller
    return dataclasses.replace(scn, controller=dataclasses.replace(c, dsc=dataclasses.replace(c.dsc, **dsc)))


def tightest_chiinf(scn: Scenario, rate: float, *, lo: float = 0.5, hi: float = 2.0, rtol: float = 0.01,
                    engine: str = "cpp") -> dict[str, Any]:
    """Bisection on a factor c of chiinf = c * chiinf_min(scn, rate), both cases (the
    scenario and its fault-free copy), 300 s: the smallest c that holds (to rtol)."""
    base = chiinf_min(scn, rate)
    log = []
    r_hi = holds(scn, hi * base, rate, engine=engine)
    r_lo = holds(scn, lo * base, rate, engine=engine)
    log += [(hi, r_hi), (lo, r_lo)]
    if not r_hi["holds"] or r_lo["holds"]:
        return {"rate_hz": rate, "chiinf_min_predicted": base.tolist(), "bracket_ok": False, "log": log}
    while hi / lo > 1 + rtol:
        mid = math.sqrt(lo * hi)
        r = holds(scn, mid * base, rate, engine=engine)
        log.append((mid, r))
        if r["holds"]:
            hi = mid
        else:
            lo = mid
    return {"rate_hz": rate, "chiinf_min_predicted": base.tolist(), "bracket_ok": True,
            "factor_holds": hi, "factor_fails": lo, "chiinf_tightest": (hi * base).tolist(),
            "log": [{"factor": f, **r} for f, r in log]}


FEASIBLE_FILES = {10.0: "scenarios/ppc_feasible_10hz.toml", 100.0: "scenarios/ppc_feasible_100hz.toml",
                  1000.0: "scenarios/ppc_feasible_1khz.toml"}


def feasible_search(*, engine: str = "cpp", rates=(10.0, 100.0, 1000.0)) -> dict[str, Any]:
    """Per rate: the tightest chiinf that holds (bisection) with the paper's k2 = 4 and
    with k2 = 1.6 f, and the shipped scenarios' runs in both cases."""
    paper = load_scenario(ROOT / CASES["faults"])
    rows = []
    for rate in rates:
        for k2 in (paper.controller.dsc.k2, 1.6 * rate):
            r = tightest_chiinf(with_dsc(paper, k2=float(k2)), rate, engine=engine)
            r["k2"] = float(k2)
            rows.append(r)
    shipped = []
    for rate in rates:
        f = FEASIBLE_FILES.get(rate)
        if f is None:
            continue
        scn = load_scenario(ROOT / f)
        for case, s in (("faults", scn), ("fault_free", without_faults(scn))):
            res = simulate(s, engine=engine)
            m, tr = res.metrics, res.trajectory
            shipped.append({"file": f, "case": case, "rate_hz": rate, "k2": scn.controller.dsc.k2,
                            "chiinf": [float(v) for v in scn.controller.ppc.chiinf],
                            "first_bound_violation_s": m["first_bound_violation_s"],
                            "max_abs_lambda": float(np.nanmax(np.abs(tr["lam"]))),
                            "sigma_e_norm_300s": m["sigma_e_norm"]["300"],
                            "max_abs_omega_e_after_70s": m["max_abs_omega_e_after_70s"],
                            "max_observer_error_after_30s": m["max_observer_error_after_30s"],
                            "max_abs_u_cmd": m["max_abs_u_cmd"],
                            "saturated_fraction": m["saturated_fraction"]})
    return {"search": rows, "shipped": shipped}


def format_search_md(doc: dict[str, Any]) -> str:
    lines = [("| rate | k2 [1/s] | predicted chiinf_min x / y / z | tightest factor that holds (fails) | "
             "tightest chiinf x / y / z |"), "|---|---|---|---|---|"]
    for r in doc["search"]:
        p = " / ".join(f"{v:.3g}" for v in r["chiinf_min_predicted"])
        if r.get("bracket_ok"):
            t = " / ".join(f"{v:.3g}" for v in r["chiinf_tightest"])
            f = f"{r['factor_holds']:.4f} ({r['factor_fails']:.4f})"
        else:
            t, f = "bracket failed", "-"
        lines.append(f"| {r['rate_hz']:g} Hz | {r['k2']:g} | {p} | {f} | {t} |")
    lines += ["", ("| file | case | k2 | chiinf | first violation | max abs lambda | norm sigma_e at 300 s | "
              "max abs omega_e after 70 s | max observer error after 30 s | max abs u_cmd | saturated fraction |"),
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in doc["shipped"]:
        lines.append(f"| `{s['file']}` | {s['case']} | {s['k2']:g} | "
                     f"{', '.join(f'{v:.3g}' for v in s['chiinf'])} | {_fmt(s['first_bound_violation_s'])} | "
                     f"{s['max_abs_lambda']:.3f} | {_fmt(s['sigma_e_norm_300s'])} | "
                     f"{_fmt(s['max_abs_omega_e_after_70s'])} | {_fmt(s['max_observer_error_after_30s'])} | "
                     f"{_fmt(s['max_abs_u_cmd'])} | {s['saturated_fraction']:.4f} |")
    return "\n".join(lines) + "\n"
