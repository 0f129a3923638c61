"""What the Python API returns: handles on the folders it wrote (a dataset, a run, a score).

Each handle is a small frozen dataclass around a folder; the tables and files are read on first
use (pandas on demand, torch never), so holding one costs nothing. The folders are the contract
(docs/dataset-format.md): a handle reads exactly what the CLI's users read.
"""

from __future__ import annotations

import json
import math
import numbers
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

from vistac.errors import UserError, brief


@dataclass(frozen=True)
class Dataset:
    """A complete dataset folder (written by `vistac.generate` or `vistac.ingest`).

    Attributes:
        path: The dataset folder.
        already_complete: `generate` with ``resume`` found the dataset complete (checked) and
            did nothing.
    """

    path: Path
    already_complete: bool = False

    @cached_property
    def tables(self):
        """The checked tables (`vistac.dataset.reader.DatasetTables`), read once."""
        from vistac.dataset import open_tables

        return open_tables(self.path)

    @cached_property
    def manifest(self) -> dict[str, Any]:
        """The parsed ``manifest.json``: full config, seed, versions, counts, effects (read
        without the tables)."""
        from vistac.dataset.schema import MANIFEST

        return json.loads((self.path / MANIFEST).read_text())

    @property
    def configs(self):
        """``configs.parquet`` as a DataFrame, one row per configuration, sorted by config_id."""
        return self.tables.configs

    @property
    def presses(self):
        """``presses.parquet`` as a DataFrame, one row per press, with the unit labels."""
        return self.tables.presses

    @property
    def config_ids(self) -> list[int]:
        """The configuration ids, ascending."""
        return [int(c) for c in self.configs["config_id"]]

    def image_path(self, config_id: int) -> Path:
        """The PNG of configuration `config_id`.

        Raises:
            UserError: no such configuration.
        """
        if not isinstance(config_id, numbers.Integral) or isinstance(config_id, bool):
            raise UserError(f"config_id: expected an integer (one of Dataset.config_ids), got "
                            f"{brief(config_id)}")
        rows = self.configs.index[self.configs["config_id"] == int(config_id)]
        if len(rows) == 0:
            raise UserError(f"{self.path}: no configuration {config_id}")
        return self.tables.image_path(int(rows[0]))

    def image(self, config_id: int):
        """The image of configuration `config_id`: (H, W, 3) uint8 RGB array."""
        import cv2

        from vistac.dataset.files import check_file

        path = self.image_path(config_id)
        check_file(path)
        bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if bgr is None:
            raise UserError(f"{path}: cannot read the image")
        return bgr[:, :, ::-1].copy()

    def inspect(self, out: str | Path | None = None, **settings: Any):
        """Inspect the dataset (`vistac inspect`): a report folder with its summary, contact
        sheet, distributions and recordings pages, and the dataset card if it had none.

        Args:
            out: The report folder (default: ``<path>-inspect`` beside the dataset).
            settings: Fields of `vistac_learn.inspect.config.InspectCfg` (``per_group``, ...).

        Returns:
            The `vistac_learn.inspect.report.InspectReport` (``out``, ``lines``, ``files``).
        """
        from vistac_learn.inspect.config import InspectCfg
        from vistac_learn.inspect.report import inspect_dataset

        cfg = InspectCfg(out=None if out is None else str(out), **settings)
        return inspect_dataset(self.path, cfg)

    def __len__(self) -> int:
        return len(self.configs)


@dataclass(frozen=True)
class Run:
    """A training run folder (written by `vistac.train`).

    Attributes:
        path: The run folder.
        best_epoch: The epoch selected on the validation split (1-based).
        objective: Validation median angle to the cone mean at that epoch (deg, mean over the
            fingers).
    """

    path: Path
    best_epoch: int
    objective: float

    @classmethod
    def open(cls, path: str | Path) -> Run:
        """The run in folder `path` (trained to at least one checkpoint), its files checked.

        Raises:
            UserError: not a run, no finished epoch, a damaged ``config.json``,
                ``metrics.csv`` or best checkpoint (one line naming the file).
        """
        from vistac_learn.train.checkpoints import BEST_KEYS, load_checkpoint
        from vistac_learn.train.run_files import read_metrics, read_run_config

        path, fix = Path(path), "train the run again"
        read_run_config(path, fix)
        rows = read_metrics(path / "metrics.csv", fix) \
            if (path / "metrics.csv").is_file() else []
        if not rows:
            raise UserError(f"{path}: the run has not finished an epoch (no metrics.csv rows)")
        best_pt = path / "checkpoints" / "best.pt"
        best = load_checkpoint(best_pt, BEST_KEYS, fix)["epoch"]
        if not isinstance(best, numbers.Integral) or isinstance(best, bool) or best < 1:
            raise UserError(f"{best_pt}: its epoch is {brief(best)}, not a whole number >= 1; "
                            f"{fix}")
        metrics = path / "metrics.csv"
        row = next((r for r in rows if r["epoch"] == best), None)
        if row is None:
            raise UserError(f"{metrics}: no row of epoch {best}, the best checkpoint's (it has "
                            f"{len(rows)} rows); {fix}")
        columns = [f"val_{f}_angle_to_mean_median_deg" for f in ("index", "thumb")]
        values = [row[c] for c in columns if c in row]
        objective = sum(values) / len(values) if values else math.nan
        if not math.isfinite(objective):
            raise UserError(f"{metrics}: epoch {best}: no finite validation objective "
                            f"({' / '.join(c for c in columns if c in row) or 'no such column'}"
                            f"); {fix}")
        return cls(path, int(best), float(objective))

    @cached_property
    def config(self) -> dict[str, Any]:
        """The parsed ``config.json``: every setting, the dataset's path and fingerprint."""
        from vistac_learn.train.run_files import read_run_config

        return read_run_config(self.path, "train the run again")

    @property
    def history(self) -> list[dict[str, float]]:
        """The rows of ``metrics.csv``, one per epoch (training loss, validation metrics)."""
        from vistac_learn.train.run_files import read_metrics

        return read_metrics(self.path / "metrics.csv", "train the run again")


@dataclass(frozen=True)
class Evaluation:
    """A scored run or baseline (written by `vistac.evaluate`).

    Attributes:
        path: The output folder (``metrics.json``, ``predictions.parquet``, figures).
        result: The whole content of ``metrics.json``.
    """

    path: Path
    result: dict[str, Any] = field(repr=False)

    @property
    def metrics(self) -> dict[str, dict[str, float]]:
        """Finger -> scalar metric -> value (``metrics.json``'s ``"metrics"``)."""
        return self.result["metrics"]

    @property
    def table(self) -> str:
        """The markdown table in the reference study's layout (what `vistac evaluate` prints)."""
        return self.result["table"]


@dataclass(frozen=True)
class Report:
    """A finished tuning or experiment folder and its rows.

    Attributes:
        path: The folder.
        rows: One dict per finished trial or trained cell.
        best: Tuning only: the best trial's row (None before any trial finished).
    """

    path: Path
    rows: list[dict[str, Any]] = field(repr=False)
    best: dict[str, Any] | None = None
