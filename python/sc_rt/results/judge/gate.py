"""What a CI job gates on (docs/REQUIREMENTS.md, "The gate"): a scenario's
``expect`` checked against the run's verdict, and the reasons a run (or a
campaign) fails ``--strict``.

- ``expect_result``: the file's ``expect`` ("holds", "violates" or none)
  against the run's verdict (every requirement judged was met: "holds"; one
  failed: "violates"; none judged: no verdict), into metrics.json
  (``expect``) for every run, whether or not ``--strict`` is given;
- ``gate_problems``: why a run fails the gate: it is invalid (the law
  failed, real time not kept) or diverged, its ``expect`` does not match, or
  a requirement failed. A file that states ``expect = "violates"`` declares
  its failures: they are its expected outcome, and only a mismatch (the run
  holds after all) fails the gate;
- ``campaign_expect``, ``campaign_gate_problems``: the same for
  ``sc-rt montecarlo``, whose verdict is "holds" when every requirement is
  met at the campaign's confidence (sc_rt.studies.campaign.requirements).
"""

from __future__ import annotations

from typing import Any

__all__ = ["EXPECTS", "campaign_expect", "campaign_gate_problems", "expect_line", "expect_result",
           "gate_problems", "run_verdict"]

#: The values of a scenario's ``expect`` key.
EXPECTS = ("holds", "violates")


def run_verdict(reqs: list[dict[str, Any]] | None) -> str | None:
    """"holds" when every requirement judged was met, "violates" when one
    failed, None when none was judged (none stated, all across runs, not
    evaluated or not applicable)."""
    judged = [r for r in reqs or () if r.get("passed") is not None]
    if not judged:
        return None
    return "holds" if all(r["passed"] for r in judged) else "violates"


def _result(expect: str, verdict: str | None, failed: list[str], unjudged: int) -> dict[str, Any]:
    return {"stated": expect or None, "verdict": verdict,
            "matches": None if not expect or verdict is None else verdict == expect,
            "failed": failed, "not_judged": unjudged}


def expect_result(reqs: list[dict[str, Any]] | None, expect: str) -> dict[str, Any]:
    """The run's verdict against the file's ``expect``: stated (None: the file
    states none), verdict (``run_verdict``), matches (None: nothing to
    compare), the requirements that failed and how many were not judged."""
    reqs = list(reqs or ())
    return _result(expect, run_verdict(reqs), [r["name"] for r in reqs if r.get("passed") is False],
                   sum(r.get("passed") is None for r in reqs))


def expect_line(e: dict[str, Any] | None, what: str = "the run") -> str:
    """The expect check in words ("" when the file states none)."""
    if not e or not e.get("stated"):
        return ""
    stated, verdict = e["stated"], e.get("verdict")
    if verdict is None:
        return f'"{stated}": not checked, {what} judged no requirement'
    failed = f" (failed: {', '.join(e['failed'])})" if e.get("failed") else ""
    if e.get("matches"):
        return f'"{stated}": {what} {verdict}{failed}, as the file expects'
    return f'MISMATCH: the file expects "{stated}", {what} {verdict}{failed}'


def gate_problems(metrics: dict[str, Any]) -> list[str]:
    """Why a run's metrics fail ``--strict`` ([] when they pass it): invalid,
    diverged, ``expect`` not matched, requirements failed (unless the file
    expects it to violate them)."""
    out = []
    if metrics.get("valid") is False:
        out.append(f"the run is invalid ({metrics.get('invalid_reason', 'see metrics.json')})")
    if metrics.get("diverged"):
        out.append(f"the run diverged after {metrics.get('diverged_after_s', float('nan')):.4g} s")
    e = metrics.get("expect") or expect_result(metrics.get("requirements"), "")
    if e.get("matches") is False:
        out.append(f'expect = "{e["stated"]}" but the run {e["verdict"]}')
    if e.get("stated") != "violates" and e.get("failed"):
        out.append(f"requirements failed: {', '.join(e['failed'])}")
    return out


def campaign_expect(res: dict[str, Any], expect: str) -> dict[str, Any]:
    """A campaign's verdict against the file's ``expect``: "holds" when every
    requirement is met at the campaign's confidence (per-run ones in the
    coverage of the runs, ensemble and mixed ones at their probability),
    "violates" when one is not shown; None without requirements."""
    reqs = res.get("requirements") or []
    judged = [r for r in reqs if r.get("met_at_confidence") is not None]
    failed = [r["name"] for r in judged if not r["met_at_confidence"]]
    verdict = None if not judged else ("violates" if failed else "holds")
    return _result(expect, verdict, failed, len(reqs) - len(judged))


def campaign_gate_problems(res: dict[str, Any]) -> list[str]:
    """Why a campaign fails ``--strict``: runs that are not valid runs of the
    law (an invalid draw, a law that failed or crashed its process),
    ``expect`` not matched, requirements not shown at the confidence
    (unless the file expects a violation)."""
    out = []
    status = res.get("status") or {}
    bad = {k: int(status.get(k) or 0) for k in ("invalid", "law_failed", "crashed", "hung")}
    if any(bad.values()):
        out.append("runs not valid: " + ", ".join(f"{v} {k}" for k, v in bad.items() if v))
    e = res.get("expect") or campaign_expect(res, "")
    if e.get("matches") is False:
        out.append(f'expect = "{e["stated"]}" but the campaign {e["verdict"]}')
    if e.get("stated") != "violates" and e.get("failed"):
        c = res.get("requirements_confidence")
        at = f" at {100 * c:g} %" if c is not None else ""
        out.append(f"requirements not shown{at}: {', '.join(e['failed'])}")
    return out
