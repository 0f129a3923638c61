"""Find the drawn fingertips in a top-view image: tip centre, finger axis and radius, in pixels.

Works on the image alone (a simulated render or a photograph with the fingers drawn in), so the
same code serves generated and ingested datasets; the finger boxes of a dataset are not needed.
Steps, all whole-array OpenCV / NumPy:

1. **Finger mask.** The image lightly median-filtered (noise, JPEG blocks) and turned to HSV.
   The drawn colour is read off the image (`colour_masks`): the most saturated pixels within
   `LocatorCfg.hue_tol_deg` of the finger's nominal hue vote for its hue, and a finger pixel
   lies in a narrow band round that hue with at least a share of its saturation and half of its
   chroma (max - min channel, linear in how much of the pixel the overlay covers, so the outline
   stays put under blur). Hue and saturation are ratios of the channels: shading, exposure and
   a coloured light barely move them. Opened with a 7 px disc (thinner stripes and specks of the
   colour go, a finger's wider rounded end stays); the largest connected blob, closed with
   the same disc and its holes filled (pixels lost to noise or glare). A blob too small,
   covering a large part of the image, or not filling its bounding rectangle like a capsule is
   rejected with its reason (the next candidate hue is tried first).
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
from typing import Literal

import cv2
import numpy as np

from vistac.config import Config, param
from vistac_learn.data.variants import read_rgb  # noqa: F401 (re-exported: images as the locator reads them)

LOCATOR_VERSION = 5  # bump when the locator's output changes; invalidates cached tables
FIELDS = ("tip_u", "tip_v", "axis_u", "axis_v", "radius")


@dataclass(frozen=True)
class LocatorCfg(Config):
    """How drawn fingers are found in an image."""

    hue_tol_deg: float = param(35.0, gt=0, le=90, help="widest hue offset of a finger's drawn "
                               "colour from its nominal one")
    min_saturation: float = param(0.3, ge=0, le=1, help="least saturation of a finger pixel")
    min_value: float = param(0.15, ge=0, le=1, help="least brightness of a finger pixel")
    band_deg: float = param(10.0, gt=0, le=90, help="hue band round the drawn colour found in "
                            "the image")
    sat_frac: float = param(0.5, gt=0, le=1, help="least saturation of a finger pixel as a "
                            "fraction of the drawn colour's")
    seed_px: int = param(300, ge=10, help="the most saturated pixels of a finger's hue that "
                         "tell its drawn colour")
    max_area_frac: float = param(0.25, gt=0, le=1, help="a blob of the finger's colour larger "
                                 "than this fraction of the image is not a finger")
    min_area_px: int = param(40, ge=1, help="fewest pixels of a finger that count as found")
    open_px: int = param(7, ge=1, le=31, help="side of the disc that opens the colour mask "
                         "(stripes and specks of the finger's colour thinner than it go; a "
                         "finger's rounded end, wider, stays as it is)")
    min_fill: float = param(0.55, ge=0, le=1, help="least share of its bounding rectangle a "
                            "finger's blob fills (a capsule fills 0.8 or more)")
    ridge_frac: float = param(0.6, gt=0, lt=1, help="centre-line pixels: distance to the "
                              "outline >= ridge_frac * radius")
    facing: float = param(0.85, gt=0, lt=1, help="the tip is the end nearer the other finger "
                          "when its distance is below `facing` times the other end's")
    end_px: float = param(0.0, ge=-2, le=2, help="a finger's end lies this far beyond its "
                          "extreme pixel centre (0: measured on clean renders, where +0.5 put "
                          "the tip 0.4-0.6 px ahead of the simulator's)")
    probe: float = param(1.5, gt=0, help="radius of the look-ahead disc, in finger radii")
    object_tol: float = param(30.0, gt=0, help="RGB distance (0-255) from the table colour "
                              "above which a pixel is object")
    segmenter: Literal["off", "fallback", "check", "always", "refine"] = param(
        "refine", help="the learned segmenter (vistac_learn.data.segmenter) and the colour "
        "fit combined: off (colour fit only); fallback (the learned fit only for a finger the "
        "colour fit misses); check (both run, the learned fit wins where they disagree); "
        "always (the learned fit only); refine (the colour fit inside the segmenter's finger, "
        "kept where it agrees with the learned fit)")
    agree_px: float = param(3.0, gt=0, help="'check' / 'refine': colour and learned tips closer "
                            "than this (and axes within agree_deg) agree; the colour fit is kept")
    agree_deg: float = param(4.0, gt=0, help="'check' / 'refine': largest axis difference that "
                             "agrees")
    refine_px: int = param(1, ge=0, le=10, help="'refine': the colour fit looks for a finger "
                           "within this many pixels of the segmenter's finger")


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


def hue_deg(rgb) -> float:
    """Hue of an RGB colour in degrees (0 red, 120 green, 240 blue)."""
    r, g, b = (float(c) for c in rgb)
    return float(np.degrees(np.arctan2(np.sqrt(3) * (g - b), 2 * r - g - b)) % 360)


def _hue_offset(hue: np.ndarray, ref: float) -> np.ndarray:
    """Signed hue difference in degrees, in [-180, 180)."""
    return (hue - ref + 180.0) % 360.0 - 180.0


def colour_mask(hsv: np.ndarray, rgb, cfg: LocatorCfg) -> np.ndarray:
    """Every pixel loosely of a finger's colour (within `hue_tol_deg` of its nominal hue,
    saturation and brightness above the floors), from the image in OpenCV's full-range HSV
    (uint8, ``COLOR_RGB2HSV_FULL``): nearly all of the finger's mask (`colour_masks`) and more, for
    keeping clear of a finger's soft edge."""
    hue = hsv[..., 0].astype(np.float32) * (360.0 / 256.0)
    return ((np.abs(_hue_offset(hue, hue_deg(rgb))) <= cfg.hue_tol_deg)
            & (hsv[..., 1] >= cfg.min_saturation * 255) & (hsv[..., 2] >= cfg.min_value * 255))


def _peaks(hist: np.ndarray, n: int) -> list[int]:
    """Indices of up to `n` local maxima of a histogram, highest first."""
    order = np.argsort(-hist)
    out: list[int] = []
    for i in order:
        if hist[i] <= 0 or len(out) == n:
            break
        if all(abs(int(i) - j) > 6 for j in out):
            out.append(int(i))
    return out


def colour_masks(hsv: np.ndarray, rgb, cfg: LocatorCfg, region: np.ndarray | None = None
                 ) -> tuple[list[np.ndarray], str]:
    """Candidate masks of a finger's drawn colour, most likely first, from the image in float
    HSV (hue degrees, s and v in [0, 1]); ([], why) when there is none. With `region`, only
    pixels inside it are candidates (and vote for the drawn colour).

    The drawn colour is found in the image, not assumed: among the pixels whose hue lies within
    `hue_tol_deg` of the nominal colour (saturation and brightness above floors), the
    `seed_px` most saturated ones (an overlay is the most saturated thing of its hue) vote for
    the drawn hue (the modes of their hue, 1 deg bins, smoothed; up to 3). For each mode, a
    finger pixel lies within `band_deg` of it, has at least `sat_frac` of its saturation and at
    least half of its chroma (max - min channel): chroma is linear in the coverage of a pixel by
    the overlay, so the half-chroma outline is the drawn outline even when blurred. Hue and
    saturation do not change under shading or exposure (ratios of the channels).
    """
    hue, sat, val = hsv[..., 0], hsv[..., 1], hsv[..., 2]
    off = _hue_offset(hue, hue_deg(rgb))
    cand = (np.abs(off) <= cfg.hue_tol_deg) & (sat >= cfg.min_saturation) & \
        (val >= cfg.min_value)
    if region is not None:
        cand &= region
    if not cand.any():
        return [], f"0 px of its colour (none within {cfg.hue_tol_deg:g} deg of its hue)"
    c_off, c_sat, c_val = off[cand], sat[cand], val[cand]
    if len(c_sat) > cfg.seed_px:
        top = np.argpartition(-c_sat, cfg.seed_px)[:cfg.seed_px]
        c_off, c_sat, c_val = c_off[top], c_sat[top], c_val[top]
    hist = np.bincount(np.clip(np.round(c_off + 90), 0, 180).astype(int), minlength=181)
    hist = np.convolve(hist, np.ones(5) / 5, mode="same")
    chroma = sat * val
    out = []
    for i in _peaks(hist, 3):
        peak = float(i) - 90.0
        at = np.abs(c_off - peak) <= 3.0
        if at.sum() < 5:
            continue
        s0 = float(np.median(c_sat[at]))
        c0 = float(np.median(c_sat[at] * c_val[at]))
        out.append(cand & (np.abs(off - peak) <= cfg.band_deg) & (sat >= cfg.sat_frac * s0)
                   & (chroma >= 0.5 * c0))
    return out, "" if out else "0 px of its colour (no clear drawn colour)"


def _largest_blob(mask: np.ndarray) -> np.ndarray:
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.zeros(mask.shape, bool)
    return labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))


def _fill_holes(mask: np.ndarray) -> np.ndarray:
    """The mask with its enclosed holes filled (specks of noise or glare inside the overlay)."""
    m = mask.astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(1 - m, connectivity=4)
    if n <= 2:
        return mask
    h, w = m.shape
    x, y, bw, bh = (stats[:, i] for i in range(4))
    hole = (x > 0) & (y > 0) & (x + bw < w) & (y + bh < h)  # not touching the border
    hole[0] = False
    return mask | hole[labels]


def _finger_like(blob: np.ndarray, cfg: LocatorCfg) -> str:
    """Why a blob is not a drawn finger ('' if it may be one): too small, too large, or not
    filling its bounding rectangle as a capsule does."""
    area = int(blob.sum())
    if area < cfg.min_area_px:
        return f"{area} px of its colour (fewer than {cfg.min_area_px})"
    if area > cfg.max_area_frac * blob.size:
        return (f"its colour covers {100 * area / blob.size:.0f} % of the image (a background "
                "of the finger's colour?), not a finger")
    pts = cv2.findNonZero(blob.astype(np.uint8))
    (_, _), (rw, rh), _ = cv2.minAreaRect(pts)
    fill = area / max(rw * rh, 1.0)
    if fill < cfg.min_fill:
        return (f"its colour forms a blob filling {100 * fill:.0f} % of its bounding "
                "rectangle, not finger-shaped")
    return ""


def to_hsv(rgb: np.ndarray) -> np.ndarray:
    """Float HSV (hue in degrees, saturation and value in [0, 1]) of a lightly smoothed image
    (a 3 x 3 median: sensor noise and JPEG blocks out, edges kept)."""
    img = cv2.medianBlur(rgb, 3).astype(np.float32) / 255.0
    return cv2.cvtColor(img, cv2.COLOR_RGB2HSV)


def finger_masks(rgb: np.ndarray, colours: dict[str, tuple], cfg: LocatorCfg
                 ) -> dict[str, np.ndarray]:
    """Boolean mask of each drawn finger: the largest blob of its colour, holes filled."""
    return explained_finger_masks(rgb, colours, cfg)[0]


def explained_finger_masks(rgb: np.ndarray, colours: dict[str, tuple], cfg: LocatorCfg,
                           regions: dict[str, np.ndarray] | None = None
                           ) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """`finger_masks` and, for each finger whose mask is unusable (then empty), why.

    Of the candidate colours (`colour_masks`, inside the finger's entry of `regions` when it
    has one), the first whose largest blob (opened, holes filled) is finger-like
    (`_finger_like`) wins.
    """
    regions = regions or {}
    hsv = to_hsv(rgb)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (cfg.open_px, cfg.open_px))
    masks, why = {}, {}
    for f, c in colours.items():
        cands, reason = colour_masks(hsv, c, cfg, regions.get(f))
        masks[f], why[f] = np.zeros(rgb.shape[:2], bool), reason
        first = ""
        for m in cands:
            m = cv2.morphologyEx(m.astype(np.uint8), cv2.MORPH_OPEN, kernel) > 0
            blob = _largest_blob(m)
            blob = _fill_holes(blob | (cv2.morphologyEx(blob.astype(np.uint8), cv2.MORPH_CLOSE,
                                                        kernel) > 0))
            bad = _finger_like(blob, cfg)
            if not bad:
                masks[f], why[f] = blob, ""
                break
            first = first or bad
        else:
            why[f] = why[f] or first
    return masks, why


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
