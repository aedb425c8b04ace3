"""A Monte Carlo campaign: dispersed runs of one scenario (C++ engine) on a
backend, rows streamed to the dataset as batches complete, resumable, and
its statistics at the end (sc_rt.studies.campaign.stats)."""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sc_rt.plan.run import RunPlan, plan_run
from sc_rt.scenario.keys import scenario_data
from sc_rt.scenario.model import Scenario
from sc_rt.studies.campaign.backends import make_backend
from sc_rt.studies.campaign.draws import (Dispersion, RunDraw, draw_scenario, run_scenario, value_columns,
                                          value_keys)
from sc_rt.studies.campaign.requirements import campaign_requirements, row_columns
from sc_rt.studies.campaign.stats import clopper_pearson, tolerance_bound
from sc_rt.studies.campaign.store import RunStore, fingerprint

__all__ = ["Campaign", "CampaignExists", "check_out", "plan_campaign", "recorded_row", "run_batch",
           "run_campaign", "run_one", "rerun", "summarize"]

_HEAD = [("run", "int64"), ("seed", "int64"), ("status", "string"), ("redraws", "int64"),
         ("holds_bound", "bool"), ("message", "string"),
         ("draws", "string")]  # the run's drawn values, JSON (draws.RunDraw): what --rerun replays  # fmt: skip
#: Metrics left out of the rows: the same for every run, or not a property of the run.
SKIP_METRICS = ("scenario", "controller", "engine", "control_rate_hz", "duration_s", "wall_s",
                # a failed law is the row's status and message (law_failed), not columns
                "law_failures", "valid", "invalid_reason",
                # the scenario's requirements: their own columns, req.NAME.* (studies/campaign/requirements.py)
                "requirements",
                # the command interface and the metrics' units: the scenario's and the law's, every run's
                "wheel_command", "law_command", "units")
#: Metrics whose worst case (largest value) gets a Wilks tolerance bound (those present).
WORST_CASE = ("max_abs_omega_e_after_70s", "max_observer_error_after_30s",
              "max_pointing_error_arcsec_after_30s", "max_abs_u_cmd", "saturated_fraction")  # fmt: skip


class CampaignExists(RuntimeError):
    """The output directory holds another campaign's runs (or runs and no --resume)."""


@dataclass(frozen=True)
class Campaign:
    """A campaign, planned once: its base plan (the scenario with its
    overrides, the law resolved, the engine), the shortcut dispersions and
    the seed. Run i is the base plan with run i's drawn values
    (sc_rt.studies.campaign.draws.plan_draw), which its plan records as
    inputs. Pickles to the workers (in-memory changes included). Build it
    with :func:`plan_campaign`."""

    plan: RunPlan
    dispersion: Dispersion
    seed: int

    @property
    def scenario(self) -> Scenario:
        """The base plan's scenario (overrides applied, law resolved)."""
        return self.plan.scenario

    def columns(self) -> list[tuple[str, str]]:
        """The columns known before any run (the metrics' follow simulate()'s .metrics)."""
        return _HEAD + [(c, "float64") for c in value_columns(self.scenario, self.dispersion)]

    def identity(self) -> dict[str, Any]:
        """What makes two campaigns the same (resume checks it)."""
        mc = self.scenario.montecarlo
        return {"scenario": scenario_data(self.scenario), "seed": self.seed,
                "dispersion": dataclasses.asdict(self.dispersion),
                "table": None if mc is None else [dataclasses.asdict(e) for e in mc.disperse],
                "on_invalid": None if mc is None else [mc.on_invalid, mc.max_redraws],
                "law": dataclasses.asdict(self.plan.law), "engine": self.plan.engine}

    def run_plan(self, run: int, recorded: RunDraw | None = None) -> tuple[RunPlan | None, RunDraw, str]:
        """(run ``run``'s plan: the base plan with its drawn values, None when
        they make no valid scenario; the draw; why not, else ""). ``recorded``:
        the draw a dataset recorded, replayed instead of drawn (--rerun)."""
        if recorded is None:
            rd, scn, message = draw_scenario(self.scenario, self.dispersion, self.seed, run)
        else:
            rd, (scn, message) = recorded, run_scenario(self.scenario, recorded, run)
        return (None if scn is None else dataclasses.replace(self.plan, scenario=scn)), rd, message


def plan_campaign(scenario: Scenario | RunPlan, dispersion: Dispersion = Dispersion(), seed: int = 0,
                  law: str | None = None, control_rate_hz: float | None = None) -> Campaign:
    """A campaign's plan: the base plan of ``scenario`` (a Scenario, planned
    here with ``law`` and ``control_rate_hz`` on the cpp engine as
    ``sc_rt.plan.run.plan_run`` does: the law loaded and probed once; or a
    RunPlan already made), the dispersions and the seed."""
    if isinstance(scenario, RunPlan):
        plan = scenario
    else:
        plan = plan_run(scenario, law=law, engine="cpp", control_rate_hz=control_rate_hz, strays=False)
    if plan.engine not in ("python", "cpp"):
        raise ValueError(f"a campaign runs on an offline engine (cpp or python), not {plan.engine!r}")
    return Campaign(plan, dispersion, int(seed))


def _metric_row(m: dict[str, Any]) -> dict[str, Any]:
    """simulate()'s .metrics flattened to columns: "sigma_e_norm.30",
    "final_wheel_speed[2]"; numbers, booleans and None only."""
    row: dict[str, Any] = {}

    def put(key: str, v: Any) -> None:
        if isinstance(v, dict):
            for k, x in v.items():
                put(f"{key}.{k}", x)
        elif isinstance(v, (list, tuple)):
            for i, x in enumerate(v):
                put(f"{key}[{i}]", x)
        elif v is None or isinstance(v, (bool, int, float)):
            row[key] = v
        elif isinstance(v, (np.floating, np.integer, np.bool_)):
            row[key] = v.item()

    for k, v in m.items():
        if k not in SKIP_METRICS:
            put(k, v)
    return row


def run_one(c: Campaign, run: int, keep: bool = False, recorded: RunDraw | None = None
            ) -> dict[str, Any] | tuple:  # fmt: skip
    """Run ``run`` of the campaign: its dataset row (and, with ``keep``, its
    plan and the simulation result too). ``recorded``: the draw a dataset
    recorded for this run, replayed (the row's columns are its values')."""
    from sc_rt.sim.isolated import RunCrashed, RunHung, simulate_plan

    plan, rd, message = c.run_plan(run, recorded)
    values = rd.columns() if recorded is not None else rd.columns(value_keys(c.scenario, c.dispersion))
    row: dict[str, Any] = {"run": run, "seed": c.seed, "redraws": rd.redraws, "draws": rd.to_json(), **values}
    res = None
    if plan is None:
        row.update(status="invalid", holds_bound=False, message=message)
    else:
        try:  # a plugin runs in a child of its own: one crash fails this run, not the campaign (docs/HIL.md)
            res = simulate_plan(plan)
        except RunCrashed as e:
            row.update(status="hung" if isinstance(e, RunHung) else "crashed", holds_bound=False, message=str(e))
            return (row, plan, None) if keep else row
        m = res.metrics
        law_failed = m.get("valid") is False  # the law threw, went non-finite or gave a wrong shape
        row.update(status="diverged" if m.get("diverged") else "law_failed" if law_failed else "ok",
                   holds_bound=bool(m["finite"] and m["first_bound_violation_s"] is None and not law_failed),
                   message=m.get("invalid_reason", "") if law_failed else "")
        row.update(_metric_row(m))
        if m.get("requirements"):
            from sc_rt.results.judge.ensemble import campaign_series

            row.update(row_columns(m["requirements"], campaign_series(res, m["requirements"])))
    return (row, plan, res) if keep else row


def run_batch(c: Campaign, runs: list[int]) -> list[dict[str, Any]]:
    """The rows of a batch of run ids (what a worker executes)."""
    return [run_one(c, i) for i in runs]


def _batches(ids: list[int], size: int) -> list[list[int]]:
    return [ids[k:k + size] for k in range(0, len(ids), size)]


def check_out(c: Campaign, out: Path, resume: bool, overwrite: bool) -> str:
    """The campaign's fingerprint, once ``out`` may take its runs (else CampaignExists)."""
    store = RunStore(out, c.columns())
    fp = fingerprint(c.identity())
    old = store.existing_manifest()
    if resume and old is not None and old.get("fingerprint") != fp:
        raise CampaignExists("holds a different campaign (scenario, seed, dispersions, law or "
                             "rate differ): resume it with its own settings or use another --out")
    if not resume and not overwrite and store.has_runs():
        raise CampaignExists("runs/ holds runs already: --resume to continue that campaign, "
                             "--overwrite to start again")
    return fp


def run_campaign(c: Campaign, runs: int, out: Path, *, backend: str = "local",
                 workers: int | None = None, scheduler: str | None = None,
                 scheduler_file: str | None = None, resume: bool = False,
                 overwrite: bool = False, batch_size: int | None = None,
                 progress: bool = True, backend_obj=None, confidence: float = 0.95,
                 coverage: float = 0.95) -> dict[str, Any]:
    """Run ids 0..runs-1 (those not in the dataset yet with ``resume``),
    appending each completed batch to ``out/runs``; returns the summary of
    the whole dataset (also written to ``out/montecarlo.json``).
    ``confidence``, ``coverage``: of the requirements' statements (summarize)."""
    store = RunStore(out, c.columns())
    ident = c.identity()
    fp = check_out(c, out, resume, overwrite)
    b = backend_obj or make_backend(backend, workers, scheduler, scheduler_file)
    t0 = time.perf_counter()
    done_now = 0
    try:
        store.start({"fingerprint": fp, "campaign": ident, "runs": runs}, fresh=not resume)
        done = store.done_ids() if resume else set()
        todo = [i for i in range(runs) if i not in done]
        size = batch_size or max(1, min(64, len(todo) // (8 * max(1, b.workers)) or 1))
        bar = _bar(progress, runs, len(done))
        for rows in b.map(run_batch, c, _batches(todo, size)):
            store.append(rows)
            done_now += len(rows)
            if bar is not None:
                bar.update(len(rows))
        if bar is not None:
            bar.close()
        info = b.describe()
    finally:
        if backend_obj is None:
            b.close()
    wall = time.perf_counter() - t0
    summary = summarize(c, store, runs, confidence=confidence, coverage=coverage)
    summary.update(info)
    summary.update(wall_s=wall, runs_this_invocation=done_now,
                   runs_per_s=done_now / wall if wall > 0 and done_now else None)
    return summary


def _bar(on: bool, total: int, initial: int):
    if not on:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="run", desc="montecarlo", file=sys.stderr,
                disable=not sys.stderr.isatty(), smoothing=0.1)


def _final_column(names: list[str]) -> str | None:
    """The last reported true |sigma_BD| ("sigma_e_norm.<largest time>": the truth against the reference)."""
    ts = [n.removeprefix("sigma_e_norm.") for n in names if n.startswith("sigma_e_norm.")]
    ts = [t for t in ts if t.replace(".", "", 1).isdigit()]
    return f"sigma_e_norm.{max(ts, key=float)}" if ts else None


def summarize(c: Campaign, store: RunStore, runs: int, confidence: float = 0.95,
              coverage: float = 0.95) -> dict[str, Any]:
    """Statistics of the dataset (every row written so far); the
    requirements' at ``confidence``, a per-run one required in a fraction
    ``coverage`` of the runs (sc_rt.studies.campaign.requirements)."""
    t = store.read()
    rows = t.to_pylist()
    n = len(rows)
    held = sum(r["holds_bound"] for r in rows)
    values = [k for k, _ in c.columns() if k not in dict(_HEAD)]
    failed = [{"run": r["run"], "status": r["status"],
               "first_bound_violation_s": r.get("first_bound_violation_s"),
               "message": r["message"], "values": {k: r[k] for k in values}}
              for r in rows if not r["holds_bound"]]  # fmt: skip
    final = _final_column(t.column_names)

    def worst(k):  # a run without the metric (invalid, diverged, too short) counts as +inf
        return [math.inf if r.get(k) is None or not math.isfinite(r[k]) else r[k] for r in rows]

    fin = [r[final] for r in rows if final and r.get(final) is not None]
    mc = c.scenario.montecarlo
    return {
        "scenario": c.scenario.name,
        "law": c.plan.law.spec,
        # its name (a plugin's or a Python law's, not its path)
        "law_name": c.plan.law.name,
        # what the campaign was made from (the base plan's inputs; each run's draws are in its dataset row)
        "inputs": c.plan.inputs(),
        "control_rate_hz": c.scenario.run.control_rate_hz,
        "duration_s": c.scenario.run.duration,
        "runs": n, "runs_requested": runs, "complete": n == runs, "seed": c.seed,
        "dispersion": dataclasses.asdict(c.dispersion),
        "table": None if mc is None else {"on_invalid": mc.on_invalid, "max_redraws": mc.max_redraws,
                                          "disperse": [dataclasses.asdict(e) for e in mc.disperse]},
        "holds_bound": held,
        "fraction_holding_bound": held / n if n else None,
        "fraction_holding_bound_ci95": list(clopper_pearson(held, n)) if n else None,
        "ci_method": "Clopper-Pearson, two-sided 95 %",
        "status": {s: sum(r["status"] == s for r in rows)
                   for s in ("ok", "diverged", "invalid", "law_failed", "crashed", "hung")},
        "redraws_total": sum(r["redraws"] for r in rows),
        "final_metric": final,
        "worst_final_sigma_BD": max(fin) if fin else None,
        "median_final_sigma_BD": float(np.median(fin)) if fin else None,
        "tolerance_95_95": {k: tolerance_bound(worst(k)) for k in (final, *WORST_CASE)
                            if k in t.column_names},
        "runs_breaking_bound": [f["run"] for f in failed[:1000]],
        "failed_total": len(failed),
        "failed": failed[:1000],
        "dataset": {"path": "runs/", "rows": n, "bytes": store.bytes(),
                    "bytes_per_row": store.bytes() / n if n else None,
                    "columns": t.num_columns},
        **_requirements_summary(c, rows, confidence, coverage),
    }


def _requirements_summary(c: Campaign, rows: list[dict[str, Any]], confidence: float,
                          coverage: float) -> dict[str, Any]:
    """The requirements' part of the summary: the runs meeting every
    per-run requirement, and each requirement's statistics."""
    reqs = c.scenario.requirements
    if not reqs or not rows:
        return {"requirements": [] if not reqs else None}
    n = len(rows)
    met = sum(r.get("meets_requirements") is True for r in rows)
    rate = c.scenario.run.control_rate_hz
    return {
        "requirements_confidence": confidence, "requirements_coverage": coverage,
        "judged_by": "envelope" if all(r.kind == "envelope" for r in reqs) else "requirements",
        "meets_requirements": met, "fraction_meeting_requirements": met / n,
        "fraction_meeting_requirements_ci": list(clopper_pearson(met, n, confidence)),
        "requirements": campaign_requirements(reqs, rows, c.scenario.run.duration, rate, confidence, coverage),
    }


def recorded_row(c: Campaign, out: Path, run: int) -> tuple[dict[str, Any] | None, bool]:
    """(run ``run``'s row in the campaign dataset of ``out``, its nulls left
    out; None without one, or a row written before runs recorded their draws;
    whether that campaign is ``c``: the same fingerprint)."""
    store = RunStore(out, c.columns())
    old = store.existing_manifest()
    if old is None or not store.has_runs():
        return None, False
    rows = [r for r in store.read().to_pylist() if r["run"] == run]
    if not rows or rows[0].get("draws") is None:
        return None, False
    row = {k: v for k, v in rows[0].items() if v is not None or k in ("message",)}
    return row, old.get("fingerprint") == fingerprint(c.identity())


def rerun(c: Campaign, run: int, out: Path, plots: bool = True, recorded: RunDraw | None = None) -> dict[str, Any]:
    """Run ``run`` alone and write its full outputs to ``out`` as ``sc-rt
    sim`` does (trajectory.arrow, metrics.json, figures; its inputs: the base
    plan and the run's drawn values, which ``sc-rt rerun`` replays) plus
    run.json (its dataset row). ``recorded``: the draw the campaign's
    dataset recorded for it, replayed exactly (not drawn again from the
    seed); None: drawn from (seed, run), the same draws as inside the campaign."""
    import json

    from sc_rt.results.judge.metrics import json_safe
    from sc_rt.results.present.output import write_run  # what sc-rt sim writes

    row, plan, res = run_one(c, run, keep=True, recorded=recorded)
    out.mkdir(parents=True, exist_ok=True)
    if res is not None:
        write_run(res, out, figures=plots,
                  title=f"{plan.scenario.name}, run {run} of seed {c.seed}, {res.metrics['controller']}")
    (out / "run.json").write_text(json.dumps(json_safe(row), indent=2) + "\n")
    return row
