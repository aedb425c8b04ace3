"""Numpydoc sections on the public API of ``sc_rt`` (issue #24, item 6).

Every name of ``sc_rt._API`` but FIELDS (a tuple, documented where it is
defined, python/sc_rt/results/record/run.py): a function documents each parameter
of its signature in "Parameters" (``*args`` / ``**kwargs`` spelled with their
stars) and has "Returns"; a class documents its dataclass fields or its
``__init__`` parameters in "Parameters" or "Attributes". A section is a
header line over a line of dashes; an entry is a line at the section's
indentation, ``name : type`` or ``name1, name2 : type``.
"""

from __future__ import annotations

import dataclasses
import inspect

import pytest

import sc_rt

SKIP = {"FIELDS": "a tuple of Field records: the Field docstring and the #: comment document it"}
PUBLIC = sorted(name for name in sc_rt._API if name not in SKIP)


def sections(doc: str | None) -> dict[str, list[str]]:
    """Section header -> its lines (up to the next header), of a numpydoc docstring."""
    lines = inspect.cleandoc(doc or "").splitlines()
    heads = [i for i in range(len(lines) - 1)
             if lines[i].strip() and lines[i + 1].strip()
             and set(lines[i + 1].strip()) == {"-"} and len(lines[i + 1].strip()) >= len(lines[i].strip())]
    out: dict[str, list[str]] = {}
    for k, i in enumerate(heads):
        end = heads[k + 1] if k + 1 < len(heads) else len(lines)
        out[lines[i].strip()] = lines[i + 2:end]
    return out


def entry_names(body: list[str]) -> list[str]:
    """The names an entries section documents (``a, b : type`` gives a and b)."""
    indents = [len(line) - len(line.lstrip()) for line in body if line.strip()]
    if not indents:
        return []
    base = min(indents)
    names = []
    for line in body:
        if line.strip() and len(line) - len(line.lstrip()) == base:
            names += [n.strip() for n in line.split(" : ")[0].split(",") if n.strip()]
    return names


def _param_name(p: inspect.Parameter) -> str:
    return {p.VAR_POSITIONAL: "*", p.VAR_KEYWORD: "**"}.get(p.kind, "") + p.name


def docstring_problems(obj: object) -> list[str]:
    """What the docstring of a public function or class lacks (empty: nothing)."""
    secs = sections(inspect.getdoc(obj))
    problems = []
    if inspect.isclass(obj):
        init = [_param_name(p) for p in inspect.signature(obj).parameters.values()]
        if dataclasses.is_dataclass(obj):
            need = [f.name for f in dataclasses.fields(obj)]
        else:
            need = init
        if "Parameters" not in secs and "Attributes" not in secs:
            return ["no Parameters or Attributes section"]
        given = entry_names(secs.get("Parameters", [])) + entry_names(secs.get("Attributes", []))
        problems += [f"{n!r} is not documented" for n in need if n not in given]
        if "Parameters" in secs:
            extra = set(entry_names(secs["Parameters"])) - set(init)
            problems += [f"{n!r} is documented but no parameter" for n in sorted(extra)]
        return problems
    params = [_param_name(p) for p in inspect.signature(obj).parameters.values()]
    if params and "Parameters" not in secs:
        problems.append("no Parameters section")
    if "Returns" not in secs:
        problems.append("no Returns section")
    documented = entry_names(secs.get("Parameters", []))
    problems += [f"{n!r} is not documented" for n in params if n not in documented]
    problems += [f"{n!r} is documented but no parameter" for n in documented if n not in params]
    problems += [f"{n!r} is documented twice" for n in sorted({n for n in documented if documented.count(n) > 1})]
    if "Returns" in secs and not entry_names(secs["Returns"]):
        problems.append("the Returns section is empty")
    return problems


@pytest.mark.parametrize("name", PUBLIC)
def test_public_name_has_numpydoc_sections(name):
    obj = getattr(sc_rt, name)
    assert callable(obj), name
    assert docstring_problems(obj) == [], f"sc_rt.{name}"


def test_every_public_name_is_checked_or_skipped_with_a_reason():
    assert set(PUBLIC) | set(SKIP) == set(sc_rt._API)
    assert isinstance(sc_rt.FIELDS, tuple) and inspect.getdoc(type(sc_rt.FIELDS[0]))


# --------------------------------------------------------------------------- #
# The checker itself.


def _fake(a, b, *rest, c=1, **options):
    """A fake.

    Parameters
    ----------
    a, b : int
        Two numbers.
    *rest : int
        More.
    options : dict
        Spelled without its stars: not the parameter ``**options``.

    Returns
    -------
    int
        Nothing real.
    """


@dataclasses.dataclass
class _FakeRecord:
    """A fake record.

    Attributes
    ----------
    x : float
        [s] documented.
    """

    x: float
    y: float


def test_checker_reports_a_missing_parameter():
    problems = docstring_problems(_fake)
    assert "'c' is not documented" in problems
    assert "'**options' is not documented" in problems
    assert "'options' is documented but no parameter" in problems
    assert not [p for p in problems if "'a'" in p or "'b'" in p or "'*rest'" in p]


def test_checker_reports_missing_sections_and_fields():
    def bare(x):
        """No sections."""

    assert docstring_problems(bare) == ["no Parameters section", "no Returns section", "'x' is not documented"]
    assert docstring_problems(_FakeRecord) == ["'y' is not documented"]


def test_sections_parser():
    secs = sections(_fake.__doc__)
    assert list(secs) == ["Parameters", "Returns"]
    assert entry_names(secs["Parameters"]) == ["a", "b", "*rest", "options"]
    assert entry_names(secs["Returns"]) == ["int"]
