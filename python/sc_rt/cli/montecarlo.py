"""``sc-rt montecarlo``: its options, their checks and the command.

Every option is checked before anything starts (no scenario read, no worker
started, nothing written): a bad value exits with code 2 and one line naming
the option and the value. So does an unreachable Dask scheduler (within a
few seconds) and an output directory that holds another campaign.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path
from typing import Any

__all__ = ["add_parser", "cmd_montecarlo", "headline", "rerun_verdict"]

from sc_rt.scenario.lawspec import LAWS  # noqa: E402
from sc_rt.cli.validate import LAW_HELP, law_choice  # noqa: E402
from sc_rt.cli.common import add_set, add_strict, claim_out, strict_exit  # noqa: E402

LAW_CHOICES = tuple(LAWS)  # the law table (sc_rt.scenario.lawspec)
SHORTCUTS = ("inertia", "onset", "effectiveness", "attitude", "rate")
_ADDRESS_RE = re.compile(r"^(tcp|tls)://(\[[0-9a-fA-F:]+\]|[A-Za-z0-9.\-]+):(\d{1,5})$")


class BadOption(Exception):
    """One bad option: its message is the line printed."""


def add_parser(sub: Any) -> argparse.ArgumentParser:
    m = sub.add_parser("montecarlo", help="dispersed runs of a scenario (C++ engine): local pool or "
                                          "Dask, resumable Parquet dataset, confidence intervals")
    m.add_argument("scenario", help="a scenario file, or a shipped name (sc-rt scenarios)")
    m.add_argument("--runs", default="200", metavar="N", help="runs 0..N-1 (default 200)")
    m.add_argument("--workers", metavar="K", help="local worker processes (default: all cores)")
    m.add_argument("--seed", default="0", metavar="S", help="campaign seed, an integer >= 0 (default 0)")
    m.add_argument("--law", "--controller", dest="law", metavar="LAW",
                   help=LAW_HELP)
    m.add_argument("--control-rate", metavar="HZ", help="default: the scenario's")
    m.add_argument("--backend", default="local", metavar="NAME",
                   help="local (process pool, the default), dask (a Dask LocalCluster of --workers)")
    m.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run on this running Dask cluster")
    m.add_argument("--scheduler-file", metavar="FILE", help="run on the Dask cluster of this scheduler file")
    m.add_argument("--batch", metavar="N", help="runs per task and per dataset file (default: <= 64)")
    m.add_argument("--resume", action="store_true", help="continue the campaign in --out: skip finished ids")
    m.add_argument("--overwrite", action="store_true", help="replace the runs already in --out")
    m.add_argument("--rerun", metavar="ID", help="run ID alone and write its full outputs to OUT/rerun-ID/: the "
                                                 "draw the campaign in --out recorded for it, replayed (else "
                                                 "drawn from --seed)")
    m.add_argument("--confidence", metavar="C", help="confidence of the requirements' statements, in (0, 1) "
                                                     "(default 0.95; docs/REQUIREMENTS.md)")
    m.add_argument("--coverage", metavar="P", help="the fraction of runs a per-run (temporal, settling, margin, "
                                                   "envelope) requirement must hold in, in (0, 1] (default 0.95)")
    g = m.add_argument_group("shortcut dispersions (uniform half-widths; the scenario's [montecarlo] "
                             "table disperses any key: docs/SCENARIOS.md). Without a table, unset ones "
                             "take the default shown; with a table, only the ones given apply")
    g.add_argument("--inertia", metavar="F", help="relative spread of the true inertia's diagonal, in [0, 1) (0.2)")
    g.add_argument("--onset", metavar="S", help="[s] spread of fault onsets, >= 0 (2)")
    g.add_argument("--effectiveness", metavar="E", help="spread of fault effectiveness, in [0, 1] (0.2)")
    g.add_argument("--attitude", metavar="RAD", help="[rad] initial attitude spread, in [0, pi] (0.01)")
    g.add_argument("--rate", metavar="RAD/S", help="[rad/s] initial rate spread per axis, >= 0 (0.002)")
    m.add_argument("--out", default="out/montecarlo", metavar="DIR", help="default: %(default)s")
    add_strict(m)  # the campaign's requirements at --confidence (--rerun: that run's) through the gate
    add_set(m)
    m.set_defaults(func=cmd_montecarlo)
    return m


#: Counts beyond these cannot be held (one dataset row per run) or run (processes).
MAX_RUNS, MAX_WORKERS, MAX_BATCH, MAX_SEED = 10_000_000, 1024, 100_000, 2**63 - 1


def _int(option: str, value: str | None, lo: int, default: int | None = None,
         hi: int | None = None) -> int | None:
    if value is None:
        return default
    want = f">= {lo}" if hi is None else f"in {lo}..{hi}"
    try:
        v = int(value)
    except ValueError:
        raise BadOption(f"{option} {value}: must be an integer {want}") from None
    if v < lo or (hi is not None and v > hi):
        raise BadOption(f"{option} {value}: must be an integer {want}")
    return v


def _float(option: str, value: str | None, lo: float, hi: float = math.inf, *,
           open_lo: bool = False, open_hi: bool = False) -> float | None:
    if value is None:
        return None
    lo_s = f"{'(' if open_lo else '['}{lo:g}"
    want = f"in {lo_s}, {hi:g}{')' if open_hi else ']'}" if math.isfinite(hi) else (
        f"> {lo:g}" if open_lo else f">= {lo:g}")
    try:
        v = float(value)
    except ValueError:
        raise BadOption(f"{option} {value}: must be a number {want}") from None
    ok = math.isfinite(v) and (v > lo if open_lo else v >= lo) and (v < hi if open_hi else v <= hi)
    if not ok:
        raise BadOption(f"{option} {value}: must be a finite number {want}")
    return v


def parse_options(args: argparse.Namespace) -> dict[str, Any]:
    """The checked options (BadOption on the first bad one)."""
    o: dict[str, Any] = {
        "runs": _int("--runs", args.runs, 1, hi=MAX_RUNS),
        "workers": _int("--workers", args.workers, 1, hi=MAX_WORKERS),
        "seed": _int("--seed", args.seed, 0),
        "batch": _int("--batch", args.batch, 1, hi=MAX_BATCH),
        "rerun": _int("--rerun", args.rerun, 0),
        "control_rate": _float("--control-rate", args.control_rate, 0.0, open_lo=True),
        "inertia": _float("--inertia", args.inertia, 0.0, 1.0, open_hi=True),
        "onset": _float("--onset", args.onset, 0.0),
        "effectiveness": _float("--effectiveness", args.effectiveness, 0.0, 1.0),
        "attitude": _float("--attitude", args.attitude, 0.0, math.pi),
        "rate": _float("--rate", args.rate, 0.0),
        "confidence": _float("--confidence", args.confidence, 0.0, 1.0, open_lo=True, open_hi=True),
        "coverage": _float("--coverage", args.coverage, 0.0, 1.0, open_lo=True),
    }
    if args.law is not None:  # a plugin or a Python law: loaded now
        try:
            args.law = law_choice(args.law)
        except argparse.ArgumentTypeError as e:
            raise BadOption(f"--law {args.law}: {e}") from None
    if args.backend not in ("local", "dask"):
        raise BadOption(f"--backend {args.backend}: must be local or dask")
    if args.scheduler and args.scheduler_file:
        raise BadOption(f"--scheduler {args.scheduler}: give --scheduler or --scheduler-file, not both")
    if args.scheduler is not None:
        m = _ADDRESS_RE.match(args.scheduler)
        if not m or not 1 <= int(m.group(3)) <= 65535:
            raise BadOption(f"--scheduler {args.scheduler}: must be tcp://HOST:PORT (port 1..65535)")
    if args.scheduler_file is not None and not Path(args.scheduler_file).is_file():
        raise BadOption(f"--scheduler-file {args.scheduler_file}: no such file")
    if args.resume and args.overwrite:
        raise BadOption("--resume with --overwrite: give one of them")
    if args.rerun is not None and (args.resume or args.overwrite):
        raise BadOption(f"--rerun {args.rerun}: runs one run alone; --resume and --overwrite do not apply")
    from sc_rt.results.present.output import check_out_dir  # not a directory, not writable

    problem = check_out_dir(Path(args.out), "--out")
    if problem:
        raise BadOption(problem)
    return o


def _dispersion(o: dict[str, Any], has_table: bool):
    from sc_rt.studies.campaign import NO_SHORTCUTS, Dispersion

    given = {k: o[k] for k in SHORTCUTS if o[k] is not None}
    if not has_table:
        return Dispersion(**given)
    base = NO_SHORTCUTS
    if "inertia" in given:  # the off-diagonal products go with the inertia shortcut
        given["products"] = Dispersion().products
    import dataclasses

    return dataclasses.replace(base, **given)


def _clear_reruns(out: Path) -> None:
    """The previous campaign's --rerun directories (each a finished run's, with
    its manifest and no live lock): they are not this campaign's runs."""
    import shutil

    from sc_rt.results.present.output import LOCK, MANIFEST

    for d in out.glob("rerun-*"):
        if d.is_dir() and (d / MANIFEST).exists() and not (d / LOCK).exists():
            shutil.rmtree(d)


def _stats(o: dict[str, Any]) -> dict[str, float]:
    """The requirements' statistics options given (the rest keep their defaults)."""
    return {k: o[k] for k in ("confidence", "coverage") if o[k] is not None}


def headline(res: dict[str, Any]) -> str:
    """The campaign in one line: the runs, and what the scenario is judged
    by: the fraction that met its per-run requirements, with its interval;
    where it asks for the prescribed envelope alone, the fraction that held
    the bound; "no requirements stated" for a scenario that states none;
    then the worst final true error (the truth against the reference: with
    sensors not the law's estimate)."""
    from sc_rt.results.judge.verdict import asks_envelope

    worst = res["worst_final_sigma_BD"]
    head = f"{res['runs']} runs of {res['scenario']} ({res.get('law_name') or res['law']}), seed {res['seed']}: "
    lo, hi = res["fraction_holding_bound_ci95"]
    if res.get("judged_by") == "requirements":
        lo2, hi2 = res["fraction_meeting_requirements_ci"]
        c = 100 * res["requirements_confidence"]
        head += (f"{100 * res['fraction_meeting_requirements']:.1f} % meet every per-run requirement "
                 f"({c:g} % CI {100 * lo2:.1f}-{100 * hi2:.1f} %)")
    elif asks_envelope(res.get("requirements")):
        head += (f"{100 * res['fraction_holding_bound']:.1f} % hold the bound (95 % CI {100 * lo:.1f}-"
                 f"{100 * hi:.1f} %)")
    else:
        head += "no requirements stated"
    return head + f"; worst final true |sigma_BD| {'-' if worst is None else f'{worst:.3e}'}"


def rerun_verdict(row: dict[str, Any], where: Path) -> str:
    """What a run alone (--rerun) did, in the terms of its scenario's
    verdict: its requirements (as ``sc-rt sim`` says them: how many met,
    which failed, the worst margin), or where it asks for the envelope
    alone, the prescribed bound (held, or when it left it)."""
    import json

    from sc_rt.results.judge.verdict import asks_envelope, requirements_summary

    if row["status"] == "invalid":
        return f"has no valid draw ({row['message']})"
    if row["status"] == "crashed":
        return f"crashed its process ({row['message']})"
    if row["status"] == "hung":
        return f"hung: its process was killed ({row['message']})"
    metrics = where / "metrics.json"
    reqs = json.loads(metrics.read_text()).get("requirements") if metrics.is_file() else None
    if reqs is not None and not (reqs and all(r.get("kind") == "envelope" for r in reqs)):
        return requirements_summary(reqs)  # "2 of 7 requirements failed (...)", "no requirements stated"
    if asks_envelope(reqs):
        return ("holds the bound" if row["holds_bound"] else
                f"leaves the bound at {row.get('first_bound_violation_s')} s")
    return "has no metrics"


def _fail(message: str) -> int:
    print(f"sc-rt montecarlo: error: {message}", file=sys.stderr)
    return 2


def _interrupted(c: Any, o: dict[str, Any], out: Path, scn: Any, e: Any) -> int:
    """A campaign stopped by a signal: the summary of the runs in the
    dataset, marked partial; exit 128 + the signal."""
    from sc_rt.studies.campaign import write_summary
    from sc_rt.studies.campaign.runner import summarize
    from sc_rt.studies.campaign.store import RunStore

    store = RunStore(out, c.columns())
    rows = store.read().to_pylist() if store.has_runs() else []
    if rows:
        res = summarize(c, store, o["runs"], **_stats(o))
        res.update(partial=True, stopped=str(e), runs_done=len(rows))
        write_summary(res, rows, out)
    print(f"sc-rt montecarlo: STOPPED ({e}): {len(rows)} of {o['runs']} runs of {scn.name} in {out}/runs"
          + (" (montecarlo.json \"partial\": true); --resume continues the campaign" if rows else ""),
          file=sys.stderr)
    return e.exit_code


def cmd_montecarlo(args: argparse.Namespace) -> int:
    try:
        o = parse_options(args)
    except BadOption as e:
        return _fail(str(e))
    from sc_rt.cli.common import scenario_arg
    from sc_rt.studies.campaign import (CampaignExists, SchedulerUnreachable, make_backend, plan_campaign,
                                        run_campaign, write_summary)
    from sc_rt.studies.campaign.runner import check_out
    from sc_rt.studies.campaign.store import RunStore

    # ScenarioError: exit 2 with file, line, key, value (the file's law probed when --law replaces it)
    scn = scenario_arg(args.scenario, args, probe=args.law is not None)
    from sc_rt.plan.run import plan_run

    # the campaign planned once: its base plan, the law loaded and probed at rest before any run
    # (ScenarioError: exit 2); every run is this plan with its drawn values
    plan = plan_run(scn, law=args.law, engine="cpp", control_rate_hz=o["control_rate"], strays=False)
    from sc_rt.cli.validate import UsageError, check_run_size

    try:  # a run of each worker held at once
        check_run_size(plan.scenario, f"--control-rate {args.control_rate}" if args.control_rate else "",
                       copies=o["workers"] or 1)
    except UsageError as e:
        return _fail(str(e))
    c = plan_campaign(plan, _dispersion(o, scn.montecarlo is not None and bool(scn.montecarlo.disperse)),
                      o["seed"])
    out = Path(args.out)
    if o["rerun"] is not None:
        return _rerun(c, o["rerun"], out, args)
    try:
        check_out(c, out, args.resume, args.overwrite)
    except CampaignExists as e:
        return _fail(f"--out {args.out}: {e}")
    try:  # the directory is this campaign's: refused while a live run holds it; the previous one's files go
        claim_out(out, keep_previous=args.resume)  # (--resume: its own dataset stays)
    except UsageError as e:
        return _fail(str(e))
    if not args.resume:
        _clear_reruns(out)
    try:
        backend = make_backend(args.backend, o["workers"], args.scheduler, args.scheduler_file)
    except SchedulerUnreachable as e:
        return _fail(f"--scheduler{'-file' if args.scheduler_file else ''} "
                     f"{args.scheduler or args.scheduler_file}: {e}")
    from sc_rt.cli.interrupts import Interrupted

    try:
        res = run_campaign(c, o["runs"], out, resume=args.resume, overwrite=args.overwrite,
                           batch_size=o["batch"], backend_obj=backend, **_stats(o))
    except CampaignExists as e:
        return _fail(f"--out {args.out}: {e}")
    except OSError as e:  # the dataset cannot be written
        return _fail(f"--out {args.out}: {e}")
    except Interrupted as e:  # the batches already in the dataset stay: summarize them, --resume goes on
        return _interrupted(c, o, out, scn, e)
    finally:
        backend.close()
    rows = RunStore(out, c.columns()).read().to_pylist()
    from sc_rt.results.judge.gate import campaign_expect, campaign_gate_problems, expect_line

    res["expect"] = campaign_expect(res, scn.expect)  # the file's expect against the campaign's verdict
    write_summary(res, rows, out)
    print(f"sc-rt montecarlo: {headline(res)}; {res['runs_this_invocation']} runs now"
          + (f" at {res['runs_per_s']:.1f} runs/s on {res['workers']} workers ({res['backend']})"
             if res["runs_per_s"] else "") + f" -> {args.out}/")
    if res.get("requirements"):
        from sc_rt.studies.campaign.text import requirement_lines

        for line in requirement_lines(res["requirements"], res["requirements_confidence"],
                                      res["requirements_coverage"]):
            print(f"  {line}")
    if line := expect_line(res["expect"], "the campaign"):
        print(f"  expect {line}")
    if res["status"].get("law_failed"):  # counted as not holding; each run's reason in montecarlo.json
        print(f"sc-rt montecarlo: the law failed (threw, non-finite or wrong shape; contained) in "
              f"{res['status']['law_failed']} of {res['runs']} runs: counted as failures "
              f"(montecarlo.json 'failed', status law_failed)", file=sys.stderr)
    for status, what in (("crashed", "crashed its run's process"),  # a law that killed its run's process
                         ("hung", "hung (no step within SCRT_STALL_TIMEOUT; killed)")):  # that run only
        if res["status"].get(status):
            print(f"sc-rt montecarlo: the law {what} in {res['status'][status]} of {res['runs']} runs: counted "
                  f"as failures (montecarlo.json 'failed', status {status})", file=sys.stderr)
    return strict_exit(campaign_gate_problems(res), 0, "montecarlo", args.strict)


def _rerun(c: Any, run: int, out: Path, args: argparse.Namespace) -> int:
    """``--rerun ID``: run ID alone into OUT/rerun-ID/. When the campaign in
    --out holds run ID, its recorded draw is replayed exactly (its seed and
    values as the campaign drew them, whatever --seed, the shortcut options
    or the [montecarlo] table say now) and the new row is compared with the
    recorded one; else the run is drawn from (--seed, ID)."""
    import dataclasses

    from sc_rt.cli.validate import UsageError
    from sc_rt.studies.campaign import RunDraw, rerun
    from sc_rt.studies.campaign.runner import recorded_row

    where = out / f"rerun-{run}"
    try:
        claim_out(where)
    except UsageError as e:
        return _fail(str(e))
    same, ours = recorded_row(c, out, run)
    recorded = None
    if same is not None:
        recorded = RunDraw.from_row(same)
        c = dataclasses.replace(c, seed=int(same["seed"]))
        if not ours:
            print(f"sc-rt montecarlo: note: the campaign in {out} was planned with other settings (seed, "
                  f"dispersions, [montecarlo] table, scenario or law); run {run} replays the draw it recorded "
                  f"(seed {c.seed})", file=sys.stderr)
    try:
        row = rerun(c, run, where, recorded=recorded)
    except KeyError as e:
        return _fail(f"--rerun {run}: the draw {out}/runs recorded sets {e}, which {c.scenario.name} does "
                     "not have: rerun it with the campaign's scenario")
    except OSError as e:
        return _fail(f"--out {args.out}: {e}")
    verdict = rerun_verdict(row, where)  # its requirements (the envelope where the scenario asks for it)
    print(f"sc-rt montecarlo: run {run} of seed {c.seed} ({c.scenario.name}): {verdict} -> {where}/")
    problems = _rerun_gate(row, where) if args.strict else []
    if same is not None:  # the campaign in --out holds this run: the two must agree
        match = repr(same) == repr({k: row.get(k) for k in same})
        print(f"sc-rt montecarlo: run {run} {'matches' if match else 'DIFFERS FROM'} its row in {out}/runs")
        return strict_exit(problems, 0 if match else 1, "montecarlo", args.strict)
    return strict_exit(problems, 0, "montecarlo", args.strict)


def _rerun_gate(row: dict[str, Any], where: Path) -> list[str]:
    """--strict's problems of a run alone (--rerun): its metrics.json through
    the gate; a draw that gave no run is one."""
    import json

    from sc_rt.results.judge.gate import gate_problems

    metrics = where / "metrics.json"
    if row.get("status") == "crashed":
        return [f"the law crashed the run's process ({row.get('message')})"]
    if row.get("status") == "hung":
        return [f"the law hung; its run's process was killed ({row.get('message')})"]
    if row.get("status") == "invalid" or not metrics.is_file():
        return [f"run {row.get('run')} has no valid draw ({row.get('message')})"]
    return gate_problems(json.loads(metrics.read_text()))
