"""What every image view shares (`vistac_learn.data.views`): the view names, one sample's
augmentation draw (`Aug`), what a view knows of a sample besides its pixels (`SampleInfo`), the
`View` base class, and the fingertip crop the ``tip`` and ``pinch`` views cut (`TipCfg`,
`tip_crop` and its frame).

Its own module so that each view's module (`views`, `pinch_view`) builds on it and
`views.make_view` can import every view without an import cycle.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from vistac_learn.data.fingertips import Fingertip

TIP_VIEW = "tip"
PINCH_VIEW = "pinch"  # both crops and their relative frames (`vistac_learn.data.pinch_view`)


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
