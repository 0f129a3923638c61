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
    everything = np.arange(len(mesh.faces))
    for p, r, dr in zip(pts, ref, dist_ref, strict=True):
        q, normals = index.closest(p, radius=0.05)
        assert np.linalg.norm(q - p) == pytest.approx(dr, abs=1e-9)
        np.testing.assert_allclose(q, r, atol=1e-7)
        assert len(normals) >= 1
        fast = index._inside_face(p.tolist(), everything)
        if fast is not None:  # the same point and face as the full search
            fast_used += 1
            full = closest_point_on_triangles(p, index.tri)
            dist = np.linalg.norm(full - p, axis=1)
            np.testing.assert_allclose(fast[0], full[np.argmin(dist)], atol=1e-12)
            np.testing.assert_allclose(fast[1], index.face_normals[dist <= dist.min() + 1e-9])
    assert fast_used > 280  # the fast path is the common case (299 of 300 here)


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


def test_triangle_index_fast_path_declines_when_a_neighbour_is_truly_closer():
    """A low step on a floor: the point projects inside the floor, but the step's edge is closer
    than the floor; the fast path must decline and the full search find the step."""
    floor = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]]
    step = [[0.5, -0.1, 0.0], [0.5, 0.1, 0.0], [0.5, 0.0, 0.001]]  # a wall facing +x, 1 mm high
    index = TriangleIndex(np.array(floor + step), np.array([[0, 1, 2], [3, 4, 5]]))
    p = np.array([0.5005, 0.0, 0.002])  # 2 mm above the floor, 1.1 mm from the step's top
    assert index._inside_face(p.tolist(), np.arange(2)) is None
    q, normals = index.closest(p, radius=1.0)
    assert np.linalg.norm(q - p) < 0.0015
    assert abs(abs(normals[0][0]) - 1.0) < 1e-12  # the step's normal (+-x), not the floor's


def test_surface_normals_of_a_degenerate_face_follow_the_pad():
    """A face with no area has no normal of its own: the normal points from the mesh point to
    the pad, as on an edge (never a zero vector)."""
    from vistac_sim.hand.grasp import Grasp
    from vistac_sim.physics.normals import surface_normals
    from vistac_sim.physics.press import PressResult

    line = np.array([[0.0, -0.01, 0.0], [0.0, 0.0, 0.0], [0.0, 0.01, 0.0]])  # collinear
    index = TriangleIndex(line, np.array([[0, 1, 2]]))
    approach = np.array([[-1.0, 0.0], [-1.0, 0.0]])
    grasp = Grasp(np.zeros(2), 0.0, np.zeros((2, 2)), -approach, approach)
    tip = np.array([[0.003, 0.0, 0.0], [0.003, 0.0, 0.0]])
    contacts = (np.array([[0.001, 0.0, 0.0, 1.0]]), np.array([[0.001, 0.0, 0.0, 1.0]]))
    res = PressResult(np.zeros((2, 3)), np.zeros((2, 3)), np.tile(np.eye(3), (2, 1, 1)), tip,
                      np.zeros(2), contacts)
    normals = surface_normals(index, grasp, res, reach=0.002)
    np.testing.assert_allclose(normals, [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]], atol=1e-12)
