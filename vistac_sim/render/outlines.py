"""What a finger's capsules look like in the image of any `Shot`: polygons and exact-enough boxes.

An orthographic view draws a sphere as a circle; a perspective view as an ellipse (the cone of
rays tangent to the sphere cut by the image plane). A capsule is the convex hull of its two end
spheres, and a projection keeps convex hulls, so its image is the convex hull of the images of
its end spheres. Each sphere's image is bounded by a polygon of `SIDES` points circumscribed
about it (the projection of a polygon circumscribed about the sphere's silhouette circle), so a
box from these points holds the whole capsule and is at most r * (1/cos(pi/SIDES) - 1) px too
wide (0.5 % of the radius).

The drawn fingers of `DrawnStyle` are such hulls too: one per capsule (the finger's own shape,
widened), or one tapered hull from the fingertip to the shaft's far end.
"""

from __future__ import annotations

import cv2
import numpy as np

from vistac.dataset import FINGERS
from vistac.projection import displace
from vistac_sim.hand.ids import ModelIds
from vistac_sim.mj import mujoco
from vistac_sim.render.shot import Shot
from vistac_sim.render.topview import finger_capsules

SIDES = 24
_ANGLES = np.linspace(0.0, 2 * np.pi, SIDES, endpoint=False)
_RING = np.stack([np.cos(_ANGLES), np.sin(_ANGLES)], axis=1) / np.cos(np.pi / SIDES)


def moved_capsules(model: mujoco.MjModel, data: mujoco.MjData, ids: ModelIds,
                   shot: Shot) -> list[np.ndarray]:
    """Per finger, (2 capsules, 2 ends, 4) rows (x, y, z, radius) in world coordinates, moved
    by the view's overlay error (turned about the fingertip, then shifted)."""
    out = []
    for k, (f, caps) in enumerate(zip(FINGERS, finger_capsules(model, data, ids), strict=True)):
        ends = np.array([[a, b] for a, b, _ in caps], float)  # (2, 2, 3)
        ends = displace(ends, data.site_xpos[ids.site[f]], shot.overlay[k])
        radii = np.array([[r, r] for _, _, r in caps], float)[..., None]
        out.append(np.concatenate([ends, radii], axis=-1))
    return out


def px_per_m_at(shot: Shot, points: np.ndarray) -> np.ndarray:
    """Pixels per metre of the image at world points (..., 3) (for a small length across
    the view axis)."""
    return shot.projection.px_per_m_at(points)


def sphere_polygons(shot: Shot, spheres: np.ndarray) -> np.ndarray:
    """(n, SIDES, 2) pixel polygons circumscribed about the images of spheres (n, 4) rows
    (x, y, z, radius)."""
    spheres = np.asarray(spheres, float).reshape(-1, 4)
    c, r = spheres[:, :3], spheres[:, 3]
    if not shot.perspective:
        centre = shot.project(c)
        return centre[:, None, :] + (r * shot.px_per_m)[:, None, None] * _RING[None]
    pos, right, up, _ = shot.frame()
    w = c - pos
    dist = np.sqrt(np.einsum("ij,ij->i", w, w))
    wn = w / dist[:, None]
    # the silhouette circle: centre m, radius rho, in the plane across the ray to the centre
    m = c - (r**2 / dist)[:, None] * wn
    rho = r * np.sqrt(np.maximum(dist**2 - r**2, 0.0)) / dist
    e1 = _cross(wn, up)
    e1 /= np.sqrt(np.einsum("ij,ij->i", e1, e1))[:, None]
    e2 = _cross(wn, e1)
    pts = m[:, None, :] + rho[:, None, None] * (_RING[None, :, :1] * e1[:, None, :]
                                                 + _RING[None, :, 1:] * e2[:, None, :])
    return shot.project(pts)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (n, 3) and (n, 3) or (3,) (cheaper than np.cross here)."""
    b = np.broadcast_to(b, a.shape)
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def hull(points: np.ndarray) -> np.ndarray:
    """(m, 2) convex hull (float32) of pixel points (..., 2)."""
    return cv2.convexHull(np.asarray(points, np.float32).reshape(-1, 1, 2)).reshape(-1, 2)


def finger_shapes(capsules: np.ndarray, shot: Shot, width: float = 1.0, grow_px: float = 0.0,
                  taper: float = 1.0) -> list[np.ndarray]:
    """Convex pixel polygons whose union is a finger's outline in the image.

    Args:
        capsules: the finger's (2, 2, 4) capsule ends (`moved_capsules`), pad first.
        view: the view it is seen from.
        width: radii scale (a drawn finger's width against the real one).
        grow_px: pixels added to every radius (half an outline's thickness).
        taper: 1 for the capsules themselves; below 1 one hull from the fingertip (the pad's end
            farthest from the shaft) to the shaft's far end, whose radius is `taper` times the
            fingertip's.
    """
    return many_finger_shapes([(capsules, width, grow_px, taper)], shot)[0]


def many_finger_shapes(jobs: list[tuple[np.ndarray, float, float, float]],
                       shot: Shot) -> list[list[np.ndarray]]:
    """`finger_shapes` of several (capsules, width, grow_px, taper), projected in one batch."""
    groups: list[np.ndarray] = []  # each: the two spheres whose hull is one polygon
    counts = []
    for capsules, width, grow_px, taper in jobs:
        caps = np.array(capsules, float)
        caps[..., 3] *= width
        if grow_px:
            caps[..., 3] += grow_px / px_per_m_at(shot, caps[..., :3])
        if taper >= 1.0:
            groups += [caps[0], caps[1]]
            counts.append(2)
            continue
        pad, shaft = caps
        # the shaft's far end: its end farthest from the pad; the tip: the pad's end farthest
        # from that
        far = shaft[np.argmax(np.linalg.norm(shaft[:, :3] - pad[:, :3].mean(0), axis=1))]
        tip = pad[np.argmax(np.linalg.norm(pad[:, :3] - far[:3], axis=1))]
        end = far.copy()
        end[3] = tip[3] * taper
        groups.append(np.stack([tip, end]))
        counts.append(1)
    polys = sphere_polygons(shot, np.concatenate(groups)).reshape(len(groups), -1, 2)
    hulls = [hull(p) for p in polys]
    out, k = [], 0
    for n in counts:
        out.append(hulls[k:k + n])
        k += n
    return out


_SQUARES: dict[int, np.ndarray] = {}


def polygons_box(polygons: list[np.ndarray], size: int) -> np.ndarray:
    """(x, y, w, h) box of the union of convex pixel polygons clipped to [0, size]^2 (zeros if
    none of it is in the image)."""
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for poly in polygons:
        p = np.asarray(poly, np.float32).reshape(-1, 2)
        if p.min() < 0 or p.max() > size:  # partly outside: clip to the image square
            if size not in _SQUARES:
                _SQUARES[size] = np.array([[0, 0], [size, 0], [size, size], [0, size]],
                                          np.float32)
            area, p = cv2.intersectConvexConvex(p, _SQUARES[size])
            if area <= 0 or p is None:
                continue
            p = p.reshape(-1, 2)
        lo, hi = np.minimum(lo, p.min(0)), np.maximum(hi, p.max(0))
    if not np.isfinite(lo).all():
        return np.zeros(4)
    lo, hi = np.clip(lo, 0, size), np.clip(hi, 0, size)
    return np.array([lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1]], float)
