"""A non-learned geometric baseline: force direction from the object's outline at the fingertip.

Assumption: a frictionless contact, so the object pushes the tip along the outward surface
normal at the contact. Everything is read from the (possibly rotated) top-view image alone:

1. Fingers: tip centre, axis a (back of the finger -> tip) and radius r, found by the shared
   locator `vistac_learn.data.fingertips` (colour mask, centre line, which end is the tip).
2. Object: pixels that are neither finger nor table (`fingertips.object_mask`).
3. Normal: a sphere pressed on a surface touches it where the surface normal passes through
   the sphere's centre, so the outward normal is the direction from the contact to the tip
   centre. The contact is estimated as the centroid of the visible object pixels within
   r (1 + reach) of the tip centre (on a flat face they lie symmetrically on both sides of the
   hidden contact point); n = (tip centre - centroid) / |.|, flipped if it points along a (a
   contact must oppose the approach). No object near the tip: n = -a.
4. Sensor frame (dataset layout): image (u, v) -> world-like (u, -v); z = a; index y = a turned
   +90 degrees counter-clockwise, thumb y mirrored. Prediction (r_y, r_z) = (n.y, n.z), unit.

A finger that cannot be found yields (0, -1) (straight against the approach) and is counted in
``failures``. Whole-array OpenCV/NumPy per image; no per-pixel Python loops.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from vistac.dataset import FINGERS, DatasetTables
from vistac.dataset.frames import image_to_sensor
from vistac.progress import bar as progress_bar
from vistac_learn.data.finger_masks import finger_masks
from vistac_learn.data.fingertips import (
    Fingertip,
    LocatorCfg,
    locate_finger,
    object_mask,
    read_rgb,
)
from vistac_learn.data.samples import RotationCfg
from vistac_learn.data.variants import rotation_matrix


@dataclass(frozen=True)
class GeometricCfg:
    """Settings of the geometric baseline.

    Attributes:
        locator: How the fingers and the object are found.
        reach: Object pixels closer than r + reach * r to the tip centre are the contact
            neighbourhood (widened twice, to 2x and 3x, when none is found).
    """

    locator: LocatorCfg = LocatorCfg()
    reach: float = 0.5


def sensor_direction(n: np.ndarray, a: np.ndarray, finger: str) -> np.ndarray:
    """(r_y, r_z) of an image-plane direction `n` in the sensor frame of a finger with axis `a`
    (both unit, image (u, v) coordinates)."""
    return image_to_sensor(n, a, finger)


def geometric_direction(tip: Fingertip, obj: np.ndarray, finger: str,
                        cfg: GeometricCfg = GeometricCfg()) -> tuple[np.ndarray, bool]:
    """Predicted unit (r_y, r_z) of one located finger.

    Args:
        tip: The located finger.
        obj: Object pixels of the image (`fingertips.object_mask`).
        finger: ``index`` or ``thumb``.
        cfg: Settings.

    Returns:
        (prediction (2,), ok); ok is False when the finger or the object was not found and the
        fallback (0, -1) was returned.
    """
    fallback = np.array([0.0, -1.0])
    if not tip.ok or not obj.any():
        return fallback, False
    a, r, c = tip.axis, tip.radius, tip.tip
    ov, ou = np.nonzero(obj)
    dist_c = np.hypot(ou - c[0], ov - c[1])
    n, found = -a, False
    for reach in (cfg.reach * r, 2 * cfg.reach * r, 3 * cfg.reach * r):
        near = dist_c < r + max(reach, 2.0)
        if near.any():
            v = c - np.array([ou[near].mean(), ov[near].mean()])
            if np.hypot(*v) > 1e-6:
                n = v / np.hypot(*v)
                if n @ a > 0:
                    n = -n
                found = True
            break
    pred = sensor_direction(n, a, finger)
    norm = np.hypot(*pred)
    if norm < 1e-9:
        return fallback, False
    return pred / norm, found


def predict_image(img: np.ndarray, colours: dict, fingers: tuple[str, ...],
                  cfg: GeometricCfg = GeometricCfg()) -> tuple[np.ndarray, int]:
    """(2F,) predictions of one image and the number of fingers that fell back."""
    loc = cfg.locator
    masks = finger_masks(img, colours, loc)
    obj = object_mask(img, np.logical_or.reduce(list(masks.values())), loc)
    centres = {f: (np.array([np.nonzero(m)[1].mean(), np.nonzero(m)[0].mean()]) if m.any()
                   else None) for f, m in masks.items()}
    out, failures = [], 0
    for f in fingers:
        other = next((centres[g] for g in masks if g != f and centres[g] is not None), None)
        p, ok = geometric_direction(locate_finger(masks[f], obj, other, loc), obj, f, cfg)
        failures += int(not ok)
        out.append(p)
    return np.concatenate(out), failures


def rotation_angles(rotations: RotationCfg, row: int) -> np.ndarray:
    """Angles an image is scored at: fixed steps, none, or random ones drawn from the row."""
    if rotations.mode == "none":
        return np.zeros(1)
    if rotations.mode == "fixed":
        return np.arange(rotations.n) * rotations.step_deg
    return np.random.default_rng([0, int(row)]).uniform(0, 360, rotations.n)


def image_predictions(
    tables: DatasetTables,
    rows: np.ndarray,
    rotations: RotationCfg,
    predict: Callable[[np.ndarray], tuple[np.ndarray, int]],
    desc: str = "baseline",
    progress: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """An image-only predictor applied to every (configuration, rotation) of the given rows.

    Args:
        tables: The dataset.
        rows: Configuration rows.
        rotations: Angles each image is rotated by (table colour fills the corners).
        predict: Image (H, W, 3) uint8 RGB -> ((2F,) prediction, fingers that fell back).
        desc: Progress bar label.
        progress: Show a progress bar.

    Returns:
        (pred (M, 2F), item_row (M,), item_rot (M,), failures), items ordered row-major.
    """
    rows = np.asarray(rows, dtype=np.int64)
    bg = tuple(int(round(c * 255)) for c in tables.table_rgb)
    preds, item_row, item_rot, failures = [], [], [], 0
    for row in progress_bar(rows, desc=desc, leave=False, enabled=progress):
        img = read_rgb(tables.image_path(row))
        h, w = img.shape[:2]
        for k, ang in enumerate(rotation_angles(rotations, row)):
            rot = img if ang == 0 else cv2.warpAffine(
                img, rotation_matrix(ang, w, h), (w, h), flags=cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_CONSTANT, borderValue=bg)
            p, lost = predict(rot)
            failures += lost
            preds.append(p)
            item_row.append(row)
            item_rot.append(k)
    return np.array(preds), np.array(item_row), np.array(item_rot), failures


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
    colours = {f: tables.finger_rgb(f) for f in FINGERS}
    return image_predictions(tables, rows, rotations,
                             lambda img: predict_image(img, colours, fingers, cfg),
                             "geometric baseline", progress)
