"""Reading a vistac dataset directory and serving (configuration, rotation) training pairs.

A dataset directory (contracts.md) holds `manifest.json`, `configs.parquet` (one row per grasp
configuration), `presses.parquet` (one row per press) and `images/`. `open_dataset` reads and
checks it; `PairDataset` is the torch Dataset the trainer and the evaluator use.

Items are (configuration, rotation) pairs: every configuration's image is seen under each angle
of a `RotationCfg` (the study's 20 fixed rotations of 18 degrees, or per-configuration random
angles drawn once from a seed). The label is unchanged by the rotation, because forces are in the
fingertip frame. The unit labels of all repeats of a configuration travel with it (`cones`), so
the evaluation can build the cone.

How repeats become training targets (`target`):

- ``"mean"`` (default): the mean of the repeats' unit vectors, renormalised to unit length (one
  target per configuration, as the study's one label per image; a zero mean falls back to
  (0, -1), straight against the approach). It is the least noisy target and the least-squares
  optimum of the study's MSE over the repeats, up to the renormalisation.
- ``"press"``: one repeat per (configuration, rotation) pair, drawn anew each epoch from a
  generator seeded by (seed, epoch); the target carries the label noise, as a single press would.
- ``"all"``: every press is its own pair (configurations x rotations x repeats items per epoch).

Splits are whole configurations, read from the `split` column (a by-object split is made at
generation time; `object_id` is there to check it).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd
import torch

from vistac_sim.errors import UserError

FINGERS = ("index", "thumb")
TARGETS = ("mean", "press", "all")
DEFAULT_TABLE_RGB = (0.81, 0.81, 0.81)
DEFAULT_FINGER_RGB = {"index": (0.0, 0.85, 0.0), "thumb": (0.9, 0.0, 0.0)}


def fingers_of(finger: str) -> tuple[str, ...]:
    """Fingers named by a `--finger` option: ``index``, ``thumb`` or ``both``."""
    if finger == "both":
        return FINGERS
    if finger in FINGERS:
        return (finger,)
    raise UserError(f"--finger must be index, thumb or both, not {finger!r}")


@dataclass(frozen=True)
class RotationCfg:
    """The rotation angles each configuration's image is shown at.

    Attributes:
        mode: ``fixed`` (angles k * step_deg, k < n; the study: n=20, step 18), ``random``
            (n angles uniform in [0, 360) per configuration, drawn once from seed and the
            configuration id) or ``none`` (the unrotated image only).
        n: Number of angles per configuration.
        step_deg: Step of the fixed angles, degrees counter-clockwise in the image.
        seed: Seed of the random angles.
    """

    mode: Literal["fixed", "random", "none"] = "fixed"
    n: int = 20
    step_deg: float = 18.0
    seed: int = 0

    def angles(self, config_ids: np.ndarray) -> np.ndarray:
        """Angles in degrees, shape (len(config_ids), count)."""
        ids = np.asarray(config_ids, dtype=np.int64)
        if self.mode == "none":
            return np.zeros((len(ids), 1))
        if self.n < 1:
            raise UserError(f"rotation count must be >= 1, not {self.n}")
        if self.mode == "fixed":
            return np.tile(np.arange(self.n) * self.step_deg, (len(ids), 1))
        if self.mode == "random":
            return np.stack(
                [np.random.default_rng([self.seed, int(c)]).uniform(0, 360, self.n) for c in ids]
            ).reshape(len(ids), self.n)
        raise UserError(f"rotation mode must be fixed, random or none, not {self.mode!r}")

    @property
    def count(self) -> int:
        """Number of angles per configuration."""
        return 1 if self.mode == "none" else self.n


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

    @property
    def render(self) -> dict:
        """The manifest's render config (may be empty for ingested data)."""
        return dict((self.manifest.get("config") or {}).get("render") or {})

    @property
    def table_rgb(self) -> tuple[float, float, float]:
        """Background colour of the images in [0, 1]."""
        return tuple(self.render.get("table_rgb", DEFAULT_TABLE_RGB))

    def finger_rgb(self, finger: str) -> tuple[float, float, float]:
        """Colour the finger is drawn in, [0, 1]."""
        return tuple(self.render.get(f"{finger}_rgb", DEFAULT_FINGER_RGB[finger]))

    def rows(self, split: str | None) -> np.ndarray:
        """Row indices of a split (``None`` or ``all``: every row)."""
        if split in (None, "all"):
            return np.arange(len(self.configs))
        rows = np.flatnonzero(self.configs["split"].to_numpy() == split)
        if len(rows) == 0:
            present = sorted(set(self.configs["split"]))
            raise UserError(
                f"{self.root / 'configs.parquet'}: no configuration in split {split!r} "
                f"(splits present: {', '.join(present)})"
            )
        return rows

    def image_path(self, row: int) -> Path:
        """Path of a configuration's image."""
        return self.root / "images" / str(self.configs["image"].iat[row])

    def has_boxes(self, finger: str) -> bool:
        """Whether the finger's bounding-box columns exist and are all finite."""
        cols = [f"bbox_{finger}_{k}" for k in "xywh"]
        if not all(c in self.configs for c in cols):
            return False
        return bool(np.isfinite(self.configs[cols].to_numpy(float)).all())

    def box(self, row: int, finger: str) -> np.ndarray | None:
        """(x, y, w, h) of the drawn finger in pixels (top-left origin), or None if absent."""
        cols = [f"bbox_{finger}_{k}" for k in "xywh"]
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

    def fingerprint(self) -> str:
        """SHA-256 (hex) of the manifest, the configuration table and every image's bytes."""
        if self._fingerprint is None:
            h = hashlib.sha256()
            for name in ("manifest.json", "configs.parquet"):
                h.update((self.root / name).read_bytes())
            for row in range(len(self.configs)):
                path = self.image_path(row)
                h.update(path.name.encode())
                h.update(path.read_bytes() if path.exists() else b"<missing>")
            self._fingerprint = h.hexdigest()
        return self._fingerprint


def _require(df: pd.DataFrame, cols: list[str], path: Path) -> None:
    missing = [c for c in cols if c not in df.columns]
    if missing:
        raise UserError(f"{path}: missing column(s) {', '.join(missing)}")


def open_dataset(root: str | Path, require_complete: bool = True) -> DatasetTables:
    """Read and check a dataset directory.

    Args:
        root: The dataset directory (contracts.md layout).
        require_complete: Refuse a dataset whose manifest lacks ``"complete": true``.

    Returns:
        The checked tables, configurations sorted by `config_id`, with the per-finger cones.

    Raises:
        UserError: A missing file or column, an unfinished dataset, a configuration without
            presses, a non-finite or non-unit label (file, row and reason in the message).
    """
    root = Path(root)
    man_path = root / "manifest.json"
    if not root.is_dir():
        raise UserError(f"{root}: not a dataset directory")
    if not man_path.exists():
        raise UserError(f"{man_path}: missing (not a vistac dataset?)")
    try:
        manifest = json.loads(man_path.read_text())
    except json.JSONDecodeError as exc:
        raise UserError(f"{man_path}: not valid JSON ({exc})") from exc
    if require_complete and manifest.get("complete") is not True:
        raise UserError(
            f"{man_path}: dataset is not complete (generation unfinished or interrupted; "
            "finish it with `vistac generate --resume` first)"
        )
    cpath, ppath = root / "configs.parquet", root / "presses.parquet"
    for p in (cpath, ppath):
        if not p.exists():
            raise UserError(f"{p}: missing")
    configs = pd.read_parquet(cpath)
    presses = pd.read_parquet(ppath)
    _require(configs, ["config_id", "image", "split"], cpath)
    label_cols = [f"r_{a}_{f}" for f in FINGERS for a in "yz"]
    _require(presses, ["config_id", "repeat", *label_cols], ppath)
    if configs["config_id"].duplicated().any():
        dup = configs.loc[configs["config_id"].duplicated(), "config_id"].iat[0]
        raise UserError(f"{cpath}: config_id {dup} appears more than once")
    bad_split = ~configs["split"].isin(["train", "val", "test"])
    if bad_split.any():
        i = int(np.flatnonzero(bad_split)[0])
        raise UserError(
            f"{cpath}: row {i}: split {configs['split'].iat[i]!r} is not train/val/test"
        )
    configs = configs.sort_values("config_id", kind="stable").reset_index(drop=True)
    labels = presses[label_cols].to_numpy(float)
    if not np.isfinite(labels).all():
        i = int(np.flatnonzero(~np.isfinite(labels).all(axis=1))[0])
        raise UserError(f"{ppath}: row {i}: non-finite unit label")
    for f in FINGERS:
        norms = np.hypot(presses[f"r_y_{f}"], presses[f"r_z_{f}"]).to_numpy()
        bad = np.abs(norms - 1) > 1e-3
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise UserError(f"{ppath}: row {i}: ({f}) label (r_y, r_z) is not a unit vector")
    known = set(configs["config_id"].tolist())
    stray = sorted(set(presses["config_id"].tolist()) - known)
    if stray:
        raise UserError(f"{ppath}: presses of unknown config_id {stray[0]}")
    presses = presses.sort_values(["config_id", "repeat"], kind="stable").reset_index(drop=True)
    groups = {int(k): g.index.to_numpy() for k, g in presses.groupby("config_id")}
    cones: dict[str, list[np.ndarray]] = {f: [] for f in FINGERS}
    for row, cid in enumerate(configs["config_id"].tolist()):
        idx = groups.get(int(cid))
        if idx is None:
            raise UserError(f"{cpath}: row {row}: config_id {cid} has no presses")
        for f in FINGERS:
            cones[f].append(presses.loc[idx, [f"r_y_{f}", f"r_z_{f}"]].to_numpy(float))
    return DatasetTables(root, manifest, configs, presses, cones)


class PairDataset(torch.utils.data.Dataset):
    """(configuration, rotation[, press]) pairs of one split, images from a variant cache.

    Args:
        tables: The dataset.
        rows: Configuration rows of the split.
        images: uint8 array (N_all, R, C, S, S) of variant images for every configuration row
            of `tables` (a memory map from `variants.variant_images`).
        fingers: Fingers whose labels form the target, in order (2 values per finger).
        target: ``mean``, ``press`` or ``all`` (see the module docstring).
        seed: Seed of the per-epoch press draw (``press``).

    Items are dicts: ``image`` (float32 C x S x S in [0, 1]), ``target`` (float32, 2 per finger),
    ``row`` (configuration row), ``rot`` (rotation index).
    """

    def __init__(
        self,
        tables: DatasetTables,
        rows: np.ndarray,
        images: np.ndarray,
        fingers: tuple[str, ...],
        target: str = "mean",
        seed: int = 0,
    ):
        if target not in TARGETS:
            raise UserError(f"target must be one of {', '.join(TARGETS)}, not {target!r}")
        self.tables, self.images, self.fingers = tables, images, tuple(fingers)
        self.target, self.seed = target, seed
        self.rows = np.asarray(rows, dtype=np.int64)
        n_rot = images.shape[1]
        rr, kk = np.meshgrid(self.rows, np.arange(n_rot), indexing="ij")
        self.item_row, self.item_rot = rr.ravel(), kk.ravel()
        self.item_press = np.full(len(self.item_row), -1, dtype=np.int64)
        if target == "all":
            reps = np.array([len(tables.cones[fingers[0]][r]) for r in self.item_row])
            self.item_row = np.repeat(self.item_row, reps)
            self.item_rot = np.repeat(self.item_rot, reps)
            self.item_press = np.concatenate([np.arange(k) for k in reps]).astype(np.int64)
        self._mean = np.concatenate([tables.mean_label(f) for f in self.fingers], axis=1)
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        """Select the epoch whose press draw ``target="press"`` uses."""
        self.epoch = int(epoch)

    def __len__(self) -> int:
        return len(self.item_row)

    def targets(self, items: np.ndarray) -> np.ndarray:
        """(len(items), 2 * fingers) float32 targets of the given item indices."""
        items = np.asarray(items, dtype=np.int64)
        rows = self.item_row[items]
        if self.target == "mean":
            return self._mean[rows].astype(np.float32)
        press = self.item_press[items]
        if self.target == "press":
            rng = np.random.default_rng([self.seed, self.epoch])
            draws = rng.random(len(self.item_row))[items]
            press = np.array(
                [int(d * len(self.tables.cones[self.fingers[0]][r])) for d, r in zip(
                    draws, rows, strict=True)]
            )
        out = [
            np.stack([self.tables.cones[f][r][k] for r, k in zip(rows, press, strict=True)])
            for f in self.fingers
        ]
        return np.concatenate(out, axis=1).astype(np.float32)

    def batch(self, items: np.ndarray) -> dict[str, torch.Tensor]:
        """A whole batch at once (faster than collating single items)."""
        items = np.asarray(items, dtype=np.int64)
        rows, rots = self.item_row[items], self.item_rot[items]
        imgs = np.asarray(self.images[rows, rots], dtype=np.float32) / 255.0
        return {
            "image": torch.from_numpy(imgs),
            "target": torch.from_numpy(self.targets(items)),
            "row": torch.from_numpy(rows),
            "rot": torch.from_numpy(rots),
        }

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        b = self.batch(np.array([i]))
        return {k: v[0] for k, v in b.items()}
