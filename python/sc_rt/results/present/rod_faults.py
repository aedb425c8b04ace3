"""The magnetorquer rods' faults of a run, as the report's timeline and the
magnetic figure draw them (issue 43 item 8): the scenario's scheduled ones
(``RunMeta.rod_faults``, ``[[magnetorquers.faults]]``) and the live ones
(``rod_fault_cmd_t`` on SCRT_ROD_FAULT), from either record of them: the
emulator's (``faults_applied`` of timing.json: ``t`` of receipt, ``onset``,
``end`` None for none) or a log's (``sc-rt report``'s
``faults.commands``: ``t_sim_at_receipt``, ``now``, ``t_onset``, ``t_end``
negative for none).

A live command replaces whatever fault its rod had at its receipt, scheduled
or live, and a clear removes it, as the emulator applies them
(emulator/receiver.py ``_apply_rod_fault``): the fault it replaced ends at
the receipt, or never begins when its onset was later. Pure data in, spans
out; every span is named "rod N" (1-based), never a wheel's.

Examples
--------
>>> spans = rod_fault_spans([{"rod": 2, "kind": "stuck", "dipole": 5.0, "onset": 10.0, "end": None}],
...                         [{"t": 4.0, "rod": 2, "action": "inject", "kind": "dead", "dipole": 0.0,
...                           "onset": 4.0, "end": 8.0}])
>>> [s.text() for s in spans]
['rod 2 dead (live, received at 4 s) from 4 s to 8 s']
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

__all__ = ["RodFaultSpan", "RodCommand", "rod_commands", "rod_fault_spans", "live_fault_records", "rod_fault_line"]


@dataclass(frozen=True)
class RodFaultSpan:
    """One rod's fault over ``onset <= t < end``."""

    rod: int  # 1-based
    kind: str  # "dead", "stuck" or "reversed"
    dipole: float  # [A m^2] a stuck rod's dipole (0 for the others)
    onset: float  # [s] simulation time
    end: float | None  # [s] simulation time; None: no end
    source: str  # "scheduled" (the scenario) or "live" (a rod_fault_cmd_t)
    received: float | None = None  # [s] simulation time the live command reached the plant; None: scheduled

    def what(self) -> str:
        """"rod N stuck at X A m^2", "rod N dead", "rod N reversed"."""
        return f"rod {self.rod} {self.kind}" + (f" at {self.dipole:g} A m^2" if self.kind == "stuck" else "")

    def text(self) -> str:
        """What, where from, and when: the timeline's hover text and the verdict's."""
        src = "scheduled" if self.received is None else f"live, received at {self.received:g} s"
        return f"{self.what()} ({src}) from {self.onset:g} s" + ("" if self.end is None else f" to {self.end:g} s")


@dataclass(frozen=True)
class RodCommand:
    """One live rod fault command, as the plant received it."""

    received: float  # [s] simulation time at receipt (0 when the record does not say)
    rod: int  # 1-based
    action: str  # "inject" or "clear"
    kind: str  # an inject's "dead", "stuck" or "reversed"; "" for a clear
    dipole: float  # [A m^2]
    onset: float  # [s] an inject's onset (its receipt for "now")
    end: float | None  # [s] None: no end


def _num(v: Any) -> float | None:
    return None if v is None else float(v)


def rod_commands(records: list[dict[str, Any]] | None) -> list[RodCommand]:
    """The live rod fault commands of ``records`` (the emulator's
    ``faults_applied`` or a log's fault commands), in receipt order; a
    wheel's record (``"wheel"``), a refused one (``"rejected"``) and an
    unknown action are left out."""
    out = []
    for i, r in enumerate(records or ()):
        if r.get("rod") is None or "rejected" in r or r.get("action") not in ("inject", "clear"):
            continue
        if "t_sim_at_receipt" in r or "t_onset" in r:  # a log's command (logs/faults.py fault_summary)
            got = _num(r.get("t_sim_at_receipt"))
            received = 0.0 if got is None else got  # logged before the first state: the run's start
            onset = received if r.get("now") else float(r.get("t_onset", 0.0))
            t_end = _num(r.get("t_end"))
            end = None if t_end is None or t_end < 0 else t_end
        else:  # the emulator's record (emulator/receiver.py): onset resolved, end None for none
            received = float(r.get("t") or 0.0)
            onset, end = float(r.get("onset", received)), _num(r.get("end"))
        inject = r["action"] == "inject"
        out.append((received, i, RodCommand(received=received, rod=int(r["rod"]), action=r["action"],
                                            kind=str(r.get("kind", "")) if inject else "",
                                            dipole=float(r.get("dipole") or 0.0), onset=onset, end=end)))
    return [c for _, _, c in sorted(out, key=lambda x: (x[0], x[1]))]


def rod_fault_spans(scheduled: list[dict[str, Any]] | tuple = (),
                    records: list[dict[str, Any]] | None = None) -> list[RodFaultSpan]:
    """Every rod fault of a run, by rod then onset: the ``scheduled`` ones
    (``RunMeta.rod_faults`` dicts) as the live commands of ``records``
    (``rod_commands``) left them."""
    current: dict[int, RodFaultSpan] = {}
    done: list[RodFaultSpan] = []
    for f in scheduled or ():
        end = _num(f.get("end"))
        current[int(f["rod"])] = RodFaultSpan(
            rod=int(f["rod"]), kind=str(f["kind"]), dipole=float(f.get("dipole") or 0.0), onset=float(f["onset"]),
            end=None if end is None or math.isinf(end) else end, source="scheduled")
    for c in rod_commands(records):
        old = current.pop(c.rod, None)
        if old is not None and old.onset < c.received:  # it acted until the command replaced it
            done.append(old if old.end is not None and old.end <= c.received else
                        replace(old, end=c.received))
        if c.action == "inject":
            current[c.rod] = RodFaultSpan(rod=c.rod, kind=c.kind, dipole=c.dipole, onset=c.onset, end=c.end,
                                          source="live", received=c.received)
    return sorted(done + list(current.values()), key=lambda s: (s.rod, s.onset))


def live_fault_records(report: dict[str, Any] | None, timing: dict[str, Any] | None) -> list[dict[str, Any]]:
    """The live fault records of a run directory, the wheels' and the rods':
    ``sc-rt report``'s report.json commands (the log's), else timing.json's
    ``faults_applied`` (the emulator's). A log's report has both, the same
    commands (logs/report.py puts them in the run's ``faults_applied``): one
    is taken, so that none is counted twice. Of a log's, a command the
    plant's truth says it did not apply (``applied`` False: refused, another
    emulator's, one that ignores fault commands) is left out."""
    cmds = ((report or {}).get("faults") or {}).get("commands")
    if report is not None and cmds is not None:  # the log's: those the plant's truth did not say it applied left out
        return [c for c in cmds if c.get("applied") is not False]
    return list((timing or {}).get("faults_applied") or [])


def rod_fault_line(spans: list[RodFaultSpan], t_end: float | None = None) -> str:
    """The verdict's line of the rods' faults ("Rod faults: rod 3 stuck at
    5 A m^2 (scheduled) from 20 s; ..."); one after ``t_end`` [s] (the
    run's last time) says so."""
    texts = [s.text() + (" (after the run's end)" if t_end is not None and s.onset > t_end else "") for s in spans]
    return "Rod faults: " + ("; ".join(texts) if texts else "none")
