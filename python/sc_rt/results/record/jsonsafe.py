"""JSON that stays JSON: NaN and inf as null, numpy scalars and arrays as
plain numbers and lists (every file a run writes). Re-exported by
sc_rt.results.record.run."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["json_safe", "write_json"]


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
    """``obj`` through json_safe, indented, into ``path``; returns ``path``."""
    path.write_text(json.dumps(json_safe(obj), indent=2) + "\n")
    return path
