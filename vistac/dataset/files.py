"""Writing dataset files: atomic bytes and JSON, deterministic Parquet tables, the manifest."""

from __future__ import annotations

import json
import os
import platform
from importlib import import_module
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from vistac.dataset.schema import MANIFEST, SPLITS


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write `data` to `path` through a temporary file and a rename."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as fh:
        fh.write(data)
    os.replace(tmp, path)


def atomic_write_json(path: Path, obj: Any) -> None:
    """Write `obj` as indented JSON with sorted keys (the manifest's format), atomically."""
    atomic_write_bytes(path, (json.dumps(obj, indent=2, sort_keys=True) + "\n").encode())


def write_manifest(root: Path, manifest: dict[str, Any]) -> None:
    """Write a dataset's `manifest.json`: its last file, the mark of a complete dataset."""
    atomic_write_json(root / MANIFEST, manifest)


def write_table(path: Path, rows: list[dict] | pd.DataFrame) -> None:
    """Write rows as Parquet, atomically, with deterministic bytes for identical rows."""
    df = rows if isinstance(rows, pd.DataFrame) else pd.DataFrame(rows)
    table = pa.Table.from_pandas(df, preserve_index=False).replace_schema_metadata(None)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    pq.write_table(table, tmp, compression="zstd", write_statistics=False)
    os.replace(tmp, path)


def table_counts(configs: pd.DataFrame, presses: pd.DataFrame) -> dict[str, Any]:
    """The manifest's counts of a dataset's tables: configurations, presses, splits, objects."""
    return {"configs": len(configs), "presses": len(presses),
            "split": {s: int((configs["split"] == s).sum()) for s in SPLITS},
            "objects": int(configs["object_id"].nunique())}


def versions(*modules: str) -> dict[str, str]:
    """The manifest's versions: vistac, each named module and Python."""
    import vistac

    return {"vistac": vistac.__version__,
            **{m: import_module(m).__version__ for m in modules},
            "python": platform.python_version()}
