"""What a model sees: image views of a configuration, registered by name, rendered per batch.

A view turns one decoded top-view image (plus what is known about it: finger boxes, located
fingertips) and one draw of augmentation parameters into the model's input. Nothing is cached
but the per-configuration fingertip table: images are decoded and rendered batch by batch, so
memory and disk stay flat however many configurations or augmentations a run uses.

Views:

- ``tip``: per finger, a square crop centred on the front of the fingertip and
  rotated so that the finger points up (`vistac_learn.data.fingertips` finds tip and axis in the
  image), side `span` fingertip radii, in colour. The thumb's crop is mirrored left-right, so
  that both fingers' labels read in the index finger's convention (the thumb's y axis is the
  index finger's mirrored, docs/dataset-format.md) and one network serves both. Output (F, 3, S, S).
- ``pinch`` (the default, `vistac_learn.data.pinch_view`): both fingers' ``tip`` crops, the
  numbers relating the two crops' frames and, where the dataset knows them, the simulator's
  contact geometry as auxiliary targets (`View.aux`). Output (2, 3, S, S) whichever finger is
  the target.
- The study's ``<color|edge>-<base|crop|index|thumb>`` (docs/study.md section 4,
  `vistac_learn.data.variants`): the whole image rotated, optionally cut to the finger boxes
  (the simulator's, or where the dataset has none, as after `vistac ingest`, each finger's
  located in the image: `vistac_learn.data.located_boxes`). Output (C, S, S).

Augmentations (`Aug`, drawn per sample by `vistac_learn.data.augment`) and what they do to the
labels, which are forces in each fingertip's own frame:

- rotation of the top view (study views): the labels do not change;
- mirror (left-right flip of the view): r_y changes sign, r_z does not. A mirrored scene is a
  physically valid scene whose forces are the mirror image, and a fingertip frame built by the
  same rule from the mirrored finger has its y axis mirrored too (tested against the simulator);
- crop jitter (tip view): the crop centre moves by a fraction of a radius, its angle by a few
  degrees and its side by a few per cent, as errors of the fingertip locator would; labels
  unchanged;
- appearance (`vistac_learn.data.perturb`): the image made to look more like a photograph
  (textures, overlay style, light, tilt, camera); labels unchanged, fingertips and boxes moved
  with a tilt.
"""

from __future__ import annotations

import numpy as np

from vistac.dataset import FINGERS
from vistac.errors import UserError
from vistac_learn.data.fingertips import Fingertip
from vistac_learn.data.pinch_view import PinchView
from vistac_learn.data.variants import VARIANTS, VariantCfg, auto_canny, render_variant
from vistac_learn.data.view_base import (
    IDENTITY,
    PINCH_VIEW,
    TIP_VIEW,
    Aug,
    SampleInfo,
    TipCfg,
    View,
    crop_centre,
    tip_crop,
    to_crop_frame,
)

VIEWS = (PINCH_VIEW, TIP_VIEW, *VARIANTS)
SIDE_FEATURES = 5  # per finger, tip view: direction (2) and log distance (1) to the other
# fingertip, the other finger's axis (2)


def mirror_labels(labels: np.ndarray) -> np.ndarray:
    """Labels (..., 2) = (r_y, r_z) of the mirrored view: (-r_y, r_z)."""
    out = np.array(labels, dtype=np.float64, copy=True)
    out[..., 0] *= -1
    return out


def pair_features(this: Fingertip, other: Fingertip, aug: Aug, mirror: bool) -> np.ndarray:
    """`SIDE_FEATURES` numbers: where the other fingertip is, seen from this one's crop."""
    if not (this.ok and other.ok):
        return np.zeros(SIDE_FEATURES, np.float32)
    d = other.tip - this.tip
    dist = max(float(np.hypot(*d)), 1e-6)
    u = to_crop_frame(d / dist, this, aug, mirror)
    a = to_crop_frame(other.axis, this, aug, mirror)
    return np.array([u[0], u[1], np.log(dist / this.radius), a[0], a[1]], np.float32)


class TipView(View):
    """Per finger, the fingertip-centred, finger-aligned colour crop (thumb mirrored)."""

    name, channels, per_finger, needs_tips = TIP_VIEW, 3, True, True
    side_features = SIDE_FEATURES

    def __init__(self, cfg: TipCfg = TipCfg()):
        self.cfg = cfg

    def render(self, rgb, info, aug, size, fingers):
        return np.stack([
            tip_crop(rgb, info.tips[f], size, self.cfg, aug, mirror=(f == "thumb") != aug.mirror)
            for f in fingers
        ])

    def side(self, info, aug, fingers):
        other = {"index": "thumb", "thumb": "index"}
        return np.stack([
            pair_features(info.tips[f], info.tips[other[f]], aug, (f == "thumb") != aug.mirror)
            for f in fingers
        ])


class StudyView(View):
    """One of the study's variants (docs/study.md section 4), rendered at the sample's angle."""

    def __init__(self, name: str, margin: float = 0.05):
        self.cfg = VariantCfg(name, margin=margin)
        self.name = name
        self.channels = self.cfg.channels
        self.needs_boxes = self.cfg.region_fingers

    def render(self, rgb, info, aug, size, fingers):
        if any(info.boxes.get(f) is None for f in self.needs_boxes):
            # a finger not found in an image without boxes (`vistac_learn.data.located_boxes`):
            # no input, the sample is masked out (`SampleSet.found`)
            return np.zeros((self.channels, size, size), np.uint8)
        cfg = VariantCfg(self.cfg.name, size, self.cfg.margin)
        edges = auto_canny(rgb, cfg.canny_low_ratio, cfg.canny_floor) if cfg.mode == "edge" \
            else None
        out = render_variant(rgb, info.boxes, aug.angle, cfg, info.table_rgb, edges)
        return np.ascontiguousarray(out[:, :, ::-1]) if aug.mirror else out


def make_view(name: str, margin: float = 0.05, tip: TipCfg = TipCfg()) -> View:
    """The view registered under `name` (`VIEWS`)."""
    if name == TIP_VIEW:
        return TipView(tip)
    if name == PINCH_VIEW:
        return PinchView(tip)
    if name in VARIANTS:
        return StudyView(name, margin)
    raise UserError(f"unknown view {name!r}; choose from {', '.join(VIEWS)}")


__all__ = ["Aug", "IDENTITY", "FINGERS", "PINCH_VIEW", "SIDE_FEATURES", "SampleInfo", "StudyView",
           "TipCfg", "TipView", "VIEWS", "View", "crop_centre", "make_view", "mirror_labels",
           "pair_features", "tip_crop"]
