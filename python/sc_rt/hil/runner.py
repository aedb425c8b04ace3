"""``sc-rt hil``: the controller process, the plant emulator and
``lcm-logger`` on real LCM; a timing report and the run's log.

The emulator runs in this process (it is the test bench's clock in
lockstep); the controller (``sc-rt-controller``) and the logger (the real
binary in the lcm wheel) are child processes, stopped cleanly at the end.
"""

from __future__ import annotations

import dataclasses
import json
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sc_rt import __version__, _core
from sc_rt.emulator.process import Emulator, Options
from sc_rt.emulator.sensorpub import SENT_COUNTERS
from sc_rt.hil.bench_end import bench_timing, death_line, judge_real_time, logger_summary
from sc_rt.hil.external import ExternalController, python_controller_command
from sc_rt.hil.floor import TimingSetup, compare_to_floor, floor_for
from sc_rt.hil.procs import (Drain, Stopper, bench_binary, child_kwargs,
                             controller_binary, lift_logger, probe_logger, stop_child, wait_logged)
from sc_rt.logs.timing import RealtimeLimits, log_missing, timing_report
from sc_rt.plan.law import ExternalLaw, PythonLaw
from sc_rt.plan.run import RunPlan
from sc_rt.results.judge.metrics import fill_tracking_errors, finish_run, mark_invalid, record_law_failures
from sc_rt.results.present.output import write_run
from sc_rt.results.record.run import Run, provenance
from sc_rt.scenario.model import Scenario
from sc_rt.wire.auth import load_key, open_bus
from sc_rt.wire.lcmio import channel, free_port_url, open_lcm
from sc_rt.wire.startrec import encode_end, encode_start

__all__ = ["HilResult", "run_hil", "CONTROLLER_START_TIMEOUT_S", "LOCKSTEP_ANSWER_S"]

#: [s] sc-rt-controller says it has subscribed within this, or the run does not start
CONTROLLER_START_TIMEOUT_S = 30.0
#: [s] lockstep: how long the bench waits for the answer to a state (re-sent every second)
#: before the run stops, failed: a controller stopped for less gets its run, bitwise the offline one
LOCKSTEP_ANSWER_S = 10


@dataclass
class HilResult:
    """A bench run: its record (with ``run.metrics`` and ``run.timing``),
    where it was written, and the controller's own exit summary."""

    out: Path
    run: Run
    controller_summary: dict[str, Any]
    files: list[Path]
    #: why the run stopped before its end (a signal, the logger gone); None: it ran to its end
    stopped: str | None = None
    #: the signal that stopped it (exit code 128 + signum)
    signum: int | None = None

    @property
    def metrics(self) -> dict[str, Any]:
        return self.run.metrics

    @property
    def timing(self) -> dict[str, Any]:
        return self.run.timing or {}


def run_hil(plan: RunPlan, *, floor: dict | None = None, record_chunk: int | None = None) -> HilResult:
    """A bench run of ``plan`` (sc_rt.plan: ``plan_run(..., engine="bench")``).
    The controller is sc-rt-controller running the plan's law, a Python law
    run as ``sc-rt controller``, or an external controller (hil/external.py):
    a command line started instead, or one started by hand that speaks the
    protocol (docs/PROTOCOL.md).

    The emulator runs in this process; the controller and ``sc-rt-logger``
    are child processes, stopped at the end (SIGINT/SIGTERM stop the run
    early: it is kept, partial).

    Parameters
    ----------
    plan : RunPlan
        The run, resolved (sc_rt.plan.run): the scenario with its overrides,
        the law, ``timing`` (mode "lockstep": the emulator steps when the
        controller has answered each state, bitwise the offline run;
        "realtime": one tick per control period on the wall clock; the
        priority, the trigger, CPUs and spin, the floor policy, the real-time
        limits, the start timeout, the controller's memory limit),
        ``outputs`` (the run's directory, created: run.lcmlog,
        controller_config.bin, controller_summary.json, the controller's
        stderr and what ``sc_rt.write_run`` writes; the figures) and ``bus``
        (the LCM URL, None: a free port with ttl=0; the channel prefix;
        fault commands; the key file authenticating the bus).
    floor : dict, optional
        A bench floor measured already (hil/floor.py); None: the plan's policy
        (``plan.timing.floor``; None there: no comparison).
    record_chunk : int, optional
        Rows per chunk of the run's record (results/record/store.py; None: its
        CHUNK_ROWS).

    Returns
    -------
    HilResult
        ``.run`` (the record, with ``metrics`` and ``timing``; its meta's
        ``inputs`` are ``plan.inputs()``), ``.out``, ``.files``,
        ``.controller_summary``, and ``.stopped`` / ``.signum`` when it
        stopped before its end.

    Raises
    ------
    ValueError
        An unreadable or empty key file, an external command that does not
        split, a plan that is not the bench's.
    FileNotFoundError
        sc-rt-controller or sc-rt-logger is not installed.
    RuntimeError
        LCM cannot start on the URL, or the logger, sc-rt-controller or the
        external controller did not start or never answered.
    OSError
        The run's files cannot be written.
    """
    if plan.engine != "bench" or plan.outputs.out is None:
        raise ValueError(f"run_hil runs a bench plan with an output directory (engine {plan.engine!r}, "
                         f"out {plan.outputs.out})")
    scn, timing, bus, out = plan.scenario, plan.timing, plan.bus, Path(plan.outputs.out)
    mode, setup, realtime_priority = timing.mode, timing.setup, timing.priority
    python_law = plan.law.spec if isinstance(plan.law, PythonLaw) else None
    external = plan.law.command if isinstance(plan.law, ExternalLaw) else None
    external_wait = isinstance(plan.law, ExternalLaw) and plan.law.command is None
    if python_law is not None:  # run by sc-rt controller, with the config of its own table, told as sc-rt-controller
        external = python_controller_command(python_law, realtime_priority, setup.trigger, setup.controller_cpu)
    if floor is None and timing.floor is not None:  # the floor's own short run first, before this run's children
        floor = floor_for(scn, run=run_hil, mode=mode, control_rate_hz=None, realtime_priority=realtime_priority,
                          setup=setup, policy=timing.floor)

    url = bus.lcm_url or free_port_url(ttl=0)
    auth_key = bus.auth_key
    key = load_key(auth_key)  # --auth-key: read (and refused when empty) before anything starts
    # everything that can fail before a child starts: the URL, both binaries, the directory
    open_lcm(url)
    ctl_bin = None if external or external_wait else controller_binary()
    logger_bin = bench_binary("sc-rt-logger")  # lcm-logger's format, a deep queue (cpp/tools/sc_rt_logger.cpp)
    out.mkdir(parents=True, exist_ok=True)
    cfg_path = out / "controller_config.bin"
    cfg_path.write_bytes(scn.controller_config_msg().encode())
    log_path = out / "run.lcmlog"
    if log_path.exists():
        log_path.unlink()
    ext = ExternalController(external, external_wait, timing.start_timeout, url=url, prefix=bus.prefix,
                             mode=mode, out=out, config=cfg_path, trigger=setup.trigger if python_law else None
                             ) if external or external_wait else None
    if ext is not None and auth_key is not None:
        ext.env["SCRT_AUTH_KEY"] = str(Path(auth_key).resolve())  # sc-rt controller reads it
    names = () if (external or external_wait) and python_law is None else _telemetry_names(scn)
    bench = _Bench(scn=scn, out=out, url=url, mode=mode, prefix=bus.prefix, realtime_priority=realtime_priority,
                   time_scale=timing.time_scale, accept_fault_commands=bus.accept_fault_commands,
                   plots=plan.outputs.plots, ctl_bin=ctl_bin, logger_bin=logger_bin, cfg_path=cfg_path,
                   log_path=log_path, ext=ext, key=key, key_path=auth_key, setup=setup, floor=floor,
                   rt_limits=timing.rt_limits, record_chunk=record_chunk, telemetry_names=names,
                   inputs=plan.inputs())
    with Stopper(memory_limit_mb=timing.controller_memory_limit_mb) as stopper:
        return _run_children(bench, stopper)


@dataclass(frozen=True)
class _Bench:
    """One bench run as settled before any child starts (run_hil)."""

    scn: Scenario
    out: Path
    url: str
    mode: str
    prefix: str
    realtime_priority: bool
    time_scale: float
    accept_fault_commands: bool
    plots: bool
    #: sc-rt-controller (None: an external controller, ``ext``)
    ctl_bin: str | None
    logger_bin: str
    cfg_path: Path
    log_path: Path
    ext: ExternalController | None
    #: the bus key (wire/auth.py) and its file (passed on to the controller)
    key: bytes | None
    key_path: str | Path | None
    setup: TimingSetup
    floor: dict | None
    rt_limits: RealtimeLimits = RealtimeLimits()
    record_chunk: int | None = None
    #: the law's telemetry names (the run's telemetry columns), () when the bench does not know the law
    telemetry_names: tuple[str, ...] = ()
    #: the plan as the run records it (RunPlan.inputs)
    inputs: dict | None = None


def _telemetry_names(scn: Scenario) -> tuple[str, ...]:
    """The telemetry names of the law the controller runs, from the law
    constructed once with the run's configuration in a child of its own (a
    plugin's native code). () when it cannot be constructed (the controller
    then refuses the configuration itself)."""
    from sc_rt.isolate import ChildDied, call_in_child, probe_timeout

    cfg = scn.core_config()
    try:
        return tuple(call_in_child(lambda: list(_core.Controller(cfg).telemetry_names), timeout=probe_timeout()))
    except (ChildDied, ValueError, RuntimeError):
        return ()


def _start_record(b: _Bench) -> bytes:
    """The run's start record, the log's first message (SCRT_HIL_START): what
    the run is, so that every consumer of the log reads it instead of
    guessing: scenario, mode, trigger, rate, the law's identity (name, spec,
    a plugin's file and SHA-256; an external controller's command), run id,
    and the scenario's requirements (what ``sc-rt report`` judges the log by)."""
    from sc_rt.results.present.output import claimed_run_id
    from sc_rt.scenario.model import law_identity

    law = ({"name": "external", "spec": b.ext.command_line, "source": "external"} if b.ext is not None
           else law_identity(b.scn.run.controller))
    rec = {"scenario": b.scn.name, "mode": b.mode,
           # the setup's trigger, which the controller was told (sc-rt-controller, a Python law's sc-rt
           # controller); an --external process is not told: its own, unknown here
           "trigger": b.setup.trigger if b.mode == "realtime" and (b.ext is None or b.ext.trigger) else None,
           "control_rate_hz": float(b.scn.run.control_rate_hz), "duration_s": float(b.scn.run.duration),
           "time_scale": b.time_scale, "law": law, "run_id": claimed_run_id(b.out), "sc_rt": __version__,
           "requirements": [dataclasses.asdict(r) for r in b.scn.requirements], "expect": b.scn.expect,
           "telemetry_names": list(b.telemetry_names),
           # what "kept real time" meant for this run: sc-rt report LOG judges the log by it
           "rt_limits": dataclasses.asdict(b.rt_limits),
           # what the run was made from (RunPlan.inputs): sc-rt report LOG traces the log to it
           "inputs": b.inputs}
    return encode_start(rec)


def _end_record(scn, res, stopper: Stopper) -> bytes:
    """The end marker's payload (wire/startrec.py): what the bench saw that
    no message shows, for ``sc-rt report`` to give the live run's reasons."""
    rec: dict = {"scenario": scn.name, "died": stopper.died}  # (died: None while the controller lived)
    if res is not None:
        rec.update(rows=len(res), partial=bool(res.partial), stopped=res.message if res.partial else None)
    return encode_end(rec)


def _run_children(b: _Bench, stopper: Stopper) -> HilResult:
    scn, out, url, mode, prefix = b.scn, b.out, b.url, b.mode, b.prefix
    realtime_priority, setup, floor, ext, key = b.realtime_priority, b.setup, b.floor, b.ext, b.key
    ctl_bin, logger_bin, cfg_path, log_path, key_path = b.ctl_bin, b.logger_bin, b.cfg_path, b.log_path, b.key_path
    # it says how many of our states it has written: lockstep never runs ahead of it (emulator/logpace.py)
    logger = subprocess.Popen([logger_bin, "--flush-interval=20", "--lcm-url", url,
                               "--ack-channel", channel("SCRT_LOG_ACK", prefix),
                               "--count-channel", channel("SCRT_STATE", prefix), str(log_path)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, **child_kwargs())
    stopper.logger = logger
    # a non-empty log means the logger is listening: publish a marker until it
    # shows up (SCRT_HIL_START carries the scenario name; readers skip it)
    print(f"sc-rt hil: LCM URL {url}" + (f", channel prefix {prefix!r}" if prefix else ""),
          file=sys.stderr, flush=True)
    if not probe_logger(url, log_path, _start_record(b), 5.0, prefix + "SCRT_HIL_START"):
        stop_child(logger, signal.SIGINT)
        raise RuntimeError(f"lcm-logger did not start on {url}: {logger.stderr.read().decode()}")
    logger_policy = lift_logger(logger.pid)  # now that it runs: all its threads exist
    # the run's controller_config_t goes into the log (sc-rt report takes the law,
    # the rate and the PPC envelope from it); the controller reads its file and
    # listens to SCRT_CONFIG only with --config-channel
    open_bus(url, key).publish(channel("SCRT_CONFIG", prefix), cfg_path.read_bytes())

    cmd = [ctl_bin, "--config", str(cfg_path), "--mode", mode, "--lcm-url", url,
           "--summary", str(out / "controller_summary.json")]
    if prefix:
        cmd += ["--prefix", prefix]
    if realtime_priority:
        cmd.append("--realtime-priority")
    if key_path is not None:
        cmd += ["--auth-key", str(key_path)]
    cmd += setup.controller_args()  # --trigger, --cpu, --null-law
    res = None
    try:
        ctl = (ext.start(child_kwargs()) if ext else
               subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, **child_kwargs()))
    except BaseException:
        stop_child(logger, signal.SIGINT)
        raise
    # its stderr read as it comes (a law that writes there never blocks its controller), capped
    drain = Drain(ctl.stderr, out / "controller_stderr.txt", watch=b"mode on") if ext is None else None
    stopper.controller = ctl
    stopper.controller_name = "the external controller" if ext else "sc-rt-controller"
    try:
        if drain is not None:
            # the controller says on stderr when it has subscribed
            if not drain.wait_for(CONTROLLER_START_TIMEOUT_S):
                if ctl.poll() is None:
                    stop_child(ctl, signal.SIGKILL)
                raise RuntimeError(f"sc-rt-controller did not start within {CONTROLLER_START_TIMEOUT_S:g} s: "
                                   + (" | ".join(drain.close().strip().splitlines()[-3:]) or "it said nothing")
                                   + " (controller_stderr.txt)")
        emu = Emulator(scn, Options(mode=mode, url=url, prefix=prefix, time_scale=b.time_scale,
                                    accept_fault_commands=b.accept_fault_commands,
                                    start_timeout=ext.start_timeout if ext else None, auth_key=key,
                                    spin_us=setup.spin_us, cpu=setup.emulator_cpu,
                                    realtime_priority=realtime_priority, record_dir=out,
                                    record_chunk=b.record_chunk, log_paced=True,
                                    retries=LOCKSTEP_ANSWER_S - 1, stop_unanswered=True),
                       stop=stopper)
        t0 = time.perf_counter()
        res = emu.run()
        wall = time.perf_counter() - t0 - emu.start_wait_s  # the run, not the wait for its controller
        if ext is not None and stopper.signum is None:
            ext.check_started(res)
    finally:
        if ctl is not None:
            stop_child(ctl, signal.SIGTERM)
        ctl_err = ext.close_output() if ext else drain.close()
        log_complete = wait_logged(url, log_path, logger, prefix + "SCRT_HIL_END", _end_record(scn, res, stopper))
        logger_rc = stop_child(logger, signal.SIGINT)
    logger_err = logger.stderr.read().decode(errors="replace").strip() if logger.stderr else ""
    if stopper.died is not None and res.partial and res.message == stopper.died:
        res.message = death_line(res, stopper.died, ext)
        res.metrics["stopped"] = res.message
        mark_invalid(res, res.message)
    stopped = res.message if res.partial else None
    if not res.partial and logger_rc not in (0, -signal.SIGINT):
        # the logger failed at the very end (its last flush): the log may be short of the run
        stopped = f"sc-rt-logger exited with code {logger_rc} at the end of the run"
        res.partial = True
        res.metrics.update(stopped=stopped, t_reached_s=emu.t_reached if len(res) else None)
    if stopped and logger_err and logger_rc not in (0, -signal.SIGINT):
        stopped += f" (sc-rt-logger: {logger_err.splitlines()[-1]})"
        res.metrics["stopped"] = stopped
    summary_path = out / "controller_summary.json"
    try:  # (empty when the controller could not write it: a full disk)
        summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
    except ValueError:
        summary = {}
    if not ctl_err.strip() and ext is None and "controller_stderr.txt" not in (res.message or ""):
        (out / "controller_stderr.txt").unlink(missing_ok=True)  # nothing said, nothing named it: no file
    if stopper.controller_peak_mb is not None:
        res.metrics["controller_peak_rss_mb"] = round(stopper.controller_peak_mb, 1)
    if ext is not None:
        ext.label(res, emu.controller_info)  # the law's name from its controller_info_t
    # a controller that followed another plant than ours (it adopted another
    # bench's states before ours, docs/HIL.md "Bench isolation"): invalid
    others = [s for s in summary.get("plant_sessions", []) if s != emu.session]
    if others:
        why = (
            f"bench collision on {url}" + (f" (prefix {prefix!r})" if prefix else "")
            + f": the controller (session {res.metrics.get('controller_session') or 0:#x}) also followed "
            f"another plant (session {others[0]:#x}) besides this bench's ({emu.session:#x}): another bench "
            "runs on the same URL and prefix. The run is invalid")
        if emu.invalid is None:  # the emulator heard no collision itself: this is the run's reason
            if stopped:  # and what stopped it early (a state the busy controller left unanswered) follows
                why = f"{why}; this bench stopped: {stopped}"
            res.metrics.update(provenance(emu.session, res.metrics.get("controller_session"), why))
            stopped = why

    res.meta = dataclasses.replace(res.meta, wall_s=wall, telemetry_names=b.telemetry_names,
                                   **({"inputs": b.inputs} if b.inputs is not None else {}))
    guidance = scn.core_config().guidance
    fill_tracking_errors(res, guidance)
    finish_run(res, guidance)  # the guidance: with sensors, the true rate error
    record_law_failures(res, summary.get("law_failures"))  # the controller's summary: counted, named, invalid
    res.timing = timing_report(res, summary, wall)
    # the end marker reached the log: every message published before it is there too
    res.timing["log_complete"] = bool(log_complete)
    res.timing["logger_scheduler"] = logger_policy
    res.timing["log_missing"] = log_missing(log_path, prefix, len(res),
                                            {c: int(res.counters.get(k, 0))
                                             for c, k in {**SENT_COUNTERS, "SCRT_MAG": "mag_sent"}.items()})
    res.timing["logger"] = logger_summary(logger_err)
    # a command (wheels or rods) not the controller's reached the bus
    if (conflicts := int(res.counters.get("cmd_conflict", 0)) + int(res.counters.get("rod_conflict", 0))):
        why = (f"{conflicts} commands carried the controller's session and seq but not its command: a forged or "
               "racing sender on the bus (docs/PROTOCOL.md, 'Sequence numbers'; --auth-key refuses them)")
        mark_invalid(res, why)
        print(f"sc-rt hil: {why}", file=sys.stderr)
    if any(res.timing["log_missing"].values()):  # the log is the run's evidence: a lost message fails it
        lost = {c: n for c, n in res.timing["log_missing"].items() if n}
        why = (f"the log lost {sum(lost.values())} messages of this run ({lost}; the logger runs "
               f"{logger_policy}; docs/HIL.md, 'A complete log')")
        mark_invalid(res, why)
        print(f"sc-rt hil: {why}", file=sys.stderr)
    res.timing.update(bench_timing(res, summary, emu, setup, told=ext is None or ext.trigger is not None))
    if floor:
        res.timing["floor"] = floor
        res.timing["over_floor"] = compare_to_floor(res.timing, floor)
    judge_real_time(res, summary, b.rt_limits)
    try:
        files = write_run(res, out, figures=b.plots and len(res) > 1)  # (no figure of a run stopped at once)
    except OSError as e:  # a full disk: say where, and why the run had stopped
        raise OSError(e.errno, e.strerror + (f" (the run had stopped: {stopped})" if stopped else ""),
                      str(e.filename or out)) from e
    files += [p for p in (log_path, cfg_path, summary_path, out / "controller_stderr.txt",
                          out / "controller_stdout.txt") if p.exists()]
    return HilResult(out, res, summary, files, stopped, stopper.signum)


