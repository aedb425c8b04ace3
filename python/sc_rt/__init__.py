"""sc-rt: real-time attitude-control emulator for a combined spacecraft with
four reaction wheels, some of them faulty.

The control laws live in the C++ core (``sc_rt._core``); this package holds
the plant, the scenario files, the offline simulator, the LCM emulator and
the command line (``sc-rt``). The Python API (docs/API.md)::

    import sc_rt
    scn = sc_rt.load_scenario("paper_faults")       # a shipped name or a path
    run = sc_rt.simulate(scn, law="pd", engine="cpp")
    print(sc_rt.verdict_line(run.metrics))
    run["sigma_BD"]                                 # (rows, 3) array, see sc_rt.FIELDS
    plan = sc_rt.plan_run("paper_faults", law="pd", engine="bench",   # a run's plan: law resolved
                          outputs=sc_rt.Outputs(out=pathlib.Path("out/pd")))  # and probed once
    res = sc_rt.run_hil(plan)                                          # the bench runs the plan

Layers (imports run one way, checked by tests/test_layers.py): ``model``
(plant, wheels) | ``wire`` (LCM transport and codecs) | ``pylaw`` (Python
laws into the core's registry) -> ``scenario`` -> ``results`` (the Run
record, metrics, figures) -> ``plan`` (a run's plan: the law resolved and
probed, the timing, outputs and bus) -> ``sim``
(offline engines) | ``emulator`` (the plant process) | ``controller`` (the
Python controller process) | ``logs`` (log reading, report) | ``tools``
(spy, lcm-spy, fault) -> ``export`` (MCAP) -> ``hil`` (orchestration) ->
``studies`` (design, reproduce, Monte Carlo) -> ``cli``.
"""

import os
from importlib.metadata import PackageNotFoundError, version

# sc-rt's matrices are 3x3 and 3x4: BLAS worker threads never help, and their
# busy-waiting after a numpy call steals a core from the control loop on a
# 2-core bench. Takes effect when sc_rt is imported before numpy (the CLI);
# a user's own setting wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

try:
    __version__ = version("sc-rt")
except PackageNotFoundError:  # running from a source tree without install
    __version__ = "0+unknown"

#: The public Python API: name -> (module, attribute). Imported on first use,
#: so that ``import sc_rt`` stays cheap (the CLI imports only what it runs).
_API = {
    "load_scenario": ("sc_rt.scenario.reader", "load_scenario"),
    "Scenario": ("sc_rt.scenario.model", "Scenario"),
    "ScenarioError": ("sc_rt.scenario.schema", "ScenarioError"),
    "with_overrides": ("sc_rt.scenario.overrides", "with_overrides"),
    "shipped_scenarios": ("sc_rt.scenario.shipped", "shipped"),
    "simulate": ("sc_rt.sim.engines", "simulate"),
    "Run": ("sc_rt.results.record.run", "Run"),
    "RunMeta": ("sc_rt.results.record.run", "RunMeta"),
    "FIELDS": ("sc_rt.results.record.run", "FIELDS"),
    "write_run": ("sc_rt.results.present.output", "write_run"),
    "verdict_line": ("sc_rt.results.judge.verdict", "verdict_line"),
    "run_hil": ("sc_rt.hil.runner", "run_hil"),
    "plan_run": ("sc_rt.plan.run", "plan_run"),
    "RunPlan": ("sc_rt.plan.run", "RunPlan"),
    "Outputs": ("sc_rt.plan.run", "Outputs"),
    "Bus": ("sc_rt.plan.run", "Bus"),
    "Timing": ("sc_rt.plan.timing", "Timing"),
    "design": ("sc_rt.studies.design", "design_report"),
    "montecarlo": ("sc_rt.studies.montecarlo", "run_montecarlo"),
}

__all__ = ["__version__", *_API]


def __getattr__(name: str):
    try:
        module, attr = _API[name]
    except KeyError:
        raise AttributeError(f"module 'sc_rt' has no attribute {name!r}") from None
    import importlib

    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))
