"""Dataset directory writing and reading: shards, atomic files, splits, the manifest.

A dataset is complete only when `manifest.json` exists with ``"complete": true``; it is written
last, atomically, after `configs.parquet` and `presses.parquet`. While a run is in progress its
state lives in `.partial/` (the run's config and one committed shard per finished chunk), so an
interrupted run, even one killed with SIGKILL, can never pass for a complete dataset and can be
resumed from its finished shards.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from vistac_sim.errors import UserError

FORMAT_VERSION = 1
MANIFEST = "manifest.json"
PARTIAL = ".partial"
SPLITS = ("train", "val", "test")


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write `data` to `path` through a temporary file and a rename."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as fh:
        fh.write(data)
    os.replace(tmp, path)


def atomic_write_json(path: Path, obj: Any) -> None:
    atomic_write_bytes(path, (json.dumps(obj, indent=2, sort_keys=True) + "\n").encode())


def write_table(path: Path, rows: list[dict] | pd.DataFrame) -> None:
    """Write rows as Parquet, atomically, with deterministic bytes for identical rows."""
    df = rows if isinstance(rows, pd.DataFrame) else pd.DataFrame(rows)
    table = pa.Table.from_pandas(df, preserve_index=False).replace_schema_metadata(None)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    pq.write_table(table, tmp, compression="zstd", write_statistics=False)
    os.replace(tmp, path)


def shard_paths(out: Path, chunk: int) -> tuple[Path, Path]:
    """(configs, presses) shard files of one chunk; the configs file is the commit marker."""
    d = out / PARTIAL / "shards"
    return d / f"chunk_{chunk:05d}.configs.parquet", d / f"chunk_{chunk:05d}.presses.parquet"


def finished_chunks(out: Path) -> set[int]:
    """Chunks whose shard was committed (the configs file is written last)."""
    d = out / PARTIAL / "shards"
    if not d.is_dir():
        return set()
    return {int(p.name[6:11]) for p in d.glob("chunk_*.configs.parquet")}


def start_run(out: Path, run_state: dict, resume: bool) -> set[int]:
    """Prepare `out` for a run and return the chunks already finished.

    Raises:
        UserError: `out` holds a complete dataset, holds something else, or (with resume) an
            interrupted run made with different settings.
    """
    partial = out / PARTIAL
    state_file = partial / "run.json"
    if (out / MANIFEST).exists():
        raise UserError(f"{out}: already holds a complete dataset; choose another --out")
    if resume:
        if not state_file.exists():
            raise UserError(f"{out}: nothing to resume (no interrupted run found there)")
        previous = json.loads(state_file.read_text())
        if previous != run_state:
            diff = sorted(k for k in set(previous) | set(run_state)
                          if previous.get(k) != run_state.get(k))
            raise UserError(f"{out}: the interrupted run used other settings ({', '.join(diff)}); "
                            "resume with the same options or choose another --out")
        return finished_chunks(out)
    if out.exists() and any(out.iterdir()):
        hint = " (an interrupted run: add --resume)" if state_file.exists() else ""
        raise UserError(f"{out}: folder exists and is not empty{hint}")
    (partial / "shards").mkdir(parents=True, exist_ok=True)
    (out / "images").mkdir(parents=True, exist_ok=True)
    atomic_write_json(state_file, run_state)
    return set()


def assign_splits(configs: pd.DataFrame, by: str, fractions, seed: int) -> np.ndarray:
    """Split labels for whole configurations, or whole objects when `by == "object"`."""
    fr = np.asarray(fractions, float)
    if fr.shape != (3,) or (fr < 0).any() or fr.sum() <= 0:
        raise UserError(f"split fractions must be three non-negative numbers, got {fractions}")
    fr = fr / fr.sum()
    rng = np.random.default_rng([seed, 0x5B1])
    keys = configs["object_id"] if by == "object" else configs["config_id"]
    units = np.array(sorted(pd.unique(keys)))
    units = units[rng.permutation(len(units))]
    bounds = np.round(np.cumsum(fr) * len(units)).astype(int)
    label_of = {u: SPLITS[int(np.searchsorted(bounds, i, side="right"))] for i, u in
                enumerate(units)}
    return np.array([label_of[k] for k in keys])


def finalize(out: Path, n_chunks: int, manifest: dict, split_by: str, fractions, seed: int) -> dict:
    """Merge shards into the final tables, write the manifest last, remove `.partial/`."""
    configs, presses = [], []
    for c in range(n_chunks):
        cpath, ppath = shard_paths(out, c)
        configs.append(pd.read_parquet(cpath))
        presses.append(pd.read_parquet(ppath))
    cfg_df = pd.concat(configs).sort_values("config_id").reset_index(drop=True)
    prs_df = pd.concat(presses).sort_values(["config_id", "repeat"]).reset_index(drop=True)
    cfg_df.insert(4, "split", assign_splits(cfg_df, split_by, fractions, seed))
    write_table(out / "configs.parquet", cfg_df)
    write_table(out / "presses.parquet", prs_df)
    counts = {"configs": len(cfg_df), "presses": len(prs_df),
              "split": {s: int((cfg_df["split"] == s).sum()) for s in SPLITS},
              "objects": int(cfg_df["object_id"].nunique()),
              "families": {k: int(v) for k, v in cfg_df["object_family"].value_counts().items()}}
    reasons: dict[str, int] = {}
    for text in cfg_df["redraw_reasons"]:
        for item in filter(None, text.split(",")):
            name, count = item.split(":")
            reasons[name] = reasons.get(name, 0) + int(count)
    manifest = {**manifest, "format_version": FORMAT_VERSION, "complete": True, "counts": counts,
                "redraws": {"total": int(cfg_df["redraws"].sum()),
                            "by_reason": dict(sorted(reasons.items()))}}
    atomic_write_json(out / MANIFEST, manifest)
    shutil.rmtree(out / PARTIAL, ignore_errors=True)
    return manifest


def load_dataset(path: str | os.PathLike) -> tuple[dict, pd.DataFrame, pd.DataFrame]:
    """Read a complete dataset: (manifest, configs, presses).

    Raises:
        UserError: the folder is missing, incomplete (an interrupted run) or malformed.
    """
    root = Path(path)
    if not root.is_dir():
        raise UserError(f"{root}: no such dataset folder")
    mpath = root / MANIFEST
    if not mpath.exists():
        why = "an interrupted run (resume it with --resume)" if (root / PARTIAL).exists() else \
            "no manifest.json"
        raise UserError(f"{root}: not a complete dataset: {why}")
    manifest = json.loads(mpath.read_text())
    if not manifest.get("complete"):
        raise UserError(f"{mpath}: dataset is marked incomplete")
    return manifest, pd.read_parquet(root / "configs.parquet"), pd.read_parquet(
        root / "presses.parquet")
