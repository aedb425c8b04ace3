"""The plan of a run (issue 38): the law resolved to a typed reference and
probed (``law.py``), the timing set-up (``timing.py``), the plan itself, its
record and its replay (``run.py``). Built where a run is asked for (sc_rt.cli,
or ``plan_run`` from Python); everything below takes it."""

from sc_rt.plan.law import BuiltinLaw, ExternalLaw, LawRef, PluginLaw, PythonLaw, probe_law, resolve_law
from sc_rt.plan.run import Bus, Outputs, RunPlan, plan_from_inputs, plan_run
from sc_rt.plan.timing import RealtimeLimits, Timing, TimingSetup

__all__ = ["BuiltinLaw", "ExternalLaw", "LawRef", "PluginLaw", "PythonLaw", "probe_law", "resolve_law",
           "Bus", "Outputs", "RunPlan", "plan_from_inputs", "plan_run", "RealtimeLimits", "Timing", "TimingSetup"]
