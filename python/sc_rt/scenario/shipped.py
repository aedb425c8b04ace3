"""The scenarios shipped with sc-rt, addressable by name.

They are the TOML files of ``sc_rt/scenario/library/`` (in the wheel, and in
the source tree where ``scenarios/`` is a symlink to that folder). A scenario's
name is its file name without ``.toml``: wherever a scenario path is taken,
``paper_faults`` stands for the shipped ``paper_faults.toml`` unless a file of
that name exists (:func:`resolve`, used by ``load_scenario``). ``sc-rt
scenarios`` lists them (:func:`shipped`).
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

from sc_rt.scenario.schema import ScenarioError, ScenarioIssue

__all__ = ["LIBRARY", "resolve", "shipped"]

LIBRARY = Path(__file__).resolve().parent / "library"


def shipped() -> dict[str, tuple[Path, str]]:
    """Name -> (path, one-line description) of every shipped scenario, by name.

    The description is the file's ``description`` key (the schema's), or its
    first comment line when the key is absent.

    Returns
    -------
    dict of str to (Path, str)
        Scenario name (file name without ``.toml``) -> (its file in
        ``LIBRARY``, its one-line description), sorted by name.
    """
    return {p.stem: (p, _description(p)) for p in sorted(LIBRARY.glob("*.toml"))}


def resolve(scenario: str | Path) -> Path:
    """The file of a scenario given as a path or as a shipped name.

    An existing path (a symlink too, even a broken one), or anything with a folder or another suffix than
    ``.toml``, is returned as given (reading it reports its own errors). A
    bare name (``paper_faults`` or ``paper_faults.toml``) that is no file here
    is the shipped scenario of that name; an unknown one raises ScenarioError
    listing the shipped names.
    """
    path = Path(scenario)
    if os.path.lexists(path) or len(path.parts) != 1 or path.suffix not in ("", ".toml"):
        return path
    name = path.name.removesuffix(".toml")
    library = shipped()
    if name in library:
        return library[name][0]
    names = ", ".join(library) or "none"
    raise ScenarioError(path, [ScenarioIssue(
        0, "", None, f"no such file, and no shipped scenario of that name (shipped: {names}; "
        "`sc-rt scenarios` lists them)")])


def _description(path: Path) -> str:
    text = path.read_text(encoding="utf-8")
    try:
        description = tomllib.loads(text).get("description")
    except tomllib.TOMLDecodeError:
        description = None
    if isinstance(description, str) and description.strip():
        return " ".join(description.split())
    for line in text.splitlines():
        if line.strip().startswith("#"):
            return line.strip().lstrip("#").strip()
        if line.strip():
            break
    return ""
