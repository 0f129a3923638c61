"""Finger boxes where a dataset has none: each drawn finger's box read off its image.

The study's views (`vistac_learn.data.variants`) crop or draw by the finger boxes
(``bbox_<finger>_x|y|w|h``, `vistac.dataset.schema.box_columns`). A generated dataset has the
simulator's exact boxes; `vistac ingest` leaves them NaN (only the simulator knows them). Here a
finger's box is the extent of its mask as the fingertip locator finds it
(`vistac_learn.data.finger_masks`, inside the learned segmenter's finger on an image that is not
a flat render, as `vistac_learn.data.locator` does), in the simulator's convention: pixels, top-left
origin, a mask covering pixel columns u0 .. u1 spans x = u0, w = u1 - u0 + 1 (pixel u covers
[u, u + 1] of the image's continuous coordinates, as the simulator clips its boxes to
[0, size]).

`box_table` gives the boxes of every configuration: the dataset's own where they are finite
(byte for byte), located ones elsewhere (cached like the fingertips, one small Parquet table). A
finger that is not found has no box (``ok`` False, with the reason): its samples are masked
out and counted like the fingertips not found (`vistac_learn.data.tip_coverage`,
``--max-missing-pct``).

Measured on a generated dataset (tests/learn/test_located_boxes.py): the located boxes lie
within 2.3 px of the simulator's on every side, 0.23 px on average (24 images, 48 boxes).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from vistac.dataset import FINGERS, DatasetTables
from vistac.dataset.files import remove_stale_temporaries, write_table
from vistac.errors import UserError
from vistac.progress import bar as progress_bar
from vistac_learn.data.finger_masks import explained_finger_masks
from vistac_learn.data.fingertip_table import cache_path
from vistac_learn.data.locator import flat_render, learned_fit, refine_regions
from vistac_learn.data.locator_cfg import LocatorCfg
from vistac_learn.data.variants import read_rgb

BOX_VERSION = 1  # bump when the located boxes change; invalidates cached tables
BOX_FIELDS = ("x", "y", "w", "h")


@dataclass(frozen=True)
class LocatedBox:
    """One finger's box (x, y, w, h in pixels, top-left origin), or why there is none."""

    box: np.ndarray | None
    reason: str = ""

    @property
    def ok(self) -> bool:
        """Whether the finger has a box."""
        return self.box is not None


def mask_box(mask: np.ndarray) -> np.ndarray | None:
    """(x, y, w, h) of a mask's pixels in the simulator's box convention (pixel u covers
    [u, u + 1]), None for an empty mask."""
    vs, us = np.nonzero(mask)
    if not len(us):
        return None
    return np.array([us.min(), vs.min(), us.max() - us.min() + 1, vs.max() - vs.min() + 1],
                    float)


def located_masks(rgb: np.ndarray, colours: dict[str, tuple], cfg: LocatorCfg = LocatorCfg()
                  ) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Each finger's mask as the locator finds it (`vistac_learn.data.locator`), and why a
    finger has none: its colour alone on a flat render or with the segmenter off; the
    segmenter's finger with the segmenter ``always``; otherwise the colour inside the
    segmenter's finger (the segmenter's own mask where the colour gives none there)."""
    if cfg.segmenter == "off" or flat_render(rgb):
        return explained_finger_masks(rgb, colours, cfg)
    learned, masks = learned_fit(rgb, colours, cfg)
    if cfg.segmenter == "always":
        return masks, {f: "" if masks[f].any() else learned[f].reason for f in masks}
    refined, why = explained_finger_masks(rgb, colours, cfg, refine_regions(masks, cfg))
    for f, m in masks.items():
        if why[f] and m.any():
            refined[f], why[f] = m, ""
    return refined, why


def locate_boxes(rgb: np.ndarray, colours: dict[str, tuple], cfg: LocatorCfg = LocatorCfg()
                 ) -> dict[str, LocatedBox]:
    """Every finger's box in an (H, W, 3) uint8 RGB image: the extent of its located mask
    (`located_masks`, `mask_box`)."""
    masks, why = located_masks(rgb, colours, cfg)
    out = {}
    for f, m in masks.items():
        b = None if why[f] else mask_box(m)
        out[f] = LocatedBox(b, "" if b is not None else why[f] or "no pixels of its colour")
    return out


class BoxTable:
    """The finger boxes of every configuration of a dataset (one row per configuration).

    Columns: ``<finger>_<x|y|w|h>``, ``<finger>_ok`` and ``<finger>_reason`` (the fingertip
    table's layout, so that `vistac_learn.data.tip_coverage` counts the boxes not found too).
    """

    def __init__(self, frame: pd.DataFrame):
        self.frame = frame

    def get(self, row: int, finger: str) -> LocatedBox:
        """The box of one configuration row."""
        fr = self.frame
        if not bool(fr[f"{finger}_ok"].iat[row]):
            return LocatedBox(None, str(fr[f"{finger}_reason"].iat[row]))
        return LocatedBox(np.array([float(fr[f"{finger}_{k}"].iat[row]) for k in BOX_FIELDS]))

    def box(self, row: int, finger: str) -> np.ndarray | None:
        """(x, y, w, h) of one configuration row's finger, None where it was not found."""
        return self.get(row, finger).box

    def failures(self, rows: np.ndarray, finger: str) -> int:
        """Configurations among `rows` whose finger has no box."""
        return int((~self.frame[f"{finger}_ok"].to_numpy()[rows]).sum())


def missing_boxes(tables: DatasetTables, fingers: tuple[str, ...]) -> tuple[str, ...]:
    """Those of `fingers` whose box columns the dataset lacks or has non-finite somewhere."""
    return tuple(f for f in fingers if not tables.has_boxes(f))


def _record(config_id: int, boxes: dict[str, LocatedBox]) -> dict:
    rec = {"config_id": config_id}
    for f in FINGERS:
        b = boxes[f]
        vals = b.box if b.ok else np.full(4, np.nan)
        rec |= dict(zip((f"{f}_{k}" for k in BOX_FIELDS), map(float, vals), strict=True))
        rec |= {f"{f}_ok": b.ok, f"{f}_reason": b.reason}
    return rec


def _row_boxes(tables: DatasetTables, row: int, colours: dict[str, tuple], cfg: LocatorCfg
               ) -> dict[str, LocatedBox]:
    """A row's boxes: the dataset's own where finite, the others located in its image."""
    own = {f: tables.box(row, f) for f in FINGERS}
    if all(b is not None for b in own.values()):
        return {f: LocatedBox(b) for f, b in own.items()}
    found = locate_boxes(read_rgb(tables.image_path(row)), colours, cfg)
    return {f: LocatedBox(own[f]) if own[f] is not None else found[f] for f in FINGERS}


def box_table(tables: DatasetTables, cfg: LocatorCfg = LocatorCfg(), cache_dir=None,
              progress: bool = False) -> BoxTable:
    """The finger boxes of every configuration: the dataset's own where finite, located in the
    image elsewhere (`locate_boxes`); located ones are cached as a
    small Parquet table beside the fingertips' (same key: the locator and the images).

    Raises:
        UserError: An unreadable image or an unwritable cache folder.
    """
    path = cache_path(tables, cfg, Path(cache_dir) if cache_dir is not None else None,
                      f"boxes-v{BOX_VERSION}")
    if path.is_file():
        try:
            frame = pd.read_parquet(path)
            if len(frame) == len(tables.configs) and \
                    (frame["config_id"].to_numpy() == tables.configs["config_id"].to_numpy()).all():
                return BoxTable(frame)
        except Exception:  # a damaged file: located again and rewritten
            pass
    colours = {f: tables.finger_rgb(f) for f in FINGERS}
    cids = tables.configs["config_id"].to_numpy()
    recs = []
    for row in progress_bar(range(len(tables.configs)), desc="locating finger boxes",
                            unit="img", enabled=progress, leave=False):
        recs.append(_record(int(cids[row]), _row_boxes(tables, row, colours, cfg)))
    frame = pd.DataFrame(recs)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(path.parent)
        write_table(path, frame)
    except OSError as exc:
        raise UserError(f"{path.parent}: cannot write the finger-box cache ({exc}); "
                        "choose another with --cache-dir") from exc
    return BoxTable(frame)


__all__ = ["BOX_FIELDS", "BoxTable", "LocatedBox", "box_table", "locate_boxes", "located_masks",
           "mask_box", "missing_boxes"]
