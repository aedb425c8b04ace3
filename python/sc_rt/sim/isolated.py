"""A run in a child process of its own, for laws that run in-process and
can crash the process (a law plugin: native code the bench does not own).

``simulate_isolated`` runs ``sc_rt.sim.engines.simulate`` in a forked child
(sc_rt.isolate) and returns its Run; a child that dies (a signal such as
SIGSEGV, an abort, an exit) raises ``RunCrashed`` with one line naming the
law and how it died, and the caller goes on: ``sc-rt sim`` reports it in
one line (exit 1), a Monte Carlo campaign records that run as crashed and
runs the rest (docs/HIL.md, "When a run is valid"). A law that never
returns (no step for sc_rt.isolate.stall_timeout() seconds) is killed and
reported the same way.
"""

from __future__ import annotations

from typing import Any

from sc_rt.isolate import ChildDied, ChildInterrupted, ChildStalled, call_in_child, stall_timeout

__all__ = ["RunCrashed", "RunHung", "simulate_isolated", "simulate_plan"]


class RunCrashed(RuntimeError):
    """The process running a law died (one line: the law and how)."""


class RunHung(RunCrashed):
    """The law returned no step for the stall timeout: its process was
    killed (one line: the law and the last time it reached)."""


def _simulate_handed_over(scn, **kwargs: Any):
    """In the child: the run, and the temporary directory of its rows (a run
    longer than two chunks is on disk) handed over to the parent, so that
    the child does not remove it when its copy of the run goes."""
    from sc_rt.results.record.store import hand_over
    from sc_rt.sim.engines import simulate

    run = simulate(scn, **kwargs)
    return run, hand_over(run)


def simulate_isolated(scn, **kwargs: Any):
    """``simulate(scn, **kwargs)`` in a forked child; the Run, or RunCrashed."""
    from sc_rt.results.record.store import remove_with

    try:
        run, scratch = call_in_child(_simulate_handed_over, scn, stall=stall_timeout(), **kwargs)
        if scratch is not None:  # this process removes it now, with its copy of the run
            remove_with(run, scratch)
        return run
    except ChildInterrupted as e:
        raise RunCrashed(f"interrupted; the law's run {e}; nothing of the run was kept") from None
    except ChildStalled as e:  # a law that never returns
        law = kwargs.get("law") or scn.run.controller
        raise RunHung(f"the law {law} hung: {e.how}; nothing of the run was kept") from None
    except ChildDied as e:
        law = kwargs.get("law") or scn.run.controller
        raise RunCrashed(f"the law {law} ended the run's process ({e.how}): nothing of the run was kept") from None


def simulate_plan(plan: Any):
    """The offline run of ``plan`` (sc_rt.plan.run.RunPlan, an offline
    engine): its scenario (overrides applied, law resolved) on its engine,
    in a child of its own when its law is a plugin or a Python law
    (RunCrashed when the child dies); rows beyond two chunks of a "cpp" run
    go to ``plan.outputs.out``. The run's meta records the plan
    (``RunMeta.inputs`` = ``plan.inputs()``)."""
    import dataclasses

    kwargs = dict(engine=plan.engine, record_dir=plan.outputs.out)
    if plan.law.kind in ("plugin", "python"):
        run = simulate_isolated(plan.scenario, **kwargs)
    else:
        from sc_rt.sim.engines import simulate

        run = simulate(plan.scenario, **kwargs)
    run.meta = dataclasses.replace(run.meta, inputs=plan.inputs())
    return run
