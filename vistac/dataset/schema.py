"""The dataset's names and conventions: files, fingers, columns and unit labels.

The format is described in docs/dataset-format.md.

Every table column that names a finger is built here, so the simulator, `vistac ingest` and the
learner agree on one spelling.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping

import numpy as np
import pyarrow as pa

FORMAT_VERSION = 2
"""The version written. 2: `redraw_reasons` and `failed_objects` are Parquet lists of structs
(1: text cells ``"reason:count,..."`` and JSON; `scene_effect_fallbacks` for
`grasp_effect_fallbacks`)."""
READ_VERSIONS = (1, 2)
"""The versions read: 1 differs only in bookkeeping columns the learner does not read."""
MANIFEST = "manifest.json"
CONFIGS = "configs.parquet"
PRESSES = "presses.parquet"
IMAGES = "images"
MASKS = "masks"  # optional (`--masks`): one label PNG per image, named as the image
MASK_VALUES = {"table": 0, "object": 1, "index": 2, "thumb": 3}  # a mask's pixel values
PARTIAL = ".partial"  # an unfinished `vistac generate` run keeps its state here
CARD = "README.md"  # the dataset card (vistac.dataset.card), Hugging Face convention
REJECTED = "rejected.csv"  # ingest only: every rejected grasp with its reason
SPLITS = ("train", "val", "test")
FINGERS = ("index", "thumb")  # the order of every per-finger array: (index, thumb)

# Colours of the drawn fingers and the table in [0, 1] (the simulator's defaults; the study's
# photographs were painted alike), used for datasets whose manifest has no render config.
TABLE_RGB = (0.81, 0.81, 0.81)
FINGER_RGB = {"index": (0.0, 0.85, 0.0), "thumb": (0.9, 0.0, 0.0)}

# Where a pixel's centre lies in the continuous image coordinates of the simulator's
# projections (`vistac.projection.Projection.project`, the finger boxes): pixel (u, v) covers
# [u, u + 1) x [v, v + 1). OpenCV, array indices and the fingertip locator put the centre at the
# integer itself; subtract PIXEL_CENTRE to go from the first to the second.
PIXEL_CENTRE = 0.5


def columns(prefix: str, finger: str, parts: str) -> list[str]:
    """Per-finger column names, e.g. ``columns("bbox", "index", "xywh")`` -> bbox_index_x, ..."""
    return [f"{prefix}_{finger}_{p}" for p in parts]


def box_columns(finger: str) -> list[str]:
    """Pixel box (x, y, w, h; top-left origin) of the drawn finger."""
    return columns("bbox", finger, "xywh")


def force_columns(finger: str) -> list[str]:
    """Measured force of a press, sensor frame, N."""
    return columns("force", finger, "xyz")


def clean_force_columns(finger: str) -> list[str]:
    """Noise-free force of a configuration, sensor frame, N."""
    return columns("force_clean", finger, "xyz")


def normal_columns(finger: str) -> list[str]:
    """Outward surface normal at the contact, sensor frame."""
    return columns("normal", finger, "xyz")


def label_columns(finger: str) -> list[str]:
    """Unit label (r_y, r_z) of a press."""
    return [f"r_y_{finger}", f"r_z_{finger}"]


LABEL_COLUMNS = [c for f in FINGERS for c in label_columns(f)]


def unit_labels(forces: np.ndarray) -> np.ndarray:
    """(..., 2) unit labels (r_y, r_z) = (F_y, F_z) / |(F_y, F_z)| of forces (..., 3).

    A zero (F_y, F_z) has no direction; it gets (0, -1), straight against the approach.
    """
    yz = np.asarray(forces, float)[..., 1:]
    n = np.linalg.norm(yz, axis=-1, keepdims=True)
    return np.where(n > 0, yz / np.where(n > 0, n, 1.0), np.array([0.0, -1.0]))


PRESS_COLUMNS = ["config_id", "repeat", *(c for f in FINGERS for c in force_columns(f)),
                 *LABEL_COLUMNS]
"""The columns of `presses.parquet`, in order."""


def press_rows(config_id: int, forces: np.ndarray, labels: np.ndarray) -> list[dict]:
    """The `presses.parquet` rows of a configuration's repeats: ids, the (2, 3) force and the
    (2, 2) unit labels per finger of each repeat (`forces` (R, 2, 3), `labels` (R, 2, 2))."""
    forces, labels = np.asarray(forces, float), np.asarray(labels, float)
    if forces.shape[1:] != (len(FINGERS), 3) or labels.shape != (*forces.shape[:-1], 2):
        raise ValueError(f"press_rows: forces {forces.shape} and labels {labels.shape} are not "
                         "(R, 2, 3) and (R, 2, 2)")
    values = np.concatenate([forces.reshape(len(forces), -1), labels.reshape(len(labels), -1)],
                            axis=1).tolist()
    return [dict(zip(PRESS_COLUMNS, [config_id, repeat, *v], strict=True))
            for repeat, v in enumerate(values)]


def press_row(config_id: int, repeat: int, force: np.ndarray, label: np.ndarray) -> dict:
    """One `presses.parquet` row (`press_rows` of one repeat, numbered `repeat`)."""
    row = press_rows(config_id, np.asarray(force)[None], np.asarray(label)[None])[0]
    row["repeat"] = repeat
    return row


REDRAWS_TYPE = pa.list_(pa.struct([("reason", pa.string()), ("count", pa.int64())]))
"""A `redraw_reasons` cell: rejected grasp draws by reason, sorted by reason."""
FAILED_OBJECTS_TYPE = pa.list_(pa.struct([("object_id", pa.string()), ("redraws", REDRAWS_TYPE)]))
"""A `failed_objects` cell: the objects that gave no valid grasp, sorted by id, with their
rejected draws."""
NESTED_COLUMNS = {"redraw_reasons": REDRAWS_TYPE, "failed_objects": FAILED_OBJECTS_TYPE}
"""The configs columns of nested type: their type is declared, not inferred from the rows (an
empty list has no item type to infer)."""


def redraw_cell(counts: Mapping[str, int]) -> list[dict]:
    """The `redraw_reasons` cell of draw counts by reason."""
    return [{"reason": k, "count": int(v)} for k, v in sorted(counts.items())]


def failed_objects_cell(failed: Mapping[str, Mapping[str, int]]) -> list[dict]:
    """The `failed_objects` cell of draw counts by reason, by object id."""
    return [{"object_id": k, "redraws": redraw_cell(v)} for k, v in sorted(failed.items())]


def redraw_counts(cell: Iterable[Mapping] | None) -> Counter:
    """Draw counts by reason of a `redraw_reasons` cell (as pyarrow or pandas give it)."""
    return Counter({item["reason"]: int(item["count"]) for item in (cell if cell is not None
                                                                     else ())})


def failed_object_counts(cell: Iterable[Mapping] | None) -> dict[str, Counter]:
    """Draw counts by reason, by object id, of a `failed_objects` cell."""
    return {item["object_id"]: redraw_counts(item["redraws"])
            for item in (cell if cell is not None else ())}


def with_declared_types(table: pa.Table) -> pa.Table:
    """`table` with its `NESTED_COLUMNS` cast to their declared types."""
    schema = table.schema
    for name, typ in NESTED_COLUMNS.items():
        i = schema.get_field_index(name)
        if i >= 0 and schema.field(i).type != typ:
            schema = schema.set(i, pa.field(name, typ))
    return table if schema == table.schema else table.cast(schema)
