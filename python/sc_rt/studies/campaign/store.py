"""The campaign's results as a Parquet dataset: ``OUT/runs/``, one file per
completed batch of runs, one row per run (run id, seed, status, every
dispersed value, every metric).

A batch file is written to a temporary name and renamed into place
(``os.replace`` is atomic), so a campaign killed at any instant (even
``kill -9``) leaves only whole files: it loses at most the batches in flight,
and ``--resume`` skips the ids the files hold. ``OUT/campaign.json`` records
what the campaign is (scenario, seed, dispersions, law, ...) and its
fingerprint: ``--resume`` refuses a different campaign.
"""

from __future__ import annotations

import hashlib
import json
import os
import uuid
from pathlib import Path
from typing import Any

__all__ = ["RunStore", "fingerprint"]

RUNS_DIR = "runs"
MANIFEST = "campaign.json"


def fingerprint(config: dict[str, Any]) -> str:
    """sha256 of the campaign's identity (canonical JSON)."""
    return hashlib.sha256(json.dumps(config, sort_keys=True, default=str).encode()).hexdigest()


class RunStore:
    """Append-only dataset of per-run rows under ``out/runs``."""

    def __init__(self, out: Path, columns: list[tuple[str, str]]):
        """``columns``: the columns every row has, with their types; the rest
        (the metrics) take the types of their values."""
        import pyarrow as pa

        self.out = Path(out)
        self.dir = self.out / RUNS_DIR
        types = {"int64": pa.int64(), "float64": pa.float64(), "bool": pa.bool_(), "string": pa.string()}
        self.schema = pa.schema([(name, types[t]) for name, t in columns])

    # -- the manifest
    def existing_manifest(self) -> dict[str, Any] | None:
        p = self.out / MANIFEST
        return json.loads(p.read_text()) if p.exists() else None

    def has_runs(self) -> bool:
        return self.dir.exists() and any(self.dir.glob("*.parquet"))

    def start(self, manifest: dict[str, Any], fresh: bool) -> None:
        """Create the dataset (``fresh``: remove a previous one first)."""
        self.dir.mkdir(parents=True, exist_ok=True)
        for p in self.dir.iterdir():
            if fresh and p.suffix == ".parquet" or p.name.endswith(".tmp"):
                p.unlink()  # .tmp: a batch that was being written when a run was killed
        tmp = self.out / (MANIFEST + ".tmp")
        tmp.write_text(json.dumps(manifest, indent=2) + "\n")
        os.replace(tmp, self.out / MANIFEST)

    # -- rows
    def append(self, rows: list[dict[str, Any]]) -> Path:
        """One batch file of ``rows``, atomically."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        names = list(dict.fromkeys(k for r in rows for k in r))
        rows = [{k: r.get(k) for k in names} for r in rows]  # same keys in every row
        table = pa.Table.from_pylist(rows)
        for f in self.schema:
            i = table.schema.get_field_index(f.name)
            table = table.set_column(i, f, table.column(i).cast(f.type))
        first = min(r["run"] for r in rows)
        name = f"batch-{first:010d}-{len(rows)}-{uuid.uuid4().hex[:8]}.parquet"
        tmp = self.dir / (name + ".tmp")
        pq.write_table(table, tmp, compression="zstd")
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(tmp, self.dir / name)
        return self.dir / name

    def read(self, columns: list[str] | None = None):
        """Every row written so far as a pyarrow Table sorted by run id."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        files = sorted(self.dir.glob("*.parquet")) if self.dir.exists() else []
        if not files:
            return self.schema.empty_table() if columns is None else pa.table(
                {c: pa.array([], self.schema.field(c).type) for c in columns})
        # batches may differ in their metric columns (a batch of invalid draws
        # has none): missing columns read as null
        t = pa.concat_tables([pq.read_table(f, columns=columns) for f in files],
                             promote_options="permissive")
        return t.sort_by("run") if "run" in t.column_names else t

    def done_ids(self) -> set[int]:
        return set(self.read(["run"]).column("run").to_pylist())

    def bytes(self) -> int:
        return sum(p.stat().st_size for p in self.dir.glob("*.parquet")) if self.dir.exists() else 0
