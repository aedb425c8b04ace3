"""Every command-line value checked in one place, before anything starts.

- argparse ``type=`` functions for numbers, counts, output paths and LCM
  URLs: a bad value stops the parse with one line naming the option and the
  value (``OneLineParser``), exit code 2, no child process started;
- ``check_run_size``: the rows and the plant steps a run of a scenario will
  take, its memory estimated from the ``Run`` field table (rows x bytes per
  row) against the memory available (a bench run, which writes its rows as
  it runs: its disk use against the space free), and a real-time tick the
  emulator can keep; a run that cannot fit is refused with the numbers
  (``UsageError``);
- ``law_choice`` / ``core_law_choice`` for ``--law``: a law of the core's
  table (sc_rt.scenario.lawspec.LAWS), a C++ plugin ``plugin:PATH_OR_NAME``
  (loaded now) or a Python law ``module:Class`` / ``file.py:Class``
  (imported now): a law that does not load is refused in one line.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
import tempfile
from pathlib import Path
from typing import Any, Callable

import numpy as np

from sc_rt import _core
from sc_rt.pylaw import is_python_law, load_law
from sc_rt.scenario.model import LAWS, PLUGIN_PREFIX, law_spec

__all__ = ["UsageError", "OneLineParser", "number", "integer", "out_dir", "out_file", "lcm_url", "auth_key_file",
           "resolve_url", "bytes_per_row", "bus_bytes_per_row", "disk_bytes_per_row", "free_disk", "available_memory",
           "check_run_size", "law_choice", "core_law_choice", "LAW_HELP",
           "rounded", "MAX_RATE_HZ", "MAX_TIME_SCALE", "MAX_PLANT_STEPS", "MIN_WALL_TICK_S", "ENGINE_COPIES"]

#: Rates above this are not a control loop any bench here can close (10 us a step).
MAX_RATE_HZ = 1e5
#: A real-time run faster than this is not real time any more.
MAX_TIME_SCALE = 1e4
#: Plant RK4 steps of one run (duration / plant step): ~ hours in the Python engines.
MAX_PLANT_STEPS = 1e9
#: The emulator's real-time tick, in wall-clock seconds, cannot be shorter.
MIN_WALL_TICK_S = 100e-6
#: Copies of a row a run holds at its peak (engine buffers, the Run, the file writer).
ENGINE_COPIES = 3
#: Use at most this fraction of the memory available.
MEMORY_FRACTION = 0.8


class UsageError(Exception):
    """A bad command-line value: one line, exit 2."""


class OneLineParser(argparse.ArgumentParser):
    """An argparse parser whose errors are one line (``PROG: error: ...``)
    and exit with code 2; its subparsers are of the same class."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def _want(lo: float, hi: float, open_lo: bool) -> str:
    lo_s = f"> {lo:g}" if open_lo else f">= {lo:g}"
    return lo_s if not math.isfinite(hi) else f"{lo_s} and <= {hi:g}"


def number(lo: float = 0.0, hi: float = math.inf, *, open_lo: bool = True,
           unit: str = "") -> Callable[[str], float]:
    """type=: a finite number in (lo, hi] (or [lo, hi] without ``open_lo``)."""
    want = _want(lo, hi, open_lo) + (f" {unit}" if unit else "")

    def conv(text: str) -> float:
        try:
            v = float(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(f"{text!r}: must be a number {want}") from None
        if not (math.isfinite(v) and (v > lo if open_lo else v >= lo) and v <= hi):
            raise argparse.ArgumentTypeError(f"{text}: must be a finite number {want}")
        return v

    conv.__name__ = "number"  # argparse names the type in its own messages
    return conv


def integer(lo: int = 1, hi: int | None = None) -> Callable[[str], int]:
    """type=: an integer in [lo, hi]."""
    want = f">= {lo}" if hi is None else f"in {lo}..{hi}"

    def conv(text: str) -> int:
        try:
            v = int(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(f"{text!r}: must be an integer {want}") from None
        if v < lo or (hi is not None and v > hi):
            raise argparse.ArgumentTypeError(f"{text}: must be an integer {want}")
        return v

    conv.__name__ = "integer"
    return conv


def out_dir(text: str) -> str:
    """type=: a directory a run can write into (existing or creatable)."""
    from sc_rt.results.present.output import check_out_dir

    problem = check_out_dir(Path(text), "")
    if problem:
        raise argparse.ArgumentTypeError(problem.strip())
    return text


def out_file(text: str) -> str:
    """type=: a file that can be written (not a directory; its folder exists
    or can be created and is writable)."""
    from sc_rt.results.present.output import check_out_dir

    p = Path(text)
    if p.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: is a directory")
    problem = check_out_dir(p.parent if str(p.parent) else Path("."), "")
    if problem:
        raise argparse.ArgumentTypeError(f"{text}: {problem.strip()}")
    return text


_UDPM_RE = re.compile(r"^udpm://(\d{1,3})\.(\d{1,3})\.(\d{1,3})\.(\d{1,3}):(\d{1,5})(\?(.*))?$")
_PROVIDERS = ("udpm", "tcpq", "memq", "file", "udp", "mpudpm")


def url_problem(url: str) -> str:
    """Why ``url`` is not an LCM URL sc-rt can use ("" when it is)."""
    scheme = url.split("://", 1)[0] if "://" in url else ""
    if scheme not in _PROVIDERS:
        return f"{url}: not an LCM URL (PROVIDER://ADDRESS, e.g. udpm://239.255.76.67:7667?ttl=0)"
    if scheme != "udpm":
        return ""
    m = _UDPM_RE.match(url)
    if not m:
        return f"{url}: must be udpm://A.B.C.D:PORT[?ttl=N]"
    octets = [int(m.group(i)) for i in range(1, 5)]
    if not (224 <= octets[0] <= 239 and all(o <= 255 for o in octets)):
        return f"{url}: {'.'.join(m.group(i) for i in range(1, 5))} is not a multicast group (224.0.0.0/4)"
    if not 1 <= int(m.group(5)) <= 65535:
        return f"{url}: port must be 1..65535"
    for opt in filter(None, (m.group(7) or "").split("&")):
        key, _, val = opt.partition("=")
        if key == "ttl" and not (val.isdigit() and 0 <= int(val) <= 255):
            return f"{url}: ttl must be 0..255"
    return ""


def lcm_url(text: str) -> str:
    """type=: an LCM URL."""
    problem = url_problem(text)
    if problem:
        raise argparse.ArgumentTypeError(problem)
    return text


#: --auth-key's help (every bus command has it)
AUTH_KEY_HELP = ("authenticate every message with HMAC-SHA256 under the key in FILE (give the same file "
                 "to every process of the bench; docs/PROTOCOL.md, 'Authentication'); default: none")


def auth_key_file(text: str) -> str:
    """type=: a readable, non-empty key file (its path: sc-rt hil passes it on)."""
    from pathlib import Path

    try:
        size = Path(text).stat().st_size
        with open(text, "rb"):
            pass
    except OSError as e:
        raise argparse.ArgumentTypeError(f"{text}: cannot read the key: {e.strerror}") from e
    if size == 0:
        raise argparse.ArgumentTypeError(f"{text}: the key file is empty")
    return text


def resolve_url(given: str | None, fallback: str | None) -> str | None:
    """The URL a command uses: ``--lcm-url``, else $SCRT_LCM_URL (checked),
    else ``fallback`` (None: the command picks a free port)."""
    if given:
        return given
    env = os.environ.get("SCRT_LCM_URL")
    if env:
        problem = url_problem(env)
        if problem:
            raise UsageError(f"SCRT_LCM_URL={problem}")
        return env
    return fallback


def bytes_per_row() -> int:
    """Bytes of one row of a run, from the field table (sc_rt.results.record.run.FIELDS)."""
    from sc_rt.results.record.run import FIELDS

    return int(sum(int(np.prod(f.shape, dtype=np.int64)) * np.dtype(f.dtype).itemsize for f in FIELDS))


def bus_bytes_per_row() -> int:
    """What a bench run holds per row besides the Run, all of it allocated
    and touched when the emulator is made: each state's command and status
    as received, its times, the loop's stamps (sc_rt.emulator.process
    BYTES_PER_ROW: a wheel_cmd_t and a controller_status_t plus 76 B, so it
    follows the message types)."""
    from sc_rt.emulator.process import BYTES_PER_ROW

    return BYTES_PER_ROW


def available_memory() -> int:
    """Bytes of memory available now (/proc/meminfo MemAvailable, else the
    free physical pages)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError):  # pragma: no cover
        return 1 << 62


def _size(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if abs(n) < 1000 or unit == "PB":
            return f"{n:.3g} {unit}"
        n /= 1000.0
    return f"{n:.3g} PB"  # pragma: no cover


def disk_bytes_per_row() -> int:
    """What a bench run writes per row at most: the emulator's record
    (the run's fields and ``bus_bytes_per_row``, until it is read back) and
    trajectory.arrow (the run's fields), both before their LZ4 compression,
    and the LCM log (one state, truth, guidance, command and status, each
    with its event header and channel name)."""
    import sc_rt_lcm

    msgs = (sc_rt_lcm.plant_state_t, sc_rt_lcm.plant_truth_t, sc_rt_lcm.guidance_t, sc_rt_lcm.wheel_cmd_t,
            sc_rt_lcm.controller_status_t)
    log = sum(len(m().encode()) + 20 + 20 for m in msgs)  # header 20 B, a channel name (and prefix) <= 20 B
    return 2 * bytes_per_row() + bus_bytes_per_row() + log


def free_disk(path: Path) -> int:
    """Bytes free on the file system of ``path`` (or of its nearest existing parent)."""
    import shutil

    p = Path(path).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return shutil.disk_usage(p).free


def check_run_size(scn: Any, given: str, *, bus: bool = False, realtime: bool = False,
                   time_scale: float = 1.0, copies: int = 1, out: Path | None = None,
                   on_disk: bool = False) -> None:
    """Refuse (UsageError) a run of ``scn`` (overrides applied) that cannot
    fit in memory or time. ``given``: the options that set its size, as the
    user typed them (for the message); ``bus``: a bench run, which writes
    its rows as it runs: its disk use (``disk_bytes_per_row``) against the
    space free in ``out`` (None: the temporary directory) instead of its
    memory; ``on_disk``: an offline run written to disk as it runs (the cpp
    engine, sc_rt.sim.engines): its trajectory.arrow against the space free;
    ``copies``: runs held at once (Monte Carlo workers)."""
    run = scn.run
    rows = math.floor(run.duration * run.control_rate_hz + 0.5) + 1
    steps = run.duration / run.plant_step
    what = f"{given}: " if given else ""
    if steps > MAX_PLANT_STEPS:
        raise UsageError(f"{what}{steps:.3g} plant steps (duration {run.duration:g} s / plant step "
                         f"{run.plant_step:g} s), more than the {MAX_PLANT_STEPS:.0e} a run may take")
    if bus or on_disk:  # the rows go to disk as the run goes (results/record/store.py): a disk estimate
        where = Path(out) if out is not None else Path(tempfile.gettempdir())
        per_disk = disk_bytes_per_row() if bus else bytes_per_row()
        need = float(rows) * per_disk
        have = free_disk(where)
        if need > have:
            raise UsageError(f"{what}{rows:.6g} rows ({run.duration:g} s at {run.control_rate_hz:g} Hz) x "
                             f"{_size(per_disk)} per row on disk at most ("
                             + ("the record, trajectory.arrow, the LCM log" if bus else "trajectory.arrow")
                             + f") = {_size(need)}, more than the {_size(have)} free in {where}")
        need = have = 0.0
    else:
        per_row = bytes_per_row() * ENGINE_COPIES
        need = float(rows) * per_row * copies
        have = available_memory()
    if need > MEMORY_FRACTION * have:
        raise UsageError(f"{what}{rows:.6g} rows ({run.duration:g} s at {run.control_rate_hz:g} Hz) x "
                         f"{_size(per_row)} per row"
                         + (f" x {copies} runs" if copies > 1 else "")
                         + f" = {_size(need)}, more than the {_size(have)} of memory available")
    if realtime:
        tick = 1.0 / (run.control_rate_hz * time_scale)
        if tick < MIN_WALL_TICK_S:
            raise UsageError(f"{what}a real-time tick every {tick * 1e6:.3g} us of wall clock "
                             f"(rate {run.control_rate_hz:g} Hz x time scale {time_scale:g}); the "
                             f"emulator cannot tick faster than every {MIN_WALL_TICK_S * 1e6:g} us")


def given_options(args: argparse.Namespace, **names: str) -> str:
    """``--control-rate 1e9 --duration 1``: the size options the user gave."""
    parts = [f"{opt} {getattr(args, attr):g}" for attr, opt in names.items()
             if getattr(args, attr, None) is not None]
    return " ".join(parts) or "the scenario's run"


def rounded(obj: Any, digits: int = 4) -> Any:
    """Floats to ``digits`` significant digits, recursively (CLI output)."""
    if isinstance(obj, float):
        return float(f"{obj:.{digits}g}") if math.isfinite(obj) else obj
    if isinstance(obj, dict):
        return {k: rounded(v, digits) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [rounded(v, digits) for v in obj]
    return obj


def warn(who: str, message: str) -> None:
    print(f"sc-rt {who}: {message}", file=sys.stderr)


LAW_HELP = (f"control law: {', '.join(LAWS)} (default: the scenario's), a C++ law plugin "
            "plugin:PATH_OR_NAME, or a Python law module:Class or path/file.py:Class (docs/LAWS.md)")


def plugin_choice(value: str) -> str:
    """A C++ law plugin ``plugin:PATH_OR_NAME``, loaded now (a relative path
    against the working directory): its problem in one line (exit 2)."""
    spec = law_spec(value, Path.cwd())
    try:
        _core.load_law_plugin(spec[len(PLUGIN_PREFIX):])
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from e
    return spec


def law_choice(value: str) -> str:
    if value in LAWS:
        return value
    if value.startswith(PLUGIN_PREFIX):
        return plugin_choice(value)
    if is_python_law(value):
        if os.getcwd() not in sys.path and "" not in sys.path:
            sys.path.insert(0, os.getcwd())  # module:Class from the working directory, as python -m does
        try:
            load_law(value)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e).removeprefix(f"--law {value!r}: ")) from e
        return law_spec(value, Path.cwd())  # python:..., a file made absolute (a worker's cwd may differ)
    raise argparse.ArgumentTypeError(f"{value!r} is not one of {', '.join(LAWS)} "
                                     "nor a Python law module:Class")


def law_arg(value: str) -> str:
    """``--law`` of a command that plans its run (``sim``, ``hil``): the spec
    as given, not parsed nor loaded here (the plan resolves and probes it
    once, sc_rt.plan.law); a ``module:Class`` imports from the working
    directory, as ``python -m`` does."""
    if os.getcwd() not in sys.path and "" not in sys.path:
        sys.path.insert(0, os.getcwd())
    return value


def core_law_choice(value: str) -> str:
    """Only a law of the core (commands that run the C++ controller)."""
    if value in LAWS:
        return value
    if value.startswith(PLUGIN_PREFIX):
        return plugin_choice(value)
    raise argparse.ArgumentTypeError(f"invalid choice: {value!r} (choose from {', '.join(LAWS)} "
                                     "or plugin:PATH_OR_NAME)")
