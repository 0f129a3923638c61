"""Surface normals of the full-resolution mesh at a press's contacts (the labels' reference).

`TriangleIndex` answers closest-point queries on a triangle mesh exactly; `surface_normals`
turns MuJoCo's contacts of a settled press into the outward normal at each pad's contact.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from vistac_sim.geometry import closest_on_segment, unit

if TYPE_CHECKING:
    from vistac_sim.hand.grasp import Grasp
    from vistac_sim.physics.press import PressResult

# faces this close in direction count as one flat surface
_FLAT_COS = float(np.cos(np.radians(0.5)))


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
    # Scalar arithmetic per contact (one or two per pad): NumPy's per-call overhead would cost
    # more than the work. Object frame: rotation about z by -yaw after removing the offset.
    c, s = float(np.cos(grasp.object_yaw)), float(np.sin(grasp.object_yaw))
    ox, oy = float(grasp.object_xy[0]), float(grasp.object_xy[1])
    out = []
    for k in range(2):
        ax, ay = grasp.approach[k].tolist()
        tip = res.tip[k].tolist()
        back = [tip[0] - ax * reach, tip[1] - ay * reach, tip[2]]  # the pad's (horizontal) axis
        acc = [0.0, 0.0, 0.0]
        for px, py, pz, weight in res.pad_contacts[k].tolist():
            cx, cy, cz = closest_on_segment((px, py, pz), back, tip)
            cx, cy = cx - ox, cy - oy
            centre = (c * cx + s * cy, c * cy - s * cx, cz)
            px, py = px - ox, py - oy
            q, normals = triangles.query(centre, (c * px + s * py, c * py - s * px, pz))
            to_pad = [centre[i] - q[i] for i in range(3)]
            n = normals[0]  # a degenerate face's zero normal fails this test: edge rule
            if all(_dot(m, n) > _FLAT_COS for m in normals):
                if _dot(n, to_pad) < 0:  # an open mesh seen from behind
                    n = [-x for x in n]
            else:
                n = _unit(to_pad)
            weight = max(weight, 1e-12)
            acc = [acc[i] + weight * n[i] for i in range(3)]
        nx, ny, nz = _unit(acc)
        out.append((c * nx - s * ny, s * nx + c * ny, nz))  # back to the world frame
    return np.array(out)


def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _unit(v) -> list[float]:
    length = math.sqrt(_dot(v, v))
    return [x / length for x in v] if length > 0 else [0.0, 0.0, 0.0]


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
        # What the fast path reads per face, in one block (one gather per query): first vertex,
        # normal, barycentric rows.
        self._rows = np.stack([self.tri[:, 0], self.face_normals, self.bary[:, 0],
                               self.bary[:, 1]], axis=1)  # (F, 4, 3)

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
        p = np.asarray(point, float).tolist()
        q, normals = self.query(p, p if around is None else np.asarray(around, float).tolist(),
                                radius, tol)
        return np.array(q), np.array(normals)

    def query(self, point, around, radius: float = 0.002,
              tol: float = 1e-9) -> tuple[list[float], list[list[float]]]:
        """`closest` for 3-sequences of floats, answered in Python floats (the labels' hot path:
        one query per contact)."""
        idx = self._near(np.array(around), radius)
        if len(idx) <= SCALAR_CANDIDATES:
            fast = self._inside_face(point, idx, tol)
            if fast is not None:
                return fast
        p = np.array(point, float)
        q = closest_point_on_triangles(p, self.tri[idx])
        dist = np.sqrt(((q - p) ** 2).sum(1))
        k = int(np.argmin(dist))
        return q[k].tolist(), self.face_normals[idx[dist <= dist[k] + tol]].tolist()

    def _inside_face(self, p, idx: np.ndarray, tol: float = 1e-9,
                     margin: float = 1e-6) -> tuple[list[float], list[list[float]]] | None:
        """The common case: `p` projects well inside face j (farther than `margin`, in
        barycentric units, from its edges), and every other candidate that is not coplanar with
        j lies farther than `tol` beyond it (first by its plane's distance, a lower bound; where
        that does not tell, by the distance to its edges, where its closest point then lies), so
        j holds the closest point and it lies on no edge. None otherwise. In Python floats: a
        query has a few candidates (two in most presses; `query` sends more than
        `SCALAR_CANDIDATES` to the vectorised search)."""
        px, py, pz = p
        rows = self._rows[idx].tolist()
        planes, j = [], -1
        for k, (a, n, b0, b1) in enumerate(rows):
            wx, wy, wz = px - a[0], py - a[1], pz - a[2]
            plane = wx * n[0] + wy * n[1] + wz * n[2]
            u = wx * b0[0] + wy * b0[1] + wz * b0[2]
            v = wx * b1[0] + wy * b1[1] + wz * b1[2]
            inside = u > margin and v > margin and u + v < 1 - margin
            planes.append((plane, inside))
            if inside and (j < 0 or abs(plane) < abs(planes[j][0])):
                j = k
        if j < 0:
            return None
        plane_j, n = planes[j][0], rows[j][1]
        limit = abs(plane_j) + tol
        others = []  # faces whose plane passes as close as j's and that are not coplanar with it
        for k, (plane, inside) in enumerate(planes):
            if k == j or abs(plane) > limit or (
                    _dot(rows[k][1], n) > _COPLANAR_COS and abs(plane - plane_j) < 1e-12):
                continue
            if inside:  # its own closest point is as close as j's
                return None
            others.append(int(idx[k]))
        if any(self._edge_distance2(p, f) <= limit * limit for f in others):
            return None
        return [px - plane_j * n[0], py - plane_j * n[1], pz - plane_j * n[2]], [n]

    def _edge_distance2(self, p, face: int) -> float:
        """Squared distance from `p` to the nearest edge of `face`."""
        corners = self.tri[face].tolist()
        best = math.inf
        for k in range(3):
            q = closest_on_segment(p, corners[k], corners[(k + 1) % 3])
            r = [p[i] - q[i] for i in range(3)]
            best = min(best, _dot(r, r))
        return best


SCALAR_CANDIDATES = 64
"""Up to this many candidate faces a query tries the Python fast path (`_inside_face`); beyond,
NumPy's vectorised search is cheaper."""
_COPLANAR_COS = float(np.cos(np.radians(0.01)))


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


