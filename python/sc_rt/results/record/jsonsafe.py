"""The files a run writes, safe: JSON that stays JSON (NaN and inf as null,
numpy scalars and arrays as plain numbers and lists), and every file written
whole or not at all (``atomic_path``: a full disk leaves no 0-byte or
truncated output presented as a result). Re-exported by
sc_rt.results.record.run."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["json_safe", "write_json", "atomic_path"]


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """A temporary name beside ``path`` to write to: renamed to ``path`` when
    the block ends, removed when it raises (ENOSPC, an interrupt), so that
    ``path`` is either the whole file or what it was before."""
    path = Path(path)
    part = path.with_name(f".{path.name}.{os.getpid()}.part")
    try:
        yield part
        os.replace(part, path)
    except BaseException:
        part.unlink(missing_ok=True)
        raise


def json_safe(obj: Any) -> Any:
    """NaN/inf become null and numpy scalars plain numbers, so that the
    JSON files stay valid JSON."""
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    return obj


def write_json(path: Path, obj: Any) -> Path:
    """``obj`` through json_safe, indented, into ``path`` (whole or not at
    all); returns ``path``."""
    text = json.dumps(json_safe(obj), indent=2) + "\n"
    with atomic_path(path) as part:
        part.write_text(text)
    return path
