"""A non-learned geometric baseline: force direction from the object's outline at the fingertip.

Assumption: a frictionless contact, so the object pushes the tip along the outward surface
normal at the contact. Everything is read from the (possibly rotated) top-view image alone:

1. Finger: pixels within `colour_tol` of the finger's drawn colour (inside its box grown by a
   few pixels when the dataset has boxes), largest connected blob. Its principal axis (PCA of
   the pixel coordinates) is the finger axis, its half-width (95th percentile of the distance to
   the axis) the tip radius r.
2. Object: pixels farther than `object_tol` from the table colour that are not finger pixels
   (either finger, dilated by two pixels against anti-aliased fringes).
3. Tip: the axis end nearer to the object (distance transform of the object mask); the
   approach direction a points from the other end to it; the tip centre lies r behind that end.
4. Normal: a sphere pressed on a surface touches it where the surface normal passes through
   the sphere's centre, so the outward normal is the direction from the contact to the tip
   centre. The contact is estimated as the centroid of the visible object pixels within
   r (1 + reach) of the tip centre (on a flat face they lie symmetrically on both sides of the
   hidden contact point); n = (tip centre - centroid) / |.|, flipped if it points along a (a
   contact must oppose the approach). No object near the tip: n = -a.
5. Sensor frame (dataset layout): image (u, v) -> world-like (u, -v); z = a; index y = a turned
   +90 degrees counter-clockwise, thumb y mirrored. Prediction (r_y, r_z) = (n.y, n.z), unit.

A finger that cannot be found yields (0, -1) (straight against the approach) and is counted in
``failures``. Whole-array OpenCV/NumPy per image; no per-pixel Python loops.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from tqdm import tqdm

from vistac.dataset import FINGERS, DatasetTables
from vistac_learn.data.pairs import RotationCfg
from vistac_learn.data.variants import read_rgb, rotate_box, rotation_matrix


@dataclass(frozen=True)
class GeometricCfg:
    """Settings of the geometric baseline.

    Attributes:
        colour_tol: Largest RGB distance (0-255 units) of a finger pixel to the finger colour.
        object_tol: Smallest RGB distance of an object pixel to the table colour.
        box_pad: Pixels added round a finger box before searching the finger in it.
        reach: Object pixels closer than r + reach * r to the tip centre are the contact
            neighbourhood (widened twice, to 2x and 3x, when none is found).
    """

    colour_tol: float = 60.0
    object_tol: float = 25.0
    box_pad: int = 3
    reach: float = 0.5


def _colour_dist(img: np.ndarray, rgb) -> np.ndarray:
    ref = np.asarray(rgb, np.float32) * 255.0
    return np.linalg.norm(img.astype(np.float32) - ref, axis=2)


def _largest_blob(mask: np.ndarray) -> np.ndarray:
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.zeros_like(mask, bool)
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return labels == k


def finger_masks(
    img: np.ndarray,
    finger_rgb: dict[str, tuple],
    boxes: dict[str, np.ndarray | None],
    cfg: GeometricCfg,
) -> dict[str, np.ndarray]:
    """Boolean mask of each drawn finger (largest blob of its colour, inside its box if known)."""
    h, w = img.shape[:2]
    out = {}
    for f, rgb in finger_rgb.items():
        m = _colour_dist(img, rgb) < cfg.colour_tol
        box = boxes.get(f)
        if box is not None:
            x, y, bw, bh = box
            p = cfg.box_pad
            keep = np.zeros_like(m)
            keep[max(0, int(y) - p):min(h, int(np.ceil(y + bh)) + p),
                 max(0, int(x) - p):min(w, int(np.ceil(x + bw)) + p)] = True
            m &= keep
        out[f] = _largest_blob(m)
    return out


def geometric_direction(
    img: np.ndarray,
    finger: str,
    masks: dict[str, np.ndarray],
    table_rgb,
    cfg: GeometricCfg = GeometricCfg(),
) -> tuple[np.ndarray, bool]:
    """Predicted unit (r_y, r_z) of one finger in one image.

    Args:
        img: (H, W, 3) uint8 RGB.
        finger: ``index`` or ``thumb``.
        masks: `finger_masks` of the image (both fingers).
        table_rgb: Table colour in [0, 1].
        cfg: Settings.

    Returns:
        (prediction (2,), ok); ok is False when the finger or the object was not found and the
        fallback (0, -1) was returned.
    """
    fallback = np.array([0.0, -1.0])
    fm = masks[finger]
    vs, us = np.nonzero(fm)
    if len(us) < 10:
        return fallback, False
    pts = np.stack([us, vs], axis=1).astype(np.float64)
    c = pts.mean(axis=0)
    cov = np.cov((pts - c).T)
    evals, evecs = np.linalg.eigh(cov)
    d = evecs[:, int(np.argmax(evals))]
    s = (pts - c) @ d
    perp = np.abs((pts - c) @ np.array([-d[1], d[0]]))
    r = max(float(np.quantile(perp, 0.95)), 1.0)
    any_finger = np.zeros_like(fm)
    for m in masks.values():
        any_finger |= m
    hidden = cv2.dilate(any_finger.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    obj = (_colour_dist(img, table_rgb) > cfg.object_tol) & ~hidden
    if not obj.any():
        return fallback, False
    dist = cv2.distanceTransform((~obj).astype(np.uint8), cv2.DIST_L2, 5)
    h, w = fm.shape
    ends = [c + s.min() * d, c + s.max() * d]
    de = [dist[int(np.clip(round(e[1]), 0, h - 1)), int(np.clip(round(e[0]), 0, w - 1))]
          for e in ends]
    tip_end = int(np.argmin(de))
    a = d if tip_end == 1 else -d  # back end -> tip, image (u, v)
    tip_centre = ends[tip_end] - a * r
    ov, ou = np.nonzero(obj)
    dist_c = np.hypot(ou - tip_centre[0], ov - tip_centre[1])
    n = -a
    found = False
    for reach in (cfg.reach * r, 2 * cfg.reach * r, 3 * cfg.reach * r):
        near = dist_c < r + max(reach, 2.0)
        if near.any():
            q = np.array([ou[near].mean(), ov[near].mean()])
            v = tip_centre - q
            if np.hypot(*v) > 1e-6:
                n = v / np.hypot(*v)
                if n @ a > 0:
                    n = -n
                found = True
            break
    aw = np.array([a[0], -a[1]])
    nw = np.array([n[0], -n[1]])
    y_ax = np.array([-aw[1], aw[0]]) if finger == "index" else np.array([aw[1], -aw[0]])
    pred = np.array([nw @ y_ax, nw @ aw])
    norm = np.hypot(*pred)
    if norm < 1e-9:
        return fallback, False
    return pred / norm, found


def baseline_predictions(
    tables: DatasetTables,
    rows: np.ndarray,
    fingers: tuple[str, ...],
    rotations: RotationCfg,
    cfg: GeometricCfg = GeometricCfg(),
    progress: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Geometric predictions for every (configuration, rotation) of the given rows.

    Args:
        tables: The dataset.
        rows: Configuration rows.
        fingers: Fingers to predict (2 columns each, in this order).
        rotations: Angles each image is rotated by (table colour fills the corners).
        cfg: Settings.
        progress: Show a progress bar.

    Returns:
        (pred (M, 2F), item_row (M,), item_rot (M,), failures), items ordered row-major.
    """
    rows = np.asarray(rows, dtype=np.int64)
    angles = rotations.angles(tables.configs["config_id"].to_numpy()[rows])
    colours = {f: tables.finger_rgb(f) for f in FINGERS}
    bg = tuple(int(round(c * 255)) for c in tables.table_rgb)
    preds, item_row, item_rot, failures = [], [], [], 0
    it = tqdm(list(enumerate(rows)), desc="geometric baseline", leave=False, disable=not progress)
    for i, row in it:
        img = read_rgb(tables.image_path(row))
        h, w = img.shape[:2]
        for k, ang in enumerate(angles[i]):
            m = rotation_matrix(ang, w, h)
            rot = cv2.warpAffine(img, m, (w, h), flags=cv2.INTER_LINEAR,
                                 borderMode=cv2.BORDER_CONSTANT, borderValue=bg)
            boxes = {}
            for f in FINGERS:
                b = tables.box(row, f)
                boxes[f] = None if b is None else rotate_box(b, m)
            masks = finger_masks(rot, colours, boxes, cfg)
            out = []
            for f in fingers:
                p, ok = geometric_direction(rot, f, masks, tables.table_rgb, cfg)
                failures += int(not ok)
                out.append(p)
            preds.append(np.concatenate(out))
            item_row.append(row)
            item_rot.append(k)
    return np.array(preds), np.array(item_row), np.array(item_rot), failures
