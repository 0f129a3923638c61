"""The ``pinch`` view: both fingertip crops and the numbers that tie their frames together.

What `vistac_learn.models.pinch` needs to compose a finger's label from contact geometry: per
finger, the finger-aligned crop of `views.tip_crop` (thumb mirrored, so both read in the index
finger's convention), and side numbers in that crop's frame (x right, y up, mirrored like the
crop), lengths in units of the crop's half side h:

- ``d`` (2): from this crop's centre to the other finger's crop centre;
- ``T`` (4, row-major 2 x 2): turns a vector of the other crop's frame into this one's (a
  reflection, since exactly one of the two crops is mirrored);
- ``rho`` (1): the other crop's half side over this one's;
- ``ok`` (1): 1 when both fingers were located (else every number is 0).

So a point ``q`` of the other crop (its units) lies at ``d + rho * T @ q`` in this one's.
Auxiliary targets per finger (`aux`, NaN where the dataset does not know them): the contact
point ``p`` (2) relative to the crop centre in the same units, the contact normal (2) as
(n_y, n_z) in the label's convention (n_y changes sign in a mirrored view, like r_y), and
``phi`` (1), the angle (radians) that turns a direction of the crop's label coordinates,
(-x, y), into the finger's sensor frame: the crop is aligned with the *located* finger axis,
and crop jitter or a locator error tilts it against the true one.

Every sample carries both fingers (F = 2, `FINGERS` order) whichever finger is the target: a
finger's label depends on where the other touches.
"""

from __future__ import annotations

import numpy as np

from vistac.dataset import FINGERS
from vistac_learn.data.fingertips import Fingertip
from vistac_learn.data.view_base import (
    PINCH_VIEW,
    Aug,
    SampleInfo,
    TipCfg,
    View,
    crop_centre,
    tip_crop,
    to_crop_frame,
)

PAIR_FEATURES = 8  # d (2), T (4), rho (1), ok (1)
CONTACT_FEATURES = 5  # p (2), normal (2), phi (1)
OTHER = {"index": "thumb", "thumb": "index"}


def _mirrored(finger: str, aug: Aug) -> bool:
    return (finger == "thumb") != aug.mirror


def half_side(tip: Fingertip, cfg: TipCfg, aug: Aug) -> float:
    """Half the crop's side in source pixels."""
    return 0.5 * cfg.span * tip.radius * aug.scale


def frame_matrix(tip: Fingertip, aug: Aug, mirror: bool) -> np.ndarray:
    """(2, 2) matrix of `to_crop_frame`: image (u, v) vector -> crop frame."""
    return np.stack([to_crop_frame(np.array([1.0, 0.0]), tip, aug, mirror),
                     to_crop_frame(np.array([0.0, 1.0]), tip, aug, mirror)], axis=1)


def pinch_features(tips: dict[str, Fingertip], finger: str, cfg: TipCfg, aug: Aug) -> np.ndarray:
    """`PAIR_FEATURES` numbers of one finger (zeros when a finger was not found)."""
    this, other = tips[finger], tips[OTHER[finger]]
    if not (this.ok and other.ok):
        return np.zeros(PAIR_FEATURES, np.float32)
    m_this = frame_matrix(this, aug, _mirrored(finger, aug))
    m_other = frame_matrix(other, aug, _mirrored(OTHER[finger], aug))
    h_this, h_other = half_side(this, cfg, aug), half_side(other, cfg, aug)
    d = m_this @ (crop_centre(other, cfg, aug) - crop_centre(this, cfg, aug)) / h_this
    t = m_this @ m_other.T
    return np.array([*d, *t.ravel(), h_other / h_this, 1.0], np.float32)


def contact_targets(tip: Fingertip, contact: tuple[np.ndarray, ...] | None, finger: str,
                    cfg: TipCfg, aug: Aug) -> np.ndarray:
    """`CONTACT_FEATURES` targets of one finger: p (crop frame, units of h), the normal and
    phi, from the truth (point (pixels), normal (n_y, n_z), axis (image direction))."""
    if contact is None or not tip.ok:
        return np.full(CONTACT_FEATURES, np.nan, np.float32)
    point, normal, axis = contact
    m = frame_matrix(tip, aug, _mirrored(finger, aug))
    p = m @ (np.asarray(point, float) - crop_centre(tip, cfg, aug)) / half_side(tip, cfg, aug)
    n_y = -normal[0] if aug.mirror else normal[0]
    a = m @ np.asarray(axis, float)  # the true axis in the crop frame; (0, 1) when aligned
    return np.array([*p, n_y, normal[1], np.arctan2(-a[0], a[1])], np.float32)


class PinchView(View):
    """Both fingers' crops, the numbers relating their frames, and contact targets."""

    name, channels, per_finger, needs_tips, needs_contacts = PINCH_VIEW, 3, True, True, True
    side_features, aux_features = PAIR_FEATURES, CONTACT_FEATURES

    def __init__(self, cfg: TipCfg | None = None):
        self.cfg = cfg or TipCfg()

    def render(self, rgb, info, aug, size, fingers):
        return np.stack([tip_crop(rgb, info.tips[f], size, self.cfg, aug, _mirrored(f, aug))
                         for f in FINGERS])

    def side(self, info: SampleInfo, aug, fingers):
        return np.stack([pinch_features(info.tips, f, self.cfg, aug) for f in FINGERS])

    def aux(self, info: SampleInfo, aug, fingers):
        return np.stack([contact_targets(info.tips[f], info.contacts.get(f), f, self.cfg, aug)
                         for f in FINGERS])


__all__ = ["CONTACT_FEATURES", "PAIR_FEATURES", "PINCH_VIEW", "PinchView", "contact_targets",
           "frame_matrix", "half_side", "pinch_features"]
