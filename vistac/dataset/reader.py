"""Reading a dataset directory: the manifest, both tables and the cones, checked.

`open_tables` is the one reader of the format (docs/dataset-format.md) for every consumer: the
learner, `evaluate`, benchmarks and tests. It refuses an unfinished dataset, names the file, row and
reason of any malformed content, and sorts configurations by `config_id`.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from vistac.dataset.files import check_file
from vistac.dataset.schema import (
    CONFIGS,
    FINGER_RGB,
    FINGERS,
    FORMAT_VERSION,
    IMAGES,
    LABEL_COLUMNS,
    MANIFEST,
    MASKS,
    PARTIAL,
    PRESSES,
    READ_VERSIONS,
    SPLITS,
    TABLE_RGB,
    box_columns,
    label_columns,
)
from vistac.errors import UserError


@dataclass
class DatasetTables:
    """A checked dataset directory, configurations sorted by `config_id`.

    Attributes:
        root: The dataset directory.
        manifest: Parsed `manifest.json`.
        configs: One row per configuration, sorted by `config_id`, index 0..N-1 ("row").
        presses: One row per press.
        cones: Per finger, a list (one per configuration row) of (K_i, 2) unit labels (r_y, r_z).
    """

    root: Path
    manifest: dict
    configs: pd.DataFrame
    presses: pd.DataFrame
    cones: dict[str, list[np.ndarray]] = field(default_factory=dict)
    _fingerprint: str | None = None
    _image_fingerprint: str | None = None

    @property
    def render(self) -> dict:
        """The manifest's render config (may be empty for ingested data)."""
        return dict((self.manifest.get("config") or {}).get("render") or {})

    @property
    def hand(self) -> dict:
        """The manifest's hand config (may be empty for ingested data): e.g. ``height``, the
        fingertips' axis above the table, where contact points and fingertips lie (m)."""
        return dict((self.manifest.get("config") or {}).get("hand") or {})

    @property
    def table_rgb(self) -> tuple[float, float, float]:
        """Background colour of the images in [0, 1]."""
        return tuple(self.render.get("table_rgb", TABLE_RGB))

    def finger_rgb(self, finger: str) -> tuple[float, float, float]:
        """Colour the finger is drawn in, [0, 1]."""
        return tuple(self.render.get(f"{finger}_rgb", FINGER_RGB[finger]))

    def rows(self, split: str | None) -> np.ndarray:
        """Row indices of a split (``None`` or ``all``: every row)."""
        if split in (None, "all"):
            return np.arange(len(self.configs))
        rows = np.flatnonzero(self.configs["split"].to_numpy() == split)
        if len(rows) == 0:
            present = sorted(set(self.configs["split"]))
            raise UserError(
                f"{self.root / CONFIGS}: no configuration in split {split!r} "
                f"(splits present: {', '.join(present)})"
            )
        return rows

    def image_path(self, row: int) -> Path:
        """Path of a configuration's image."""
        return self.root / IMAGES / str(self.configs["image"].iat[row])

    def mask_path(self, row: int) -> Path:
        """Path of a configuration's mask (`--masks`; named as its image), which may not exist."""
        return self.root / MASKS / str(self.configs["image"].iat[row])

    def has_boxes(self, finger: str) -> bool:
        """Whether the finger's bounding-box columns exist and are all finite."""
        cols = box_columns(finger)
        if not all(c in self.configs for c in cols):
            return False
        return bool(np.isfinite(self.configs[cols].to_numpy(float)).all())

    def box(self, row: int, finger: str) -> np.ndarray | None:
        """(x, y, w, h) of the drawn finger in pixels (top-left origin), or None if absent."""
        cols = box_columns(finger)
        if not all(c in self.configs for c in cols):
            return None
        b = self.configs.loc[row, cols].to_numpy(float)
        return b if np.isfinite(b).all() else None

    def mean_label(self, finger: str) -> np.ndarray:
        """(N, 2) renormalised mean unit label per configuration ((0, -1) if the mean is 0)."""
        out = np.empty((len(self.configs), 2))
        for i, cone in enumerate(self.cones[finger]):
            m = cone.mean(axis=0)
            norm = np.hypot(m[0], m[1])
            out[i] = m / norm if norm > 1e-12 else (0.0, -1.0)
        return out

    def image_fingerprint(self) -> str:
        """SHA-256 (hex) of the manifest, the configuration table and every image's bytes: what
        is seen of a configuration (its labels left out; the key of caches of image content)."""
        if self._image_fingerprint is None:
            h = hashlib.sha256()
            for name in (MANIFEST, CONFIGS):
                h.update(_read_bytes(self.root / name))
            for row in range(len(self.configs)):
                path = self.image_path(row)
                h.update(path.name.encode())
                h.update(path.read_bytes() if path.is_file() else b"<missing>")
            self._image_fingerprint = h.hexdigest()
        return self._image_fingerprint

    def fingerprint(self) -> str:
        """SHA-256 (hex) of the whole dataset: `image_fingerprint` and the labels
        (``presses.parquet``), so that labels changed after training are another dataset."""
        if self._fingerprint is None:
            h = hashlib.sha256(self.image_fingerprint().encode())
            h.update(_read_bytes(self.root / PRESSES))
            self._fingerprint = h.hexdigest()
        return self._fingerprint


def _read_bytes(path: Path) -> bytes:
    check_file(path)
    try:
        return path.read_bytes()
    except OSError as exc:
        raise UserError(f"{path}: unreadable ({exc.strerror or exc})") from None


def _require(df: pd.DataFrame, cols: list[str], path: Path) -> None:
    missing = [c for c in cols if c not in df.columns]
    if missing:
        raise UserError(f"{path}: missing column(s) {', '.join(missing)}")


def read_manifest(root: Path, require_complete: bool = True) -> dict:
    """The parsed `manifest.json` of a dataset directory.

    Raises:
        UserError: no such folder, no manifest (an interrupted run is named as such), invalid
            JSON or not an object, a `format_version` this version does not read, or (with
            `require_complete`) a dataset not marked complete.
    """
    man_path = root / MANIFEST
    if not root.is_dir():
        raise UserError(f"{root}: not a dataset directory")
    if not man_path.exists():
        if (root / PARTIAL).exists():
            raise UserError(f"{root}: not a complete dataset: an interrupted run (resume it with "
                            "`vistac generate --resume`)")
        raise UserError(f"{man_path}: missing (not a vistac dataset?)")
    try:
        manifest = json.loads(_read_bytes(man_path))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"{man_path}: not valid JSON ({exc}); make the dataset again") from None
    if not isinstance(manifest, dict):
        raise UserError(f"{man_path}: not a JSON object; make the dataset again")
    version = manifest.get("format_version")
    if type(version) is not int or version not in READ_VERSIONS:
        what = "missing" if version is None else f"{str(version)[:40]!r}"
        newer = type(version) is int and version > FORMAT_VERSION
        raise UserError(f"{man_path}: format_version {what} is not one this vistac reads "
                        f"({', '.join(map(str, READ_VERSIONS))}); "
                        + ("update vistac" if newer else "make the dataset again with this vistac"))
    if require_complete and manifest.get("complete") is not True:
        raise UserError(
            f"{man_path}: dataset is not complete (generation unfinished or interrupted; "
            "finish it with `vistac generate --resume` first)"
        )
    return manifest


LABEL_TOLERANCE = 1e-3
"""Largest difference of a label's length from 1 (labels are written as float64 unit vectors)."""


def _read_table(path: Path, types: dict[str, str]) -> pd.DataFrame:
    """A dataset table, its columns of `types` (name -> ``int``, ``float`` or ``str``) present
    and of that kind.

    Raises:
        UserError: a missing, truncated or non-Parquet file, a missing or mistyped column.
    """
    if not path.is_file():
        raise UserError(f"{path}: missing; make the dataset again")
    try:
        frame = pd.read_parquet(path)
    except Exception as exc:  # pyarrow's errors of a damaged file have no common base
        reason = " ".join(str(exc).split())[:160] or type(exc).__name__
        raise UserError(f"{path}: unreadable ({reason}); make the dataset again") from None
    _require(frame, list(types), path)
    check = {"int": pd.api.types.is_integer_dtype, "float": pd.api.types.is_numeric_dtype,
             "str": lambda s: pd.api.types.is_string_dtype(s) or s.dtype == object}
    for col, kind in types.items():
        series = frame[col]
        ok = check[kind](series) and not pd.api.types.is_bool_dtype(series)
        if ok and kind == "str":
            ok = bool(series.map(lambda v: isinstance(v, str)).all())
        if not ok:
            raise UserError(f"{path}: column {col} holds {series.dtype}, not {kind} values; "
                            "make the dataset again")
    return frame


def _check_image_names(configs: pd.DataFrame, path: Path) -> None:
    """Every image is a plain file name (no folder part, nothing empty) and appears once."""
    names = configs["image"]
    bad = names.map(lambda n: not n or "/" in n or "\\" in n or n in (".", ".."))
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise UserError(f"{path}: row {i}: image {names.iat[i][:80]!r} is not a file name in "
                        f"{IMAGES}/")
    if names.duplicated().any():
        raise UserError(f"{path}: image {names[names.duplicated()].iat[0]!r} belongs to more "
                        "than one configuration")


def open_tables(root: str | Path, require_complete: bool = True) -> DatasetTables:
    """Read and check a dataset directory.

    Args:
        root: The dataset directory (docs/dataset-format.md layout).
        require_complete: Refuse a dataset whose manifest lacks ``"complete": true``.

    Returns:
        The checked tables, configurations sorted by `config_id`, with the per-finger cones.

    Raises:
        UserError: A missing, damaged or mistyped file or column, an unfinished dataset, a
            configuration without presses, presses of an unknown configuration, a non-finite or
            non-unit label (file, row and reason in the message).
    """
    root = Path(root)
    manifest = read_manifest(root, require_complete)
    cpath, ppath = root / CONFIGS, root / PRESSES
    configs = _read_table(cpath, {"config_id": "int", "image": "str", "split": "str"})
    presses = _read_table(ppath, {"config_id": "int", "repeat": "int",
                                  **dict.fromkeys(LABEL_COLUMNS, "float")})
    if configs["config_id"].duplicated().any():
        dup = configs.loc[configs["config_id"].duplicated(), "config_id"].iat[0]
        raise UserError(f"{cpath}: config_id {dup} appears more than once")
    bad_split = ~configs["split"].isin(SPLITS)
    if bad_split.any():
        i = int(np.flatnonzero(bad_split)[0])
        raise UserError(
            f"{cpath}: row {i}: split {str(configs['split'].iat[i])[:40]!r} is not "
            "train/val/test"
        )
    _check_image_names(configs, cpath)
    configs = configs.sort_values("config_id", kind="stable").reset_index(drop=True)
    labels = presses[LABEL_COLUMNS].to_numpy(float)
    if not np.isfinite(labels).all():
        i = int(np.flatnonzero(~np.isfinite(labels).all(axis=1))[0])
        raise UserError(f"{ppath}: row {i}: non-finite unit label")
    for f in FINGERS:
        r_y, r_z = label_columns(f)
        norms = np.hypot(presses[r_y], presses[r_z]).to_numpy()
        bad = np.abs(norms - 1) > LABEL_TOLERANCE
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise UserError(f"{ppath}: row {i}: ({f}) label (r_y, r_z) is not a unit vector "
                            f"(length {norms[i]:.4g})")
    known = set(configs["config_id"].tolist())
    stray = sorted(set(presses["config_id"].tolist()) - known)
    if stray:
        raise UserError(f"{ppath}: presses of unknown config_id {stray[0]}")
    if presses[["config_id", "repeat"]].duplicated().any():
        i = int(np.flatnonzero(presses[["config_id", "repeat"]].duplicated().to_numpy())[0])
        raise UserError(f"{ppath}: row {i}: config_id {presses['config_id'].iat[i]} repeat "
                        f"{presses['repeat'].iat[i]} appears more than once")
    presses = presses.sort_values(["config_id", "repeat"], kind="stable").reset_index(drop=True)
    # presses are sorted by config_id: each configuration's presses are one run of rows
    pids, cids = presses["config_id"].to_numpy(), configs["config_id"].to_numpy()
    starts, ends = np.searchsorted(pids, cids, "left"), np.searchsorted(pids, cids, "right")
    if (starts == ends).any():
        row = int(np.flatnonzero(starts == ends)[0])
        raise UserError(f"{cpath}: row {row}: config_id {cids[row]} has no presses")
    cones: dict[str, list[np.ndarray]] = {}
    for f in FINGERS:
        labels = presses[label_columns(f)].to_numpy(float)
        cones[f] = [labels[a:b].copy() for a, b in zip(starts.tolist(), ends.tolist(),
                                                        strict=True)]
    return DatasetTables(root, manifest, configs, presses, cones)
