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
  `vistac_learn.data.variants`): the whole image rotated, optionally cut to the finger boxes.
  Output (C, S, S).

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

from dataclasses import dataclass, field

import cv2
import numpy as np

from vistac.dataset import FINGERS
from vistac.errors import UserError
from vistac_learn.data.fingertips import Fingertip
from vistac_learn.data.variants import VARIANTS, VariantCfg, auto_canny, render_variant

TIP_VIEW = "tip"
PINCH_VIEW = "pinch"  # both crops and their relative frames (`vistac_learn.data.pinch_view`)
VIEWS = (PINCH_VIEW, TIP_VIEW, *VARIANTS)
SIDE_FEATURES = 5  # per finger, tip view: direction (2) and log distance (1) to the other
# fingertip, the other finger's axis (2)


@dataclass(frozen=True)
class Aug:
    """One sample's augmentation parameters (identity by default).

    Attributes:
        angle: Rotation of the top view, degrees counter-clockwise (study views).
        mirror: Flip the view left-right (labels: r_y -> -r_y).
        shift: Crop-centre offset in fingertip radii, (along the finger, across it) (tip view).
        turn: Crop-angle offset, degrees (tip view).
        scale: Crop-side factor (tip view).
        appearance: Seed of the image's appearance perturbation (`vistac_learn.data.perturb`),
            -1 for none.
    """

    angle: float = 0.0
    mirror: bool = False
    shift: tuple[float, float] = (0.0, 0.0)
    turn: float = 0.0
    scale: float = 1.0
    appearance: int = -1


IDENTITY = Aug()


def mirror_labels(labels: np.ndarray) -> np.ndarray:
    """Labels (..., 2) = (r_y, r_z) of the mirrored view: (-r_y, r_z)."""
    out = np.array(labels, dtype=np.float64, copy=True)
    out[..., 0] *= -1
    return out


@dataclass
class SampleInfo:
    """What a view may use besides the pixels of one configuration's image."""

    boxes: dict[str, np.ndarray | None] = field(default_factory=dict)
    tips: dict[str, Fingertip] = field(default_factory=dict)
    table_rgb: tuple[float, float, float] = (0.81, 0.81, 0.81)
    contacts: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)
    """Per finger whose truth is known, the simulator's contact point (pixels), normal
    ((n_y, n_z)) and finger axis (image direction) (`vistac_learn.data.contacts`); filled for
    views that set `needs_contacts`."""


class View:
    """Base of the views: a name, channels, whether it yields one crop per finger."""

    name: str = ""
    channels: int = 3
    per_finger: bool = False
    side_features: int = 0
    needs_boxes: tuple[str, ...] = ()
    needs_tips: bool = False
    needs_contacts: bool = False
    aux_features: int = 0  # auxiliary targets per finger (`aux`)

    def render(self, rgb: np.ndarray, info: SampleInfo, aug: Aug, size: int,
               fingers: tuple[str, ...]) -> np.ndarray:
        """The model input of one sample: (C, S, S) uint8, or (F, C, S, S) when per finger."""
        raise NotImplementedError

    def side(self, info: SampleInfo, aug: Aug, fingers: tuple[str, ...]) -> np.ndarray:
        """(F, side_features) float32 numbers beside the pixels (none by default)."""
        return np.zeros((len(fingers), 0), np.float32)

    def aux(self, info: SampleInfo, aug: Aug, fingers: tuple[str, ...]) -> np.ndarray:
        """(F, aux_features) float32 auxiliary targets, NaN where unknown (none by default)."""
        return np.zeros((len(fingers), 0), np.float32)


@dataclass(frozen=True)
class TipCfg:
    """Geometry of the fingertip crop, in fingertip radii (so that it is scale-free)."""

    span: float = 4.0  # side of the crop
    forward: float = 1.0  # crop centre ahead of the tip centre (1: the front of the pad)


def crop_angle(tip: Fingertip, aug: Aug = IDENTITY) -> float:
    """Rotation (degrees, OpenCV's sense) that turns the finger's axis to point up."""
    return float(np.degrees(np.arctan2(tip.axis[1], tip.axis[0])) + 90.0 + aug.turn)


def to_crop_frame(v: np.ndarray, tip: Fingertip, aug: Aug, mirror: bool) -> np.ndarray:
    """An image-plane vector (u, v) in the crop's frame: x right, y up, mirrored if asked."""
    t = np.radians(crop_angle(tip, aug))
    c, s = np.cos(t), np.sin(t)
    x = c * v[0] + s * v[1]  # OpenCV's rotation by t, counter-clockwise on screen
    y = -(-s * v[0] + c * v[1])  # image v points down; the crop's y up
    return np.array([-x if mirror else x, y])


def pair_features(this: Fingertip, other: Fingertip, aug: Aug, mirror: bool) -> np.ndarray:
    """`SIDE_FEATURES` numbers: where the other fingertip is, seen from this one's crop."""
    if not (this.ok and other.ok):
        return np.zeros(SIDE_FEATURES, np.float32)
    d = other.tip - this.tip
    dist = max(float(np.hypot(*d)), 1e-6)
    u = to_crop_frame(d / dist, this, aug, mirror)
    a = to_crop_frame(other.axis, this, aug, mirror)
    return np.array([u[0], u[1], np.log(dist / this.radius), a[0], a[1]], np.float32)


def crop_centre(tip: Fingertip, cfg: TipCfg = TipCfg(), aug: Aug = IDENTITY) -> np.ndarray:
    """(u, v) pixel the crop is centred on: ``tip + forward * r * axis`` plus the jitter."""
    a = tip.axis
    across = np.array([-a[1], a[0]])
    r = tip.radius
    return tip.tip + r * (cfg.forward + aug.shift[0]) * a + r * aug.shift[1] * across


def tip_crop(rgb: np.ndarray, tip: Fingertip, size: int, cfg: TipCfg = TipCfg(),
             aug: Aug = IDENTITY, mirror: bool = False) -> np.ndarray:
    """Fingertip-centred, finger-aligned (finger pointing up) crop, (3, S, S) uint8.

    One similarity warp from the source image: centre ``tip + forward * r * axis`` (plus the
    jitter), the axis turned to point up (image -v), ``span * r`` source pixels onto `size`.
    `mirror` flips the result left-right (the thumb's convention, or the mirror augmentation).
    A finger that was not found gives a crop of zeros.
    """
    if not tip.ok:
        return np.zeros((3, size, size), np.uint8)
    centre = crop_centre(tip, cfg, aug)
    scale = size / (cfg.span * tip.radius * aug.scale)
    m = cv2.getRotationMatrix2D((float(centre[0]), float(centre[1])), crop_angle(tip, aug),
                                float(scale))
    m[:, 2] += (size - 1) / 2.0 - centre  # the centre lands on the crop's centre
    flags = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
    out = cv2.warpAffine(rgb, m, (size, size), flags=flags, borderMode=cv2.BORDER_REPLICATE)
    if mirror:
        out = out[:, ::-1]
    return np.ascontiguousarray(out.transpose(2, 0, 1))


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
        from vistac_learn.data.pinch_view import PinchView

        return PinchView(tip)
    if name in VARIANTS:
        return StudyView(name, margin)
    raise UserError(f"unknown view {name!r}; choose from {', '.join(VIEWS)}")


__all__ = ["Aug", "IDENTITY", "FINGERS", "PINCH_VIEW", "SIDE_FEATURES", "SampleInfo", "StudyView",
           "TipCfg", "TipView", "VIEWS", "View", "crop_centre", "make_view", "mirror_labels",
           "pair_features", "tip_crop"]
