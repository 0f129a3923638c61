"""An image-only physics baseline: the closing axis through the two contact points, in each
finger's frame, clamped to the friction cone (`vistac evaluate --baseline pinch`).

The physics it encodes: the hand closes both fingers along one axis, the line through the two
contact points, so the object pushes each pad back along that axis (from the other contact to
its own) while the pad sticks; a pad whose push lies outside the friction cone (half-angle
atan(mu) around the outward surface normal) slips until the force lies on the cone's edge.
Everything is read from the (possibly rotated) top-view image:

1. Fingers: tip centre c, axis a and radius r from the shared locator
   (`vistac_learn.data.fingertips`), as in the geometric baseline.
2. Object outline near each pad, sub-pixel: the colour distance to the table (the median of the
   border pixels) is thresholded at half the object's contrast, and every pixel edge whose two
   ends straddle the threshold gives one crossing point, linearly interpolated (marching
   squares without the bookkeeping). Crossings next to a finger (every pixel of a finger's
   colour, widened by `finger_margin_px`) are dropped; where object pixels touch finger pixels
   the edge between them counts as outline (there the object runs against the pad).
3. Contact point and normal of each pad (`fit_contact`): the outline points within
   r (1 + `reach`) of c; a face through the contact is fitted with a line (the contact is the
   foot of c on it, the normal the line's), else the contact is the nearest outline point and
   the normal the direction of the line separating c from the outline (a corner).
4. Label: d = unit(own contact - other contact); if the angle between d and the normal
   exceeds atan(mu) it is turned onto the cone's edge. Then (r_y, r_z) of d in the finger's
   sensor frame (`geometric.sensor_direction`: image v up, z along a, the thumb's y mirrored).

A finger that is not found yields (0, -1), like the geometric baseline; a finger found but
without outline near its pad (or the other finger not found) falls back to its own axis turned
around (-a, i.e. (0, -1) too); both are counted in ``failures``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vistac.dataset import FINGERS, DatasetTables
from vistac.dataset.schema import TABLE_RGB
from vistac_learn.data.finger_masks import colour_masks, finger_masks, to_hsv
from vistac_learn.data.fingertips import (
    Fingertip,
    LocatorCfg,
    locate_finger,
    object_mask,
    table_colour,
)
from vistac_learn.data.locator import flat_render
from vistac_learn.data.samples import RotationCfg
from vistac_learn.evaluate.geometric import image_predictions, sensor_direction

DEFAULT_FRICTION = 0.8  # the simulator's default pad-on-object friction coefficient


@dataclass(frozen=True)
class PinchCfg:
    """Settings of the pinch baseline.

    Attributes:
        locator: How the fingers are found (object pixels: `locator.object_tol`).
        friction: Friction coefficient mu of the cone; None: the dataset's (its manifest's
            ``physics.friction``), `DEFAULT_FRICTION` where the manifest has none.
        reach: Outline crossings closer than r (1 + reach) to the tip centre are used.
        finger_margin_px: Crossings within this many pixels of a finger are dropped.
        min_points: Fewest crossings for a fit; fewer: the pad's contact is not found.
        nearest_px: The points at most this much farther from the tip centre than the
            nearest one give the first normal estimate.
        search_deg: The separating direction is searched within this angle of it.
        step_deg: Step of that search (refined by a parabola through the best three).
        inlier_px: Points within this distance of the supporting line belong to the touching
            face.
        min_face: The face is refitted by a line when its points lie farther than
            min_face * r on both sides of the contact.
        segmented: Read the image through the learned segmenter first
            (`vistac_learn.data.segmenter`: its labels drawn in a clean render's flat
            colours), so that textures, light and camera noise do not reach the colour
            analysis; the outline is then the segmenter's, to about a pixel. None (the
            default): only images that are not flat renders (`locator.flat_render`), whose
            colours alone give the outline exactly.
    """

    locator: LocatorCfg = LocatorCfg()
    friction: float | None = None
    reach: float = 1.0
    finger_margin_px: int = 1
    min_points: int = 6
    nearest_px: float = 0.3
    search_deg: float = 60.0
    step_deg: float = 0.25
    inlier_px: float = 1.0
    min_face: float = 0.25
    segmented: bool | None = None


@dataclass(frozen=True)
class Contact:
    """Where one pad touches the object, in pixels (u right, v down).

    Attributes:
        point: (2,) contact point.
        normal: (2,) unit outward surface normal there (from the object towards the pad).
        ok: False when no outline was found near the pad (point and normal are NaN).
    """

    point: np.ndarray
    normal: np.ndarray
    ok: bool = True

    @classmethod
    def missing(cls) -> Contact:
        """A pad whose contact was not found."""
        return cls(np.full(2, np.nan), np.full(2, np.nan), False)


def dataset_friction(tables: DatasetTables) -> float:
    """The friction coefficient a dataset was simulated with (`DEFAULT_FRICTION` if unknown)."""
    physics = (tables.manifest.get("config") or {}).get("physics") or {}
    return float(physics.get("friction", DEFAULT_FRICTION))


def outline_crossings(field: np.ndarray, level: float, valid: np.ndarray) -> np.ndarray:
    """Sub-pixel points where `field` crosses `level` along pixel edges.

    Args:
        field: (H, W) float scalar image.
        level: The iso-level.
        valid: (H, W) bool; an edge with an invalid end gives no point.

    Returns:
        (P, 2) points (u, v) in pixel coordinates (pixel centres at integers).
    """
    vert = valid[:-1, :] & valid[1:, :] & ((field[:-1, :] - level) * (field[1:, :] - level) < 0)
    horz = valid[:, :-1] & valid[:, 1:] & ((field[:, :-1] - level) * (field[:, 1:] - level) < 0)
    v1, u1 = np.nonzero(vert)  # edge (u, v) - (u, v + 1)
    t1 = (level - field[v1, u1]) / (field[v1 + 1, u1] - field[v1, u1])
    v2, u2 = np.nonzero(horz)  # edge (u, v) - (u + 1, v)
    t2 = (level - field[v2, u2]) / (field[v2, u2 + 1] - field[v2, u2])
    pts = [np.stack([u1, v1 + t1], 1), np.stack([u2 + t2, v2], 1)]
    return np.concatenate(pts).astype(float)


def fit_contact(tip: Fingertip, points: np.ndarray, cfg: PinchCfg = PinchCfg()) -> Contact:
    """Contact point and outward normal of one pad from outline points near it.

    Among the outline points within reach of the tip centre c, the nearest ones give a first
    normal (from them towards c). The separating direction n, the one that maximises
    min_p (c - p) . n, refines it: for a corner it points from the corner towards c, for a face
    along the face's normal. When the points within `cfg.inlier_px` of the separating line lie
    on both sides of the contact (a face), a line fitted to them (total least squares) gives
    the normal and the contact, the foot of c on that line. Otherwise (a corner, a strongly
    curved outline) the contact is the nearest point's direction at the nearest distance and
    the normal is n.

    Args:
        tip: The located finger (centre c, radius r).
        points: (P, 2) outline points (u, v), e.g. `outline_crossings` of the whole image.
        cfg: Settings.

    Returns:
        The contact, or `Contact.missing()` with fewer than `cfg.min_points` points in reach.
    """
    c, r = tip.tip, tip.radius
    rel = c - points
    near = rel[np.hypot(rel[:, 0], rel[:, 1]) < r * (1 + cfg.reach)]
    if len(near) < cfg.min_points:
        return Contact.missing()
    dist = np.hypot(near[:, 0], near[:, 1])
    closest = near[dist < dist.min() + cfg.nearest_px]
    n_near = closest.mean(axis=0)
    n_near /= np.hypot(*n_near)
    n = _separating_direction(near, n_near, cfg)
    d = near @ n
    g = float(d.min())
    face = near[d < g + cfg.inlier_px]
    t = np.array([-n[1], n[0]])
    x = face @ t  # tangential coordinates; the foot of c on the supporting line is at 0
    if len(face) >= cfg.min_points and x.min() < -cfg.min_face * r and x.max() > cfg.min_face * r:
        centroid = face.mean(axis=0)
        _, _, vt = np.linalg.svd(face - centroid)
        n_fit = vt[1] if vt[1] @ n > 0 else -vt[1]  # normal of the best line, towards c
        return Contact(c - float(centroid @ n_fit) * n_fit, n_fit)
    # no face through the contact (a corner, a curve): the point nearest to c, the normal of
    # the separating line
    return Contact(c - float(dist.min()) * n_near, n)


def _separating_direction(near: np.ndarray, start: np.ndarray, cfg: PinchCfg) -> np.ndarray:
    """The unit n maximising min_p p . n over points p (relative to c): the direction of the
    line separating c from the points, searched within `cfg.search_deg` of `start`."""
    base = np.arctan2(start[1], start[0])
    theta = base + np.radians(np.arange(-cfg.search_deg, cfg.search_deg + 1e-9, cfg.step_deg))
    sep = (near @ np.stack([np.cos(theta), np.sin(theta)])).min(axis=0)
    k = int(np.argmax(sep))
    best = theta[k]
    if 0 < k < len(sep) - 1:  # parabola through the best three
        den = sep[k - 1] - 2 * sep[k] + sep[k + 1]
        if den < 0:
            best += 0.5 * (sep[k - 1] - sep[k + 1]) / den * np.radians(cfg.step_deg)
    return np.array([np.cos(best), np.sin(best)])


def clamp_to_cone(d: np.ndarray, normal: np.ndarray, friction: float) -> np.ndarray:
    """Unit direction `d` turned onto the friction cone's edge (half-angle atan(friction)
    around `normal`) when it lies outside the cone; unchanged inside."""
    half = np.arctan(friction)
    ang = np.arctan2(normal[0] * d[1] - normal[1] * d[0], normal @ d)
    if abs(ang) <= half:
        return d
    edge = np.sign(ang) * half
    cs, sn = np.cos(edge), np.sin(edge)
    return np.array([cs * normal[0] - sn * normal[1], sn * normal[0] + cs * normal[1]])


def pinch_direction(own: Contact, other: Contact, tip: Fingertip, finger: str,
                    friction: float) -> np.ndarray:
    """Predicted unit (r_y, r_z) of one finger from both contacts (both found)."""
    d = own.point - other.point
    d = clamp_to_cone(d / np.hypot(*d), own.normal, friction)
    pred = sensor_direction(d, tip.axis, finger)
    return pred / np.hypot(*pred)


def refine_tip(mask: np.ndarray, tip: Fingertip) -> Fingertip:
    """The finger's axis and tip circle refitted to the sub-pixel outline of its mask.

    Outline points: `outline_crossings` of the mask at level 1/2. Axis: the midpoints between
    the finger's two sides, in 1 px slices across the locator's axis behind the tip, fitted
    with a line (a side's step from pad to shaft cancels between the sides). Tip: a circle
    fitted (algebraic least squares) to the outline ahead of the centre, within 0.7-1.3 r of
    it. Each refinement is kept only when it has enough points and moves the locator's value
    by little (the axis by less than 3 degrees, the centre by less than r / 4).
    """
    if not tip.ok:
        return tip
    c, a, r = tip.tip, tip.axis, tip.radius
    pts = outline_crossings(mask.astype(np.float32), 0.5, np.ones(mask.shape, bool))
    lat = np.array([-a[1], a[0]])
    s, l = (pts - c) @ a, (pts - c) @ lat
    side = (s < -0.3 * r) & (np.abs(l) > 0.5 * r) & (np.abs(l) < 1.5 * r)
    bins = np.floor(s[side]).astype(int)
    mids, at = [], []
    for b in np.unique(bins):
        here = l[side][bins == b]
        if (here > 0).any() and (here < 0).any():
            mids.append(0.5 * (here[here > 0].mean() + here[here < 0].mean()))
            at.append(b + 0.5)
    if len(at) >= 10:
        slope, offset = np.polyfit(at, mids, 1)
        if abs(slope) < np.tan(np.radians(3.0)):
            a = (a + slope * lat) / np.hypot(1.0, slope)
            c = c + offset * lat
    rel = pts - c
    dist = np.hypot(rel[:, 0], rel[:, 1])
    sel = (rel @ a > 0) & (dist > 0.7 * r) & (dist < 1.3 * r)
    if sel.sum() >= 8:
        x, y = rel[sel, 0], rel[sel, 1]
        A = np.stack([2 * x, 2 * y, np.ones_like(x)], 1)
        (cx, cy, k), *_ = np.linalg.lstsq(A, x * x + y * y, rcond=None)
        if np.hypot(cx, cy) < 0.25 * r and k + cx * cx + cy * cy > 0:
            c, r = c + np.array([cx, cy]), float(np.sqrt(k + cx * cx + cy * cy))
    return Fingertip(c, a, r)


def locate(img: np.ndarray, colours: dict, loc: LocatorCfg, margin_px: int
           ) -> tuple[dict[str, Fingertip], np.ndarray, np.ndarray]:
    """Both fingers, the (dilated) finger pixels and the table colour of an image."""
    masks = finger_masks(img, colours, loc)
    anyf = np.logical_or.reduce(list(masks.values()))
    table = table_colour(img, anyf)
    # every pixel of a finger's drawn colour, also those the locator's opening drops (a
    # finger's thin edge), and a margin around them: no outline there. The drawn colour's own
    # band (`colour_masks`), not the loose hue window, which takes in brown or orange objects.
    hsv = to_hsv(img)
    raw = anyf.copy()
    for c in colours.values():
        cands, _ = colour_masks(hsv, c, loc)
        if cands:
            raw |= cands[0]
    size = 2 * margin_px + 1
    near_finger = cv2.dilate(raw.astype(np.uint8), np.ones((size, size), np.uint8)) > 0
    obj = object_mask(img, anyf, loc)
    centres = {f: (np.array([np.nonzero(m)[1].mean(), np.nonzero(m)[0].mean()]) if m.any()
                   else None) for f, m in masks.items()}
    tips = {}
    for f, m in masks.items():
        other = next((centres[g] for g in masks if g != f and centres[g] is not None), None)
        tips[f] = refine_tip(m, locate_finger(m, obj, other, loc))
    return tips, near_finger, table


def touching_edges(solid: np.ndarray, finger: np.ndarray) -> np.ndarray:
    """(P, 2) midpoints of the pixel edges between an object pixel and a finger pixel: where
    the object's outline runs against a pad, closer than a pixel (the contact itself)."""
    pts = []
    for a, b, shift in ((solid[:-1, :], finger[1:, :], (0.0, 0.5)),
                        (finger[:-1, :], solid[1:, :], (0.0, 0.5)),
                        (solid[:, :-1], finger[:, 1:], (0.5, 0.0)),
                        (finger[:, :-1], solid[:, 1:], (0.5, 0.0))):
        v, u = np.nonzero(a & b)
        pts.append(np.stack([u + shift[0], v + shift[1]], 1))
    return np.concatenate(pts).astype(float)


def image_outline(img: np.ndarray, table: np.ndarray, near_finger: np.ndarray,
                  object_tol: float) -> np.ndarray:
    """(P, 2) sub-pixel outline points of the object: where the colour distance to the table
    crosses half the object's contrast (its median over pixels clearly off the table), and
    where object pixels touch the (margin-widened) finger pixels (`touching_edges`)."""
    dist = np.linalg.norm(img.astype(np.float32) - table, axis=2)
    solid = (dist > object_tol) & ~near_finger
    if not solid.any():
        return np.zeros((0, 2))
    level = 0.5 * float(np.median(dist[solid]))
    return np.concatenate([outline_crossings(dist, max(level, 0.5 * object_tol), ~near_finger),
                           touching_edges(solid, near_finger)])


def predict_image(img: np.ndarray, colours: dict, fingers: tuple[str, ...], friction: float,
                  cfg: PinchCfg = PinchCfg()) -> tuple[np.ndarray, int]:
    """(2F,) pinch predictions of one image and the number of fingers that fell back.

    Args:
        img: (H, W, 3) uint8 RGB top view.
        colours: Drawn colour of each finger (both, to tell them apart).
        fingers: Fingers to predict, in output order.
        friction: Friction coefficient of the cone.
        cfg: Settings.
    """
    through = cfg.segmented if cfg.segmented is not None else not flat_render(img)
    if through:
        from vistac_learn.data.segmenter import palette_image, segment_image

        img = palette_image(segment_image(img), colours, TABLE_RGB)
    tips, near_finger, table = locate(img, colours, cfg.locator, cfg.finger_margin_px)
    points = image_outline(img, table, near_finger, cfg.locator.object_tol)
    contacts = {f: (fit_contact(t, points, cfg) if t.ok else Contact.missing())
                for f, t in tips.items()}
    out, failures = [], 0
    for f in fingers:
        other = next(g for g in FINGERS if g != f)
        if contacts[f].ok and contacts[other].ok:
            out.append(pinch_direction(contacts[f], contacts[other], tips[f], f, friction))
        else:
            out.append(np.array([0.0, -1.0]))
            failures += 1
    return np.concatenate(out), failures


def pinch_predictions(
    tables: DatasetTables,
    rows: np.ndarray,
    fingers: tuple[str, ...],
    rotations: RotationCfg,
    cfg: PinchCfg = PinchCfg(),
    progress: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Pinch predictions for every (configuration, rotation) of the given rows.

    Args:
        tables: The dataset (its manifest gives mu unless `cfg.friction` is set).
        rows: Configuration rows.
        fingers: Fingers to predict (2 columns each, in this order).
        rotations: Angles each image is rotated by (table colour fills the corners).
        cfg: Settings.
        progress: Show a progress bar.

    Returns:
        (pred (M, 2F), item_row (M,), item_rot (M,), failures), items ordered row-major.
    """
    mu = cfg.friction if cfg.friction is not None else dataset_friction(tables)
    colours = {f: tables.finger_rgb(f) for f in FINGERS}
    return image_predictions(tables, rows, rotations,
                             lambda img: predict_image(img, colours, fingers, mu, cfg),
                             "pinch baseline", progress)
