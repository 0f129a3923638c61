"""Procedural object outlines (top view) and their exact convex decomposition.

Every built-in family is a 2-D outline extruded upwards from the table. Sizes are in metres; the
outline's longest side equals `footprint`. Shapes are drawn from a passed-in generator.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import Point, Polygon, box
from shapely.ops import unary_union

OutlineFn = Callable[[np.random.Generator, float, float], Polygon]
_FAMILIES: dict[str, OutlineFn] = {}


def family(name: str):
    """Register an outline function under a family name."""

    def deco(fn: OutlineFn) -> OutlineFn:
        _FAMILIES[name] = fn
        return fn

    return deco


def outline(name: str, rng: np.random.Generator, footprint: float, min_wall: float) -> Polygon:
    """Draw one outline of family `name`, centred on its centroid, longest side `footprint`."""
    try:
        fn = _FAMILIES[name]
    except KeyError:
        raise ValueError(f"unknown object family {name!r}; known: {sorted(_FAMILIES)}") from None
    poly = shapely.make_valid(fn(rng, footprint, min_wall))
    if poly.geom_type != "Polygon":  # keep the largest piece of an accidental multi-polygon
        poly = max(poly.geoms, key=lambda g: g.area)
    poly = poly.simplify(1e-6)
    poly = affinity.translate(poly, -poly.centroid.x, -poly.centroid.y)
    x0, y0, x1, y1 = poly.bounds
    s = footprint / max(x1 - x0, y1 - y0)
    return affinity.scale(poly, s, s, origin=(0, 0))


@family("cylinder")
def _cylinder(rng, L, min_wall):
    return Point(0, 0).buffer(L / 2, quad_segs=24)


@family("box")
def _box(rng, L, min_wall):
    h = L * rng.uniform(0.35, 1.0)
    return box(-L / 2, -h / 2, L / 2, h / 2)


@family("prism")
def _prism(rng, L, min_wall):
    for _ in range(100):
        k = int(rng.integers(4, 9))
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        rad = rng.uniform(0.6, 1.0, k)
        hull = shapely.MultiPoint(np.c_[rad * np.cos(ang), rad * np.sin(ang)]).convex_hull
        if hull.geom_type == "Polygon" and hull.area > 0.8 and _min_angle_deg(hull) > 35:
            return hull
    return box(-1, -0.6, 1, 0.6)


@family("rounded_rect")
def _rounded_rect(rng, L, min_wall):
    w, h = L, L * rng.uniform(0.4, 1.0)
    r = min(w, h) * rng.uniform(0.1, 0.35)
    return box(-w / 2 + r, -h / 2 + r, w / 2 - r, h / 2 - r).buffer(r, quad_segs=8)


@family("L")
def _l_shape(rng, L, min_wall):
    t = max(min_wall, L * rng.uniform(0.25, 0.45))
    h = L * rng.uniform(0.6, 1.0)
    return unary_union([box(0, 0, L, t), box(0, 0, t, h)])


@family("U")
def _u_shape(rng, L, min_wall):
    t = max(min_wall, L * rng.uniform(0.18, 0.3))
    h = L * rng.uniform(0.55, 0.9)
    return unary_union([box(0, 0, L, t), box(0, 0, t, h), box(L - t, 0, L, h)])


@family("star")
def _star(rng, L, min_wall):
    k = int(rng.integers(4, 7))
    inner = rng.uniform(0.5, 0.7)
    ang = np.arange(2 * k) * np.pi / k
    rad = np.where(np.arange(2 * k) % 2 == 0, 1.0, inner)
    return Polygon(np.c_[rad * np.cos(ang), rad * np.sin(ang)])


@family("crescent")
def _crescent(rng, L, min_wall):
    outer = Point(0, 0).buffer(1.0, quad_segs=16)
    cut = Point(rng.uniform(0.45, 0.65), 0).buffer(rng.uniform(0.7, 0.85), quad_segs=12)
    return outer.difference(cut)


def _min_angle_deg(poly: Polygon) -> float:
    pts = np.asarray(poly.exterior.coords)[:-1]
    a = np.roll(pts, 1, 0) - pts
    b = np.roll(pts, -1, 0) - pts
    cos = (a * b).sum(1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    return float(np.degrees(np.arccos(np.clip(cos, -1, 1))).min())


def convex_pieces(poly: Polygon, tol: float = 1e-9) -> list[Polygon]:
    """Exact decomposition of a polygon into convex polygons (Hertel-Mehlhorn style).

    Constrained Delaunay triangles are merged greedily with a neighbour while the union stays
    convex. The union of the pieces is the polygon itself (no approximation).
    """
    if _is_convex(poly, tol):
        return [shapely.convex_hull(poly)]
    tris = list(shapely.constrained_delaunay_triangles(poly).geoms)
    pieces = [t for t in tris if t.area > tol * poly.area]
    # Greedy: merge the first pair (i < j, in list order) that shares an edge and whose union
    # is convex, then scan again. A pair that failed keeps failing until one of its pieces
    # changes, so failed pairs are remembered by the pieces' serial numbers (each merged piece
    # gets a new one): the result is that of the plain rescan, without repeating its tests.
    serial = list(range(len(pieces)))
    fresh = len(pieces)
    failed: set[tuple[int, int]] = set()
    merged = True
    while merged:
        merged = False
        for i in range(len(pieces)):
            for j in range(i + 1, len(pieces)):
                key = (serial[i], serial[j])
                if key in failed:
                    continue
                a, b = pieces[i], pieces[j]
                if a.intersection(b).length <= 1e-12:  # must share an edge
                    failed.add(key)
                    continue
                u = shapely.convex_hull(unary_union([a, b]))
                if abs(u.area - a.area - b.area) <= 1e-9 * poly.area + 1e-18:
                    pieces[i] = u
                    serial[i], fresh = fresh, fresh + 1
                    pieces.pop(j)
                    serial.pop(j)
                    merged = True
                    break
                failed.add(key)
            if merged:
                break
    return pieces


def _is_convex(poly: Polygon, tol: float) -> bool:
    return not poly.interiors and poly.convex_hull.area - poly.area <= tol * poly.area + 1e-18


def boundary_arrays(poly: Polygon) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Exterior-ring segments: starts, ends, outward normals, cumulative length."""
    ring = poly.exterior
    if not ring.is_ccw:
        ring = shapely.LinearRing(list(ring.coords)[::-1])
    pts = np.asarray(ring.coords)
    p0, p1 = pts[:-1], pts[1:]
    d = p1 - p0
    length = np.linalg.norm(d, axis=1)
    keep = length > 1e-12
    p0, p1, d, length = p0[keep], p1[keep], d[keep], length[keep]
    normals = np.c_[d[:, 1], -d[:, 0]] / length[:, None]  # outward for a CCW ring
    return p0, p1, normals, np.cumsum(length)


def families() -> list[str]:
    """Names of all registered outline families."""
    return sorted(_FAMILIES)


PROCEDURAL_FAMILIES = tuple(_FAMILIES)  # in registration order: the default library's cycle
CONCAVE_FAMILIES = ("L", "U", "star", "crescent")  # collided as several convex pieces

__all__ = ["outline", "convex_pieces", "boundary_arrays", "families", "PROCEDURAL_FAMILIES",
           "CONCAVE_FAMILIES"]
