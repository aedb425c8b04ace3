"""The repository is self-contained about its science: every citation resolves
inside it.

- No tracked file points outside the repository for the model or the paper
  (the spec and seed folders this project was started from are not shipped).
- Every ``docs/<name>.md`` that a tracked text file mentions exists.
- Every "MODEL.md section N" and "erratum N" names a section or an erratum
  that docs/MODEL.md has.

Reads the tracked files once (``git ls-files``); skipped outside a git
checkout.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT / "docs" / "MODEL.md"

# Written in pieces so that this file does not contain them itself.
FORBIDDEN = ("shared" + "/spec", ".." + "/shared", "/seed" + "/paper")

DOC_REF = re.compile(r"(?<![\w./-])docs/([\w-]+)\.md")
SECTION_REF = re.compile(r"MODEL\.md,? (?:sections?|s) ?(\d+(?:(?:, | and )s?\d+)*)")
ERRATUM_REF = re.compile(r"\berrat(?:um|a) (\d+)")


def _tracked_texts() -> dict[str, str]:
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True,
                             timeout=30).stdout
    except (OSError, subprocess.SubprocessError):
        pytest.skip("not a git checkout")
    texts = {}
    for name in out.decode().split("\0"):
        p = ROOT / name
        if not name or p.is_symlink() or not p.is_file():
            continue  # a symlink's target is listed itself; deleted in the working tree
        data = p.read_bytes()
        if b"\0" in data:
            continue  # binary (figures)
        texts[name] = data.decode("utf-8", errors="replace")
    return texts


@pytest.fixture(scope="module")
def texts() -> dict[str, str]:
    t = _tracked_texts()
    assert t, "git ls-files listed no text file"
    return t


def test_no_file_points_outside_the_repository(texts):
    bad = [f"{name}:{i}: {line.strip()}"
           for name, text in texts.items()
           for i, line in enumerate(text.splitlines(), 1)
           if any(s in line for s in FORBIDDEN)]
    assert not bad, "citations of paths outside the repository:\n" + "\n".join(bad)


def test_every_mentioned_docs_page_exists(texts):
    missing = sorted({f"{name}: docs/{m}.md" for name, text in texts.items()
                      for m in DOC_REF.findall(text) if not (ROOT / "docs" / f"{m}.md").is_file()})
    assert not missing, "docs pages mentioned but missing:\n" + "\n".join(missing)


def _model_sections_and_errata() -> tuple[set[int], set[int]]:
    text = MODEL.read_text()
    sections = {int(n) for n in re.findall(r"^## (\d+)\. ", text, re.M)}
    errata_part = text.split("\n## Errata", 1)[1]
    errata = {int(n) for n in re.findall(r"^(\d+)\. ", errata_part, re.M)}
    return sections, errata


def test_model_has_the_sections_and_errata_the_code_cites(texts):
    sections, errata = _model_sections_and_errata()
    # numbered without gaps (1-9 the paper's model, 10 on: what the bench adds)
    assert sections == set(range(1, max(sections) + 1)) and max(sections) >= 9, sections
    assert errata and errata == set(range(1, max(errata) + 1)), errata
    bad = []
    for name, text in texts.items():
        for group in SECTION_REF.findall(text):
            for n in map(int, re.findall(r"\d+", group)):
                if n not in sections:
                    bad.append(f"{name}: MODEL.md section {n}")
        for n in map(int, ERRATUM_REF.findall(text)):
            if n not in errata:
                bad.append(f"{name}: erratum {n}")
    assert not bad, "citations docs/MODEL.md cannot resolve:\n" + "\n".join(sorted(set(bad)))
