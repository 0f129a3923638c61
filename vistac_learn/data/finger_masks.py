"""A drawn finger's pixels, read off its colour: step 1 of the colour fit
(`vistac_learn.data.fingertips`).

The image is lightly median-filtered (noise, JPEG blocks) and turned to HSV (`to_hsv`). The
drawn colour is read off the image (`colour_masks`): the most saturated pixels within
`LocatorCfg.hue_tol_deg` of the finger's nominal hue vote for its hue, and a finger pixel lies
in a narrow band round that hue with at least a share of its saturation and half of its chroma
(max - min channel, linear in how much of the pixel the overlay covers, so the outline stays
put under blur). Hue and saturation are ratios of the channels: shading, exposure and a
coloured light barely move them. Opened with a 7 px disc (thinner stripes and specks of the
colour go, a finger's wider rounded end stays); the largest connected blob, closed with the
same disc and its holes filled (pixels lost to noise or glare). A blob too small, covering a
large part of the image, or not filling its bounding rectangle like a capsule is rejected with
its reason (the next candidate hue is tried first): `explained_finger_masks`.
"""

from __future__ import annotations

import cv2
import numpy as np

from vistac_learn.data.locator_cfg import LocatorCfg


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
