"""What `vistac ingest` reads and its preprocessing and rejection knobs."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from vistac.config import Config, param
from vistac.dataset import SplitCfg
from vistac.dataset.recordings import FORCE_COLUMNS

UNITS = {"mN": 1e-3, "N": 1.0}  # unit of the CSV's force cells -> newtons
MAX_COLUMN = 100_000  # the highest CSV column a force may be read from


@dataclass(frozen=True)
class ColumnMap(Config):
    """0-based CSV columns of each finger's F_x, F_y, F_z (docs/dataset-format.md by default)."""

    thumb: tuple[int, int, int] = param(FORCE_COLUMNS["thumb"], ge=0, le=MAX_COLUMN)
    index: tuple[int, int, int] = param(FORCE_COLUMNS["index"], ge=0, le=MAX_COLUMN)

    def of(self, finger: str) -> tuple[int, int, int]:
        return getattr(self, finger)

    @property
    def needed(self) -> int:
        """Fields a row must have."""
        return max(*self.thumb, *self.index) + 1


@dataclass(frozen=True)
class IngestCfg(Config):
    """The preprocessing and rejection knobs (forces in newtons, lengths in samples)."""

    columns: ColumnMap = field(default_factory=ColumnMap)
    unit: str = param("mN", choices=tuple(UNITS), help="unit of the CSV force cells")
    threshold: float = param(0.1, ge=0, help="N on |index F_z| that starts and ends a grasp")
    min_samples: int = param(5, ge=1, help="shortest grasp kept, samples above the threshold")
    saturation: float = param(9.9, gt=0, help="N; a grasp with a force component this large is "
                              "rejected as clipped")
    min_force: float = param(0.02, ge=0, help="N; smallest |(F_y, F_z)| of a finger whose "
                             "direction is kept")
    allow_pulling: bool = param(False, help="keep grasps with F_z >= 0 at the representative "
                                "sample")


@dataclass(frozen=True)
class IngestSources(Config):
    """What to ingest and how to split it."""

    images: Path = param(help="folder of the images")
    recordings: Path | None = param(None, help="folder of recording CSVs")
    labels: Path | None = param(None, help="the study's label spreadsheet (xlsx): the presses "
                                "without --recordings, a check of them with it")
    labels_sheet: str | None = param(None, help="sheet of --labels (None: the first)")
    objects_csv: Path | None = param(None, help="CSV with object_id and config_id (or name) "
                                     "per configuration")
    split: SplitCfg = field(default_factory=SplitCfg)
    seed: int = param(0, ge=0, lt=2**32, help="seed of the split")
    image_size: int | None = param(None, ge=16, le=4096,
                                   help="crop images square (centre) and resize to this "
                                   "size (default: keep)")
