"""``sc-rt hil --external COMMAND`` / ``--external-wait``: a controller that
is not sc-rt-controller, any process that speaks the protocol
(docs/PROTOCOL.md).

The command line is split like a shell's (``shlex``; no shell runs it) after
its placeholders are replaced: ``{url}``, ``{prefix}``, ``{mode}``,
``{config}`` (the run's controller_config_t file), ``{summary}`` (where the
process may write its controller_summary.json), ``{python}`` (this
interpreter). The same values are in its environment: SCRT_LCM_URL,
SCRT_PREFIX, SCRT_MODE, SCRT_CONFIG, SCRT_SUMMARY. Its stdout and stderr go
to controller_stdout.txt and controller_stderr.txt in the run's directory, read
as they come and capped (hil/procs.py ``Drain``).

The emulator re-sends the first state until the controller answers it (up
to the start timeout), so a process that takes a while to start, or one
started by hand (``--external-wait``), gets the run from its first state.
The run is labelled with the law's name the process announces
(controller_info_t), else "external".
"""

from __future__ import annotations

import dataclasses
import os
import shlex
import subprocess
import sys
from pathlib import Path
from typing import Any

from sc_rt.hil.procs import Drain

__all__ = ["ExternalController", "python_controller_command", "PLACEHOLDERS", "expand",
           "DEFAULT_START_TIMEOUT_S", "DEFAULT_WAIT_TIMEOUT_S"]

#: placeholder -> environment variable holding the same value
PLACEHOLDERS = {"url": "SCRT_LCM_URL", "prefix": "SCRT_PREFIX", "mode": "SCRT_MODE",
                "config": "SCRT_CONFIG", "summary": "SCRT_SUMMARY"}
#: [s] a started process must answer the first state within this
DEFAULT_START_TIMEOUT_S = 30.0
#: [s] a process started by hand (--external-wait)
DEFAULT_WAIT_TIMEOUT_S = 300.0


def expand(command: str, env: dict[str, str]) -> list[str]:
    """The argv of ``command`` with its placeholders replaced (ValueError
    with a one-line reason for a command that does not split)."""
    for key, var in PLACEHOLDERS.items():
        command = command.replace("{" + key + "}", shlex.quote(env[var]))
    command = command.replace("{python}", shlex.quote(sys.executable))
    try:
        argv = shlex.split(command)
    except ValueError as e:
        raise ValueError(f"--external {command!r}: {e}") from e
    if not argv:
        raise ValueError("--external: empty command")
    return argv


def python_controller_command(law: str, realtime_priority: bool = False, trigger: str = "event",
                              cpu: int | None = None) -> str:
    """``sc-rt controller`` running the Python law ``law`` (module:Class),
    told what sc-rt-controller would be: the trigger, the real-time priority
    and the CPU to pin to (it honours them; docs/HIL.md)."""
    cmd = ("{python} -m sc_rt.cli controller --law " + shlex.quote(law) + " --config {config} "
           "--mode {mode} --lcm-url {url} --prefix {prefix} --summary {summary} --trigger " + shlex.quote(trigger))
    return (cmd + (" --realtime-priority" if realtime_priority else "")
            + (f" --cpu {int(cpu)}" if cpu is not None else ""))


class ExternalController:
    """The external controller of one bench run."""

    def __init__(self, command: str | None, wait: bool, start_timeout: float | None, *, url: str,
                 prefix: str, mode: str, out: Path, config: Path, trigger: str | None = None):
        self.wait = wait
        #: the trigger the process was told (a Python law's sc-rt controller); None: not told (--external)
        self.trigger = trigger
        self.out = Path(out)
        self.start_timeout = (start_timeout if start_timeout is not None else
                              DEFAULT_WAIT_TIMEOUT_S if wait else DEFAULT_START_TIMEOUT_S)
        self.env = {"SCRT_LCM_URL": url, "SCRT_PREFIX": prefix, "SCRT_MODE": mode,
                    "SCRT_CONFIG": str(config), "SCRT_SUMMARY": str(self.out / "controller_summary.json")}
        self.argv = None if wait else expand(command or "", self.env)
        self.proc: subprocess.Popen | None = None
        self._drains: list[Drain] = []
        self._err_path = self.out / "controller_stderr.txt"

    def start(self, popen_kwargs: dict[str, Any]) -> subprocess.Popen | None:
        """Start the process (None for --external-wait: a person starts it)."""
        summary = Path(self.env["SCRT_SUMMARY"])
        if summary.exists():
            summary.unlink()  # only the summary this run's controller writes
        if self.wait:
            prefix = self.env["SCRT_PREFIX"]
            print(f"sc-rt hil: waiting up to {self.start_timeout:g} s for a controller on "
                  f"{self.env['SCRT_LCM_URL']}" + (f" (channel prefix {prefix!r})" if prefix else "")
                  + f"; its configuration: {self.env['SCRT_CONFIG']}", file=sys.stderr, flush=True)
            return None
        try:
            self.proc = subprocess.Popen(self.argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                         stdin=subprocess.DEVNULL, env={**os.environ, **self.env}, **popen_kwargs)
        except OSError as err:
            raise RuntimeError(f"--external: cannot start {self.argv[0]!r}: {err.strerror}") from err
        # read as they come into capped files: a chatty process neither blocks nor fills the disk
        self._drains = [Drain(self.proc.stdout, self.out / "controller_stdout.txt"),
                        Drain(self.proc.stderr, self._err_path)]
        return self.proc

    def close_output(self) -> str:
        """After the process has exited: its output read to the end; its stderr."""
        for d in self._drains:
            d.close()
        return self.stderr_text()

    @property
    def command_line(self) -> str:
        """The controller's command line as started ("started by hand" for --external-wait)."""
        import shlex

        return "started by hand" if self.argv is None else shlex.join(self.argv)

    @property
    def stderr_name(self) -> str:
        """The file in the run's folder holding the process's stderr."""
        return self._err_path.name

    def stderr_text(self) -> str:
        return self._err_path.read_text(errors="replace") if self._err_path.exists() else ""

    def check_started(self, res) -> None:
        """A run that ended before its first row: the controller never answered."""
        if len(res) == 0:
            tail = " | ".join(self.stderr_text().strip().splitlines()[-3:])
            raise RuntimeError(f"the controller never answered the first state: {res.message}"
                               + (f"; its stderr: {tail}" if tail else ""))

    @staticmethod
    def label(res, info: dict[str, Any] | None) -> None:
        law = info["law"] if info and info.get("law") else "external"
        res.meta = dataclasses.replace(res.meta, law=law)
