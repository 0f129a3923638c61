"""A dataset read as far as it is readable: the checked tables, or what is left of a damaged or
unfinished folder, with one note per thing that could not be read.

`vistac inspect` shows whatever it can: a folder that `open_tables` refuses (no manifest, an
interrupted run, a truncated table, a label that is not a unit vector, missing images) is read
piece by piece, and each refusal becomes a one-line note in the summary and the report.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from vistac.dataset import FINGERS, open_tables
from vistac.dataset.reader import DatasetTables
from vistac.dataset.schema import CONFIGS, IMAGES, MANIFEST, PARTIAL, PRESSES, label_columns
from vistac.errors import UserError


@dataclass
class Readable:
    """What could be read of a dataset folder.

    Attributes:
        tables: The tables; for a damaged folder a `DatasetTables` built from the readable parts
            (configs or presses may then be empty frames).
        notes: One line per part that could not be read, naming the file and the reason.
        missing_images: Rows whose image file is missing.
    """

    tables: DatasetTables
    notes: list[str] = field(default_factory=list)
    missing_images: np.ndarray = field(default_factory=lambda: np.zeros(0, int))

    @property
    def damaged(self) -> bool:
        """Whether anything could not be read."""
        return bool(self.notes)


def read_readable(root: str | Path) -> Readable:
    """The dataset folder `root`, checked when it can be, else as far as it is readable.

    Raises:
        UserError: `root` is not a folder, or holds none of a dataset's files.
    """
    root = Path(root)
    if not root.is_dir():
        raise UserError(f"{root}: not a folder")
    try:
        tables = open_tables(root)
        notes: list[str] = []
    except UserError as exc:
        tables, notes = _salvage(root, str(exc))
    missing = np.array([r for r in range(len(tables.configs))
                        if not tables.image_path(r).is_file()], int) \
        if "image" in tables.configs else np.zeros(0, int)
    if len(missing):
        notes.append(f"{root / IMAGES}: {len(missing)} of {len(tables.configs)} images missing "
                     f"(first: {tables.configs['image'].iat[missing[0]]})")
    return Readable(tables, notes, missing)


def _salvage(root: Path, refusal: str) -> tuple[DatasetTables, list[str]]:
    """The readable parts of a folder `open_tables` refused (its reason is the first note)."""
    notes = [f"not a complete, valid dataset: {refusal}"]
    manifest: dict = {}
    try:
        loaded = json.loads((root / MANIFEST).read_text())
        manifest = loaded if isinstance(loaded, dict) else {}
    except FileNotFoundError:
        if (root / PARTIAL).exists():
            notes.append(f"{root}: an unfinished `vistac generate` run (no manifest yet); "
                         "only committed shards exist, nothing merged to inspect")
    except (OSError, ValueError) as exc:
        notes.append(f"{root / MANIFEST}: unreadable ({' '.join(str(exc).split())[:120]})")
    configs = _table(root / CONFIGS, notes)
    presses = _table(root / PRESSES, notes)
    if configs is None and presses is None and not manifest:
        raise UserError(f"{root}: nothing of a dataset to inspect ({refusal})")
    configs = pd.DataFrame() if configs is None else configs
    presses = pd.DataFrame() if presses is None else presses
    if "config_id" in configs:
        configs = configs.sort_values("config_id", kind="stable").reset_index(drop=True)
    cones = _cones(configs, presses, root, notes)
    return DatasetTables(root, manifest, configs, presses, cones), notes


def _table(path: Path, notes: list[str]) -> pd.DataFrame | None:
    if not path.is_file():
        notes.append(f"{path}: missing")
        return None
    try:
        return pd.read_parquet(path)
    except Exception as exc:  # pyarrow's errors of a damaged file have no common base
        notes.append(f"{path}: unreadable ({' '.join(str(exc).split())[:120]})")
        return None


def _cones(configs: pd.DataFrame, presses: pd.DataFrame, root: Path,
           notes: list[str]) -> dict[str, list[np.ndarray]]:
    """Per finger, each configuration's finite unit labels ((0, 2) where there is none)."""
    empty = np.zeros((0, 2))
    cols = [c for f in FINGERS for c in label_columns(f)]
    if "config_id" not in configs or not {"config_id", *cols} <= set(presses.columns):
        return {f: [empty] * len(configs) for f in FINGERS}
    labels = presses[cols].apply(pd.to_numeric, errors="coerce").to_numpy(float)
    ok = np.isfinite(labels).all(axis=1)
    for f in FINGERS:
        norm = np.hypot(*labels[:, [cols.index(c) for c in label_columns(f)]].T)
        ok &= np.abs(norm - 1) < 1e-3
    if (~ok).any():
        notes.append(f"{root / PRESSES}: {int((~ok).sum())} presses without a finite unit label "
                     "left out")
    good = presses.loc[ok]
    groups = {int(k): g for k, g in good.groupby("config_id")}
    out: dict[str, list[np.ndarray]] = {f: [] for f in FINGERS}
    for cid in configs["config_id"].tolist():
        g = groups.get(int(cid))
        for f in FINGERS:
            out[f].append(empty if g is None else g[label_columns(f)].to_numpy(float))
    without = sum(1 for c in out[FINGERS[0]] if len(c) == 0)
    if without:
        notes.append(f"{root / PRESSES}: {without} configurations without presses")
    return out
