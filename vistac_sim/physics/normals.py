"""Surface normals of the full-resolution mesh at a press's contacts (the labels' reference).

`TriangleIndex` answers closest-point queries on a triangle mesh exactly; `surface_normals`
turns MuJoCo's contacts of a settled press into the outward normal at each pad's contact.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from vistac_sim.geometry import closest_on_segment, rot2, unit

if TYPE_CHECKING:
    from vistac_sim.physics.press import PressResult
    from vistac_sim.scene.grasp import Grasp

_FLAT_COS = np.cos(np.radians(0.5))  # faces this close in direction count as one flat surface


def surface_normals(triangles: TriangleIndex, grasp: Grasp, res: PressResult,
                    reach: float) -> np.ndarray:
    """(2, 3) outward normal of the full-resolution mesh at each pad's contact, world frame.

    Per contact, s is the point of the pad capsule's axis nearest MuJoCo's contact point (the
    centre of the pad sphere that touches there; it lies outside the object) and q the mesh
    point nearest s, searched among the faces near the contact point (a face the pad does not
    touch is farther from s than the touched ones, and a second touched face makes its own
    contact). Inside a face (or on an edge between coplanar faces) the normal is the
    face normal. On a sharp edge or corner it is (s - q)/|s - q|, the member of the normal
    cone that points at the pad, which is the direction a frictionless contact pushes along
    there. Several contacts of one pad are averaged with their normal-force weights.

    Args:
        triangles: The object's full-resolution mesh, object frame.
        grasp: The pressed grasp (object pose, approach directions).
        res: The settled press (tip positions, pad contacts).
        reach: Length of the pad capsule's axis behind the tip centre (2 * tip_half_length).
    """
    # World <-> object frame: rotation about z by the object's yaw, then its offset.
    rot = np.eye(3)
    rot[:2, :2] = rot2(grasp.object_yaw)
    origin = np.array([grasp.object_xy[0], grasp.object_xy[1], 0.0])
    out = np.zeros((2, 3))
    for k in range(2):
        axis = np.array([grasp.approach[k, 0], grasp.approach[k, 1], 0.0])
        tip = res.tip[k]
        for *pos, weight in res.pad_contacts[k]:
            centre = closest_on_segment(np.asarray(pos), tip - axis * reach, tip)
            q_obj, face_n = triangles.closest(rot.T @ (centre - origin),
                                              around=rot.T @ (np.asarray(pos) - origin))
            if np.all(face_n @ face_n[0] > _FLAT_COS):
                n = rot @ face_n[0]
                if n @ (centre - (rot @ q_obj + origin)) < 0:  # an open mesh seen from behind
                    n = -n
            else:
                n = unit(centre - (rot @ q_obj + origin))
            out[k] += max(weight, 1e-12) * n
    return unit(out)


class TriangleIndex:
    """Closest-point queries on a triangle mesh: AABB pre-filter, then exact point-triangle."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        self.tri = np.asarray(vertices, float)[np.asarray(faces)]  # (F, 3, 3)
        self.lo = self.tri.min(axis=1)
        self.hi = self.tri.max(axis=1)

        e1 = self.tri[:, 1] - self.tri[:, 0]
        e2 = self.tri[:, 2] - self.tri[:, 0]
        self.face_normals = unit(np.cross(e1, e2))
        # Barycentric (u, v) of a point's projection: uv = bary @ (p - a), for the fast path.
        gram = np.stack([np.stack([(e1 * e1).sum(1), (e1 * e2).sum(1)], -1),
                         np.stack([(e1 * e2).sum(1), (e2 * e2).sum(1)], -1)], -2)
        ok = np.abs(np.linalg.det(gram)) > 1e-300  # degenerate faces never take the fast path
        inv = np.zeros_like(gram)
        inv[ok] = np.linalg.inv(gram[ok])
        self.bary = inv @ np.stack([e1, e2], 1)  # (F, 2, 3)
        # What the fast path reads per face, in one row (one gather per query): first vertex,
        # normal, barycentric rows.
        self._rows = np.concatenate([self.tri[:, 0], self.face_normals,
                                     self.bary.reshape(-1, 6)], axis=1)  # (F, 12)

    def _near(self, c: np.ndarray, radius: float) -> np.ndarray:
        """Indices of the faces whose box lies within `radius` of `c` (all if none)."""
        near = ((self.lo - radius <= c) & (c <= self.hi + radius)).all(1)
        idx = near.nonzero()[0]
        return idx if len(idx) else np.arange(len(self.tri))

    def closest(self, point: np.ndarray, radius: float = 0.002, tol: float = 1e-9,
                around: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Closest point on the mesh to `point`, and the normals of all faces touching it.

        Only faces whose box lies within `radius` of `around` (default: of `point`) are tested;
        if none does, all faces are.
        Faces whose own closest point lies within `tol` of the best one share that point (it sits
        on their common edge or corner); their normals span the normal cone there.
        """
        p = np.asarray(point, float)
        idx = self._near(p if around is None else np.asarray(around, float), radius)
        fast = self._inside_face(p, idx)
        if fast is not None:
            return fast
        q = closest_point_on_triangles(p, self.tri[idx])
        dist = np.sqrt(((q - p) ** 2).sum(1))
        k = int(np.argmin(dist))
        touching = idx[dist <= dist[k] + tol]
        return q[k], self.face_normals[touching]

    def _inside_face(self, p: np.ndarray, idx: np.ndarray,
                     margin: float = 1e-6) -> tuple[np.ndarray, np.ndarray] | None:
        """The common case, exactly: `p` projects well inside face j, and no other candidate
        that is not coplanar with j has its plane closer (a face's distance is at least its
        plane's), so j holds the closest point and it lies on no edge. None otherwise."""
        rows = self._rows[idx]
        w = p - rows[:, 0:3]
        normals = rows[:, 3:6]
        plane = (w * normals).sum(1)
        u = (rows[:, 6:9] * w).sum(1)
        v = (rows[:, 9:12] * w).sum(1)
        inside = (u > margin) & (v > margin) & (u + v < 1 - margin)
        if not inside.any():
            return None
        dist = np.abs(plane)
        j = int(np.argmin(np.where(inside, dist, np.inf)))
        n = normals[j]
        coplanar = (normals @ n > _COPLANAR_COS) & (np.abs(plane - plane[j]) < 1e-12)
        if ((~coplanar) & (dist <= dist[j] + 1e-12)).any():
            return None
        return p - plane[j] * n, n[None]


_COPLANAR_COS = np.cos(np.radians(0.01))


def closest_point_on_triangles(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Closest point to `p` on each triangle of `tri` (F, 3, 3) (Ericson, Real-Time Collision
    Detection, 5.1.5), vectorised over triangles."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp = p - b
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    cp = p - c
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = 1.0 / (va + vb + vc)
        v = vb * denom
        w = vc * denom
        out = a + ab * v[:, None] + ac * w[:, None]  # inside the face
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    # Edge and vertex regions, assigned from the least to the most specific.
    m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    out[m] = a[m] + ab[m] * t_ab[m, None]
    m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    out[m] = a[m] + ac[m] * t_ac[m, None]
    m = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
    out[m] = b[m] + (c[m] - b[m]) * t_bc[m, None]
    m = (d1 <= 0) & (d2 <= 0)
    out[m] = a[m]
    m = (d3 >= 0) & (d4 <= d3)
    out[m] = b[m]
    m = (d6 >= 0) & (d5 <= d6)
    out[m] = c[m]
    return out


