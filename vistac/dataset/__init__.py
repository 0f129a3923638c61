"""The vistac dataset format: the one owner of its names, conventions, readers and writers.

A dataset directory (docs/dataset-format.md) holds `manifest.json` (written last: a dataset is
complete only once it exists with ``"complete": true``), `configs.parquet` (one row per grasp
configuration), `presses.parquet` (one row per press, with the unit labels) and `images/`.
`vistac generate`, `vistac ingest` and the learner all go through this package, which needs
neither MuJoCo nor torch:

- `vistac.dataset.schema`: file names, splits, the finger list, column names, `unit_labels`;
- `vistac.dataset.files`: atomic files, deterministic Parquet tables, the manifest's parts;
- `vistac.dataset.splits`: `SplitCfg` and `assign_splits`;
- `vistac.dataset.reader`: `read_manifest`, `open_tables` -> `DatasetTables` (with the dataset
  fingerprint);
- `vistac.dataset.recordings`: the RH8D/FTS-3 recording CSV layout (written by the simulator,
  read by `ingest`);
- `vistac.dataset.ingest`: `vistac ingest`, recordings and/or label spreadsheets plus images ->
  a dataset (imported only when used; it needs pandas and openpyxl).
"""

from vistac.dataset.files import (
    atomic_write_bytes,
    atomic_write_json,
    write_manifest,
    write_table,
)
from vistac.dataset.schema import (
    FINGERS,
    FORMAT_VERSION,
    MANIFEST,
    SPLITS,
    press_row,
    press_rows,
    unit_labels,
)
from vistac.dataset.splits import SplitCfg, assign_splits

__all__ = [
    "FINGERS",
    "FORMAT_VERSION",
    "MANIFEST",
    "SPLITS",
    "DatasetTables",
    "SplitCfg",
    "assign_splits",
    "atomic_write_bytes",
    "atomic_write_json",
    "open_tables",
    "press_row",
    "press_rows",
    "read_manifest",
    "unit_labels",
    "write_manifest",
    "write_table",
]

_READER = ("DatasetTables", "open_tables", "read_manifest")


def __getattr__(name: str):
    """The reader's names, imported on first use: it needs pandas, which the writers (the
    `vistac generate` driver, its workers) do without."""
    if name in _READER:
        from vistac.dataset import reader

        return getattr(reader, name)
    raise AttributeError(f"module 'vistac.dataset' has no attribute {name!r}")
