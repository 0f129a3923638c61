"""Serving (configuration, rotation) training pairs of a dataset (read by `vistac.dataset`).

`PairDataset` is the torch Dataset the trainer and the evaluator use.

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

from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch

from vistac.dataset import FINGERS, DatasetTables
from vistac.errors import UserError

TARGETS = ("mean", "press", "all")
FINGER_CHOICES = (*FINGERS, "both")  # the values of a `--finger` option
ROTATION_MODES = ("fixed", "random", "none")


def fingers_of(finger: str) -> tuple[str, ...]:
    """Fingers named by a `--finger` option: ``index``, ``thumb`` or ``both``."""
    if finger == "both":
        return FINGERS
    if finger in FINGERS:
        return (finger,)
    raise UserError(f"--finger must be {', '.join(FINGER_CHOICES)}, not {finger!r}")


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


class PairDataset(torch.utils.data.Dataset):
    """(configuration, rotation[, press]) pairs of one split, images from a variant cache.

    Args:
        tables: The dataset.
        rows: Configuration rows of the split.
        images: uint8 array (N_all, R, C, S, S) of variant images for every configuration row
            of `tables` (a memory map from `cache.variant_images`).
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
