"""Find the drawn fingertips in a top-view image: tip centre, finger axis and radius, in pixels.

Works on the image alone (a simulated render or a photograph with the fingers drawn in), so the
same code serves generated and ingested datasets; the finger boxes of a dataset are not needed.
Steps, all whole-array OpenCV / NumPy:

1. **Finger mask.** The finger's pixels read off its drawn colour, or the reason there are none
   (`vistac_learn.data.finger_masks`: hue, saturation and chroma, the largest finger-shaped
   blob).
2. **Axis.** A line fitted (least squares) through the ridge of the mask's distance transform
   (the image border not counted as outline), the pixels at least `ridge_frac` of the finger's
   radius inside its outline: the finger's centre line, not tilted when the border clips the
   finger. Radius r: the 99th percentile of the distance transform (the widest part, the tip).
3. **Which end is the tip.** The ends are the extreme projections on the axis of the mask's
   pixels near the axis. An end that touches the image border is the back of the finger;
   otherwise the tip is the end clearly nearer the other finger (the fingers face each other
   across the object); otherwise the end with more object ahead of it (pixels that are neither
   finger nor table, the table colour being the median of the border pixels).
4. **Tip centre.** r behind the tip end (the extreme pixel centre, `end_px`) along the axis:
   the centre of the rounded end's circle, i.e. the simulator's fingertip position. The axis
   points from the back of the finger to the tip.

These steps are the *colour fit* (`colour_fingertips`). Photographs can defeat its colour
analysis (a table or object of the overlay's hue taken for the finger or merged with it, a
restyled overlay under a white-balance shift), so a learned per-pixel segmenter
(`vistac_learn.data.segmenter`) reads the image too, and `vistac_learn.data.locator` (which
holds `locate_fingertips`, the entry point) combines the two as `LocatorCfg.segmenter` says:
by default (``refine``) the segmenter picks each finger's blob and the colour fit draws its
sub-pixel outline inside it (the `regions` of `colour_fingertips`).

Measured (`benchmarks/locator_robustness.py`, docs/appearance.md "Locating fingertips in
photographs"): clean, each perturbation, all at once and `photo`-preset images, colour fit vs
learned vs combined.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from vistac_learn.data.finger_masks import explained_finger_masks
from vistac_learn.data.locator_cfg import LocatorCfg
from vistac_learn.data.variants import read_rgb  # noqa: F401 (re-exported: images as the locator reads them)

LOCATOR_VERSION = 5  # bump when the locator's output changes; invalidates cached tables
FIELDS = ("tip_u", "tip_v", "axis_u", "axis_v", "radius")


@dataclass(frozen=True)
class Fingertip:
    """One located finger, in pixels (u right, v down).

    Attributes:
        tip: (2,) centre of the fingertip's rounded end.
        axis: (2,) unit vector from the back of the finger towards its tip.
        radius: Half the finger's width at the tip.
        ok: Whether the finger was found; if not, `reason` says why and the rest is NaN.
        reason: Why the finger was not found.
    """

    tip: np.ndarray
    axis: np.ndarray
    radius: float
    ok: bool = True
    reason: str = ""

    @classmethod
    def missing(cls, reason: str) -> Fingertip:
        """A finger that was not found."""
        nan2 = np.full(2, np.nan)
        return cls(nan2, nan2, float("nan"), False, reason)


def table_colour(rgb: np.ndarray, fingers_any: np.ndarray) -> np.ndarray:
    """(3,) float table colour: the median of the image's border pixels that are not finger."""
    border = np.zeros(fingers_any.shape, bool)
    border[:3], border[-3:], border[:, :3], border[:, -3:] = True, True, True, True
    sel = border & ~fingers_any
    img = rgb.astype(np.float32)
    return np.median(img[sel] if sel.any() else img.reshape(-1, 3), axis=0)


def object_mask(rgb: np.ndarray, fingers_any: np.ndarray, cfg: LocatorCfg) -> np.ndarray:
    """Pixels that are neither finger nor table (`table_colour`)."""
    img = rgb.astype(np.float32)
    dist = np.linalg.norm(cv2.GaussianBlur(img, (5, 5), 0) - table_colour(rgb, fingers_any),
                          axis=2)
    hidden = cv2.dilate(fingers_any.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    return (dist > cfg.object_tol) & ~hidden


def _object_ahead(obj: np.ndarray, end: np.ndarray, a: np.ndarray, r: float, probe: float
                  ) -> float:
    """Fraction of object pixels in the disc of radius probe*r centred probe*r/2 beyond `end`."""
    h, w = obj.shape
    c = end + a * probe * r * 0.5
    rad = probe * r
    x0, x1 = int(max(0, np.floor(c[0] - rad))), int(min(w, np.ceil(c[0] + rad) + 1))
    y0, y1 = int(max(0, np.floor(c[1] - rad))), int(min(h, np.ceil(c[1] + rad) + 1))
    if x1 <= x0 or y1 <= y0:
        return 0.0
    yy, xx = np.mgrid[y0:y1, x0:x1]
    disc = (xx - c[0]) ** 2 + (yy - c[1]) ** 2 <= rad * rad
    return float(obj[y0:y1, x0:x1][disc].mean()) if disc.any() else 0.0


def _open_border_distance(mask: np.ndarray, r: float) -> np.ndarray:
    """Distance of each pixel to the finger's outline where the image border is not outline:
    the mask extended past the border by repeating its edge pixels (2 r + 1 of them). A finger
    cut by the border keeps its full width up to the border, so the centre line of a short
    stub is as long as the stub (with the border as outline it shrank to a spot round the
    tip, and its direction was off by up to 47 deg on photo renders)."""
    p = int(np.ceil(2 * r)) + 1
    ext = cv2.copyMakeBorder(mask.astype(np.uint8), p, p, p, p, cv2.BORDER_REPLICATE)
    return cv2.distanceTransform(ext, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)[p:-p, p:-p]


def locate_finger(mask: np.ndarray, obj: np.ndarray | Callable[[], np.ndarray],
                  other: np.ndarray | None,
                  cfg: LocatorCfg) -> Fingertip:
    """Tip, axis and radius of one finger's mask.

    Args:
        mask: The finger's pixels.
        obj: Object pixels (`object_mask`), or a function making them (called only when
            the tip is told by the object ahead of it).
        other: Centroid (u, v) of the other finger, or None.
        cfg: Settings.

    Returns:
        The fingertip, or `Fingertip.missing` with the reason.
    """
    h, w = mask.shape
    area = int(mask.sum())
    if area < cfg.min_area_px:
        return Fingertip.missing(f"{area} px of its colour (fewer than {cfg.min_area_px})")
    dt = cv2.distanceTransform(np.pad(mask.astype(np.uint8), 1), cv2.DIST_L2,
                               cv2.DIST_MASK_PRECISE)[1:-1, 1:-1]
    r = float(np.percentile(dt[mask], 99))
    vs, us = np.nonzero(mask & (_open_border_distance(mask, r) >= cfg.ridge_frac * r))
    if len(us) < 5:
        return Fingertip.missing("no centre line (the blob is not finger-shaped)")
    line = cv2.fitLine(np.stack([us, vs], 1).astype(np.float32), cv2.DIST_L2, 0, 0.01, 0.01)
    d, c = line[:2, 0].astype(float), line[2:, 0].astype(float)
    mv, mu = np.nonzero(mask)
    rel = np.stack([mu, mv], 1) - c
    s = rel @ d
    body = np.abs(rel @ np.array([-d[1], d[0]])) <= 1.2 * r + 1.0  # off-axis blobs left out
    s = s[body]
    ends = (c + (s.min() - cfg.end_px) * d, c + (s.max() + cfg.end_px) * d)
    dirs = (-d, d)
    inside = [not (e[0] < 1.5 or e[1] < 1.5 or e[0] > w - 2.5 or e[1] > h - 2.5) for e in ends]
    near = [np.hypot(*(e - other)) for e in ends] if other is not None else None
    if inside[0] != inside[1]:
        k = int(inside[1])
    elif near is not None and min(near) < cfg.facing * max(near):
        k = int(np.argmin(near))
    else:
        obj = obj() if callable(obj) else obj
        ahead = [_object_ahead(obj, e, a, r, cfg.probe) for e, a in zip(ends, dirs, strict=True)]
        if abs(ahead[0] - ahead[1]) <= 0.02:
            return Fingertip.missing("cannot tell the tip from the back of the finger (both "
                                     "ends or neither at the image border, the other finger "
                                     "not clearly ahead of either, no object ahead)")
        k = int(ahead[1] > ahead[0])
    a = dirs[k]
    return Fingertip(ends[k] - a * r, a, r)


def colour_fingertips(rgb: np.ndarray, colours: dict[str, tuple], cfg: LocatorCfg,
                      regions: dict[str, np.ndarray] | None = None) -> dict[str, Fingertip]:
    """Every finger located by its drawn colour (steps 1-4 of the module's description), only
    inside its entry of `regions` where it has one."""
    return fit_fingers(rgb, *explained_finger_masks(rgb, colours, cfg, regions), cfg)


def fit_fingers(rgb: np.ndarray, masks: dict[str, np.ndarray], why: dict[str, str],
                cfg: LocatorCfg) -> dict[str, Fingertip]:
    """Every finger located from its mask (`explained_finger_masks`; steps 2-4), missing with
    its reason where `why` has one."""
    anyf = np.logical_or.reduce(list(masks.values()))

    @functools.cache
    def obj() -> np.ndarray:
        return object_mask(rgb, anyf, cfg)

    centres = {}
    for f, m in masks.items():
        v, u = np.nonzero(m)
        centres[f] = np.array([u.mean(), v.mean()]) if len(u) else None
    out = {}
    for f, m in masks.items():
        if why[f]:
            out[f] = Fingertip.missing(why[f])
            continue
        others = [centres[g] for g in masks if g != f and centres[g] is not None]
        out[f] = locate_finger(m, obj, others[0] if others else None, cfg)
    return out
