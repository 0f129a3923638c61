"""Geometry helpers against slow, obvious references (trimesh, shapely)."""

import numpy as np
import pytest
import trimesh
from shapely.ops import unary_union

from vistac_sim.geometry import angle_deg
from vistac_sim.objects import outlines
from vistac_sim.physics.normals import TriangleIndex, closest_point_on_triangles


def test_closest_point_matches_trimesh():
    mesh = trimesh.creation.icosphere(subdivisions=2)
    mesh.vertices *= np.array([1.0, 0.6, 0.3])  # not a sphere: faces of many orientations
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(200, 3))
    ref, dist_ref, _ = trimesh.proximity.closest_point(mesh, pts)
    tri = mesh.triangles
    for p, r, dr in zip(pts, ref, dist_ref, strict=True):
        q = closest_point_on_triangles(p, tri)
        d = np.linalg.norm(q - p, axis=1)
        assert d.min() == pytest.approx(dr, abs=1e-9)
        np.testing.assert_allclose(q[np.argmin(d)], r, atol=1e-7)


def test_triangle_index_reports_all_faces_at_an_edge():
    mesh = trimesh.creation.box(extents=[1, 1, 1])
    index = TriangleIndex(mesh.vertices, mesh.faces)
    q, normals = index.closest(np.array([0.8, 0.8, 0.0]), radius=1.0)
    np.testing.assert_allclose(q, [0.5, 0.5, 0.0], atol=1e-12)
    dirs = {tuple(np.round(n, 6)) for n in normals}
    assert (1.0, 0.0, 0.0) in dirs and (0.0, 1.0, 0.0) in dirs
    q, normals = index.closest(np.array([0.1, 0.2, 0.9]), radius=1.0)
    assert np.allclose(normals, [0, 0, 1])


def test_angle_deg_is_accurate_near_zero_and_180():
    assert angle_deg([1, 0, 0], [1, 1e-9, 0]) == pytest.approx(np.degrees(1e-9), rel=1e-6)
    assert angle_deg([1, 0, 0], [-1, 1e-9, 0]) == pytest.approx(180 - np.degrees(1e-9), rel=1e-9)


@pytest.mark.parametrize("family", outlines.families())
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_convex_pieces_are_exact_and_convex(family, seed):
    poly = outlines.outline(family, np.random.default_rng(seed), 0.06, 0.001)
    x0, y0, x1, y1 = poly.bounds
    assert max(x1 - x0, y1 - y0) == pytest.approx(0.06)
    pieces = outlines.convex_pieces(poly)
    for p in pieces:
        assert p.convex_hull.area - p.area <= 1e-9 * poly.area
    assert unary_union(pieces).symmetric_difference(poly).area <= 1e-9 * poly.area
    assert sum(p.area for p in pieces) == pytest.approx(poly.area, rel=1e-9)  # no overlaps


def test_triangle_index_fast_path_agrees_with_the_full_search():
    mesh = trimesh.creation.icosphere(subdivisions=3)
    mesh.vertices *= np.array([1.0, 0.7, 0.4])
    index = TriangleIndex(mesh.vertices, mesh.faces)
    rng = np.random.default_rng(1)
    surface, _ = trimesh.sample.sample_surface(mesh, 300, seed=1)
    pts = surface + rng.normal(scale=1e-3, size=surface.shape)  # contacts lie near the surface
    ref, dist_ref, _ = trimesh.proximity.closest_point(mesh, pts)
    fast_used = 0
    for p, r, dr in zip(pts, ref, dist_ref, strict=True):
        q, normals = index.closest(p, radius=0.05)
        fast_used += index._inside_face(p, np.arange(len(mesh.faces))) is not None
        assert np.linalg.norm(q - p) == pytest.approx(dr, abs=1e-9)
        np.testing.assert_allclose(q, r, atol=1e-7)
        assert len(normals) >= 1
    assert fast_used > 150  # the fast path is the common case (179 of 300 here)


def test_triangle_index_fast_path_sees_past_a_neighbouring_plane():
    """Beside a box's edge the neighbouring face's plane passes closer than the touched face:
    only its exact (edge) distance shows that it is farther; the fast path must answer, and
    agree with the full search."""
    mesh = trimesh.creation.box(extents=[1, 1, 1])
    index = TriangleIndex(mesh.vertices, mesh.faces)
    rng = np.random.default_rng(2)
    for _ in range(50):
        d = rng.uniform(1e-3, 1e-2)
        p = np.array([0.5 + d, 0.5 - rng.uniform(0.05, 0.95) * d, rng.uniform(-0.4, 0.4)])
        q_full = closest_point_on_triangles(p, mesh.triangles)
        best = q_full[np.argmin(np.linalg.norm(q_full - p, axis=1))]
        fast = index._inside_face(p, np.arange(len(mesh.faces)))
        assert fast is not None
        np.testing.assert_allclose(fast[0], best, atol=1e-12)
        np.testing.assert_allclose(fast[1], [[1.0, 0.0, 0.0]], atol=1e-12)
    # just past the edge the closest point is on it: the fast path declines
    assert index._inside_face(np.array([0.505, 0.501, 0.0]), np.arange(len(mesh.faces))) is None
