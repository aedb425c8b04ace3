"""What the ``sc-rt`` commands share: the scenario argument, the metrics
summary, output checks, the stopped-run summary, the bus URL, the MCAP export."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sc_rt.cli.validate import UsageError, resolve_url
from sc_rt.scenario.model import LAWS  # noqa: E402


LAW_CHOICES = tuple(LAWS)  # the law table (sc_rt.scenario.model)


def scenario_arg(path: str, args: argparse.Namespace | None = None, strays: bool = True, probe: bool = True):
    """The scenario a command names; its deprecation notes on stderr, one
    line each. A ``[laws.NAME]`` table that matches no law (a built-in, the
    file's, or one the command names: ``args.law``, ``args.laws``) but is
    near one is an error (ScenarioError: exit 2 with the file, the line and
    the nearest law name); one near none is a note (another law's table;
    sc_rt.scenario.tables.laws.stray_tables). The file's law (a plugin, a Python
    law) is loaded and probed at rest (sc_rt.plan.law.probe_law: reading the
    file does not), so that a command refuses a file naming a broken law
    before anything starts. ``strays`` and ``probe`` False: a command that
    plans its run (sc_rt.plan.run.plan_run does both, with the law it runs)."""
    from sc_rt.scenario.tables.laws import stray_tables
    from sc_rt.scenario.model import ScenarioError
    from sc_rt.scenario.reader import load_scenario

    scn = load_scenario(path, getattr(args, "sets", None) or ())
    if probe:
        from sc_rt.plan.law import resolve_law

        scn, _ = resolve_law(scn)
    errors, notes = stray_tables(scn, command_laws(args)) if strays else ([], [])
    if errors:
        raise ScenarioError(scn.path, errors)
    for note in notes:
        print(f"sc-rt: note: {note}", file=sys.stderr)
    for note in scn.deprecations:
        print(f"sc-rt: note: {note}", file=sys.stderr)
    return scn


def command_laws(args: argparse.Namespace | None) -> tuple[str, ...]:
    """The laws a command names (--law, once or repeated); () for none."""
    if args is None:
        return ()
    given = [getattr(args, "law", None), *(getattr(args, "laws", None) or ())]
    return tuple(x for x in given if isinstance(x, str) and x)


def print_metrics(m: dict, faults=()) -> None:
    from sc_rt.results.judge.gate import expect_line
    from sc_rt.results.judge.verdict import asks_envelope, verdict_line

    def f(v):
        return "-" if v is None else (f"{v:.3g}" if isinstance(v, float) else str(v))

    marks = list(m["sigma_e_norm"])
    faults = ", ".join(f"wheel {x['wheel']} from {x['onset']:g} s (L {x['effectiveness']:g}, "
                       f"bias {x['bias']:g} rad/s^2)" for x in faults) or "none"
    safe = m.get("safe_steps", 0)
    why = "; ".join(f"{k}: {v}" for k, v in m.get("safe_reasons", {}).items())
    rows = [
        ("verdict", verdict_line(m, m["controller"])),
        ("controller", m["controller"]), ("engine", m["engine"]),
        ("steps", m["steps"]), ("wall [s]", f"{m['wall_s']:.3f}"), ("finite", m["finite"]),
        *(  # the envelope's lines only where the scenario asks for it (metrics.json keeps them)
            [("first bound violation [s]", f(m["first_bound_violation_s"])),
             ("  axis", "-" if m["first_bound_violation_axis"] is None
              else "xyz"[m["first_bound_violation_axis"] - 1])] if asks_envelope(m.get("requirements")) else []),
        *_errors(m, f"|sigma_BD| at {'/'.join(marks)} s", "sigma_e_norm",
                 lambda v: " / ".join(f(v.get(k)) for k in marks), first=True),
        *_errors(m, "max pointing error after 30 s [arcsec]", "max_pointing_error_arcsec_after_30s", f),
        *_errors(m, "max |omega_BD_B| after 70 s [rad/s]", "max_abs_omega_e_after_70s", f),
        ("max observer error after 30 s [rad/s^2]", f(m["max_observer_error_after_30s"])),
        (f"max |u_cmd| before saturation [{(m.get('units') or {}).get('max_abs_u_cmd', 'rad/s^2')}]",
         f(m["max_abs_u_cmd"])),
        ("max |wheel accel| applied [rad/s^2]", f(m["max_abs_wheel_accel"])),
        ("saturated fraction", f(m["saturated_fraction"])),
        ("SAFE steps", f"{safe}" + (f" from {m['safe_from_s']:.1f} s ({why})" if safe and m.get("safe_from_s")
                                    is not None else "")
         + (f"; rows applying a SAFE command: {m['safe_rows']}" if m.get("safe_rows") not in (None, safe) else "")),
        ("faults scheduled", faults),
    ]
    lf = m.get("law_failures")
    if lf and any(lf.get(k, 0) for k in ("reset", "step", "after")):
        last = lf.get("last") or {}
        rows.append(("law failures (contained)",
                     ", ".join(f"{k} {lf[k]}" for k in ("reset", "step", "after") if lf.get(k))
                     + (f"; last: {last['call']} at t = {last['t']:.4g} s: {last['what']}" if last else "")))
    reqs = m.get("requirements")
    if reqs is not None and not reqs:
        rows.append(("requirements", "no requirements stated"))
    if expect := expect_line(m.get("expect")):  # the file's expect, checked for every file
        rows.append(("expect", expect))
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"  {k:<{w}}  {v}")
    if reqs:
        for line in requirement_table(reqs):
            print(f"  {line}")


#: The line under a true error that gives the law's own (a law fed the estimate).
LAW_ROW = "  the law's (its estimate)"


def _errors(m: dict, label: str, key: str, show, first: bool = False) -> list[tuple[str, str]]:
    """The console rows of an error metric: the true error (the truth
    against the reference), named; a law fed the estimate has its own
    (metrics ``law_<key>``, what it computed from the estimate) on the row
    below; a law fed the truth has the same numbers, which the ``first``
    row says, once."""
    v = m.get(key)
    if f"law_{key}" in m:
        return [(f"true {label}", show(v)), (LAW_ROW, show(m[f"law_{key}"]))]
    return [(f"true {label}", show(v) + ("  (= the law's: fed the truth)" if first else ""))]


def _num(v, unit: str) -> str:
    if v is None:
        return "-"
    return f"{v:.4g}" if unit == "-" else f"{v:.4g} {unit}"


#: What the peak requirements measure (every kind of sc_rt.scenario.tables.requirements.KINDS that is
#: neither a pointing index, settling nor the envelope: tests/test_requirement_matrix.py).
PEAKS = {"wheel_speed_margin": "max |Omega|", "momentum_margin": "max |Cbar Jw Omega|", "max_command": "max |u_cmd|",
         "max_torque": "max |Cbar tau_cmd|"}


def requirement_table(reqs: list) -> list[str]:
    """The requirements of a run's metrics as text lines: name, what is
    measured, value, bound, margin, when it was outside its bound and the
    result, each with its note below."""
    from sc_rt.results.judge.verdict import outside_text

    head = ("requirement", "measure", "value", "bound", "margin", "outside bound", "result")
    rows = []
    for r in reqs:
        kind = r["kind"]
        if kind == "envelope":
            what = "envelope |sigma|/bound"
        elif kind == "settling":
            what = f"settling {r.get('axis', '')}" + (f" within {r['band']:g} {r['band_unit']}" if "band" in r else "")
        elif kind in PEAKS:
            what = PEAKS[kind]
        else:  # a pointing index (a kind added without a PEAKS entry: its name, never a crash)
            what = " ".join(x for x in (kind, r.get("axis") or "",
                                        "" if r.get("confidence") is None else f"p{r['confidence']:g}",
                                        r.get("interpretation") or "") if x)
            if r.get("window_s"):
                what += f" {r['window_s']:g} s"
            if r.get("separation_s"):
                what += f" {r['separation_s']:g} s apart"
        unit = r.get("unit", "-")
        margin = "-" if r.get("margin") is None else (f"{r['margin']:+.4g}" + ("" if unit == "-" else f" {unit}"))
        status = r["status"].upper() if r["status"] in ("pass", "fail") else r["status"]
        if r.get("passed") is None and r.get("interpretation") in ("ensemble", "mixed"):
            status = "across runs"
        rows.append((r["name"], what, _num(r.get("value"), unit), _num(r.get("bound"), unit), margin,
                     outside_text(r), status, r.get("note", "")))
    widths = [max(len(str(x[i])) for x in [head, *rows]) for i in range(len(head))]
    out = ["requirements:", "  " + "  ".join(f"{h:<{widths[i]}}" for i, h in enumerate(head)).rstrip()]
    for row in rows:
        out.append("  " + "  ".join(f"{str(x):<{widths[i]}}" for i, x in enumerate(row[:-1])).rstrip())
        if row[-1]:
            out.append(f"    ({row[-1]})")
    return out


def checked_out(value: str, option: str = "--out") -> Path:
    """The output directory, checked before anything runs (exit 2 if unusable)."""
    from sc_rt.results.present.output import check_out_dir

    problem = check_out_dir(Path(value), option)
    if problem:
        raise UsageError(problem)
    return Path(value)


def claim_out(out: Path, option: str = "--out", keep_previous: bool = False) -> None:
    """Claim the output directory for this run, the last thing before it
    starts (after every check: bad input writes nothing): refused (exit 2)
    while a live run holds it; the previous run's outputs there removed;
    released, its manifest written, when this process ends
    (sc_rt.results.present.output.OutDir). ``keep_previous``: the previous
    run's outputs stay (a campaign resuming its dataset)."""
    import atexit

    from sc_rt.results.present.output import OutDir, OutDirInUse

    d = OutDir(Path(out), option)
    try:
        d.claim(keep_previous)
    except OutDirInUse as e:
        raise UsageError(str(e)) from None
    atexit.register(d.release)


def html_report(out: Path, who: str) -> None:
    """report.html of the run in ``out`` (sc_rt.results.present.html_report)."""
    from sc_rt.results.present.html_report import write_html_report

    print(f"sc-rt {who}: report for reading: {write_html_report(out)}")


def invalid_exit(metrics: dict, who: str) -> int:
    """A run that went to its end but is not a valid run of its law (the
    law failed: metrics.json ``valid`` false): one line with the reason,
    exit 1; 0 for a valid run."""
    if metrics.get("valid") is False:
        print(f"sc-rt {who}: INVALID: {metrics.get('invalid_reason', 'see metrics.json')}", file=sys.stderr)
        return 1
    return 0


#: --strict's help (sim, hil, compare, montecarlo): the gate of docs/REQUIREMENTS.md
STRICT_HELP = ("a gate for CI: exit 1 when a requirement fails, the file's expect does not match the verdict, "
               "or the run is invalid (a file with expect = \"violates\" fails only when it holds); "
               "default: the exit code does not depend on the verdict")


def set_choice(text: str) -> tuple:
    """type= of --set KEY=VALUE (sc_rt.scenario.reader.parse_set): a bad pair is one line, exit 2."""
    from sc_rt.scenario.reader import parse_set

    try:
        return parse_set(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def add_set(parser) -> None:
    """--set KEY=VALUE (repeatable) on a command that reads a scenario."""
    parser.add_argument("--set", dest="sets", action="append", type=set_choice, metavar="KEY=VALUE",
                        help="set a key of the scenario file (a dotted key, a TOML value: "
                             "laws.pd.beta1=0.3), validated like the file and recorded in the run; repeatable")


def add_strict(parser) -> None:
    """--strict on a command that judges runs."""
    parser.add_argument("--strict", action="store_true", help=STRICT_HELP)


def strict_exit(problems: list[str], rc: int, who: str, strict: bool) -> int:
    """The exit code under --strict: ``rc``, or 1 when the gate found
    ``problems`` (sc_rt.results.judge.gate), said in one line on stderr."""
    if not strict or not problems:
        return rc
    print(f"sc-rt {who}: --strict: exit 1: {'; '.join(problems)}", file=sys.stderr)
    return rc or 1


def report_stopped(run, why: str, signum: int | None, out, who: str) -> int:
    """Say that a run stopped early and where its outputs are; the exit
    code: 128 + the signal, else 1."""
    reached = run.metrics.get("t_reached_s", float(run.t[-1]) if len(run) else None)
    what = (f"partial outputs in {out}/ (metrics.json \"partial\": true, {len(run)} complete rows)"
            if run.partial else f"the run had ended: complete outputs in {out}/")
    print(f"sc-rt {who}: STOPPED at t = {'-' if reached is None else f'{reached:.4g}'} s of "
          f"{run.meta.duration_s:g} s: {why}; {what}", file=sys.stderr)
    return 128 + signum if signum else 1


# --- monitoring and reports (issue 8): spy, lcm-spy, fault, report, replay ---
def bus_url(args: argparse.Namespace) -> str:
    """--lcm-url, else $SCRT_LCM_URL (checked), else LCM's usual port."""
    from sc_rt.wire.lcmio import DEFAULT_URL

    return resolve_url(args.lcm_url, DEFAULT_URL)


def write_mcap(log, out, partial: bool = False, who: str = "export") -> int:
    """Write the MCAP of ``log`` (sc-rt export, report --mcap, hil --mcap)."""
    from sc_rt.export.mcap_export import ExportError, export_mcap

    try:
        s = export_mcap(log, out, partial=partial)
    except ExportError as e:
        print(f"sc-rt {who}: error: {e}", file=sys.stderr)
        return 2
    damaged = (f", damaged log: {s.skipped_bytes} bytes skipped, torn tail {s.torn_tail_bytes} bytes"
               if s.skipped_bytes or s.torn_tail_bytes else "")
    print(f"sc-rt {who}: {log}: {s.events} events -> {out} ({s.messages} messages, derived "
          f"{sum(s.derived.values())}) in {s.seconds:.2f} s ({s.events_per_s or 0:.3g} events/s); "
          f"{s.undecodable} undecodable{' ' + str(s.undecodable_kinds) if s.undecodable else ''} and "
          f"{s.foreign_events} events of foreign "
          f"channels carried raw{damaged}")
    return 0


def mcap_problem(path: str | None, who: str) -> bool:
    """Print why ``--mcap path`` cannot be written (checked before any work)."""
    from sc_rt.export.mcap_export import ExportError, check_output

    try:
        if path:
            check_output(Path(path))
    except ExportError as e:
        print(f"sc-rt {who}: error: {e}", file=sys.stderr)
        return True
    return False
