"""Hard meshes, built in code, as a user's file would hold them (raw vertices and faces, in the
file's units): the hard-case suite of `tests/sim/test_hard_meshes.py` and
`benchmarks/hard_meshes.py`.

Each builder returns ``(vertices, faces)``; `STRESS_MESHES` names them with the footprint they
are pressed at. They are the defects and extremes a mesh pipeline meets: vertices that are the
same point written twice a hair apart, T-junctions closed by sliver faces (in metres and in
millimetres), very thin, very small and very large objects, narrow slots, sharp wedges, an open
scan and a knotted tube.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import shapely
import trimesh


def near_duplicate_sphere(diameter: float = 0.05, jitter: float = 1e-9,
                          subdivisions: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A sphere written as a triangle soup (each corner its own vertex, as STL stores it), every
    copy moved by up to `jitter` (m): copies of one point lie on either side of any rounding
    grid."""
    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    v = s.vertices[s.faces].reshape(-1, 3) * diameter / 2
    v = v + np.random.default_rng(0).uniform(-jitter, jitter, v.shape)
    return v, np.arange(len(v)).reshape(-1, 3)


def sliver_sphere(diameter: float = 0.05, offset: float = 1e-7,
                  subdivisions: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """A closed, consistently wound sphere in which every face has a T-junction on one edge,
    closed by a sliver face: the face (a, b, c) is split at m, a point `offset` (relative) inside
    the midpoint of ab, into (a, m, c) and (m, b, c), and the sliver (a, b, m) joins them to the
    unsplit neighbour across ab. Give `diameter` in the file's units (0.05 m or 50 mm)."""
    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    verts = list(s.vertices * diameter / 2)
    faces, used = [], set()
    for f in s.faces.tolist():
        for k in range(3):
            a, b, c = f[k], f[(k + 1) % 3], f[(k + 2) % 3]
            if frozenset((a, b)) not in used:
                used.add(frozenset((a, b)))
                m = len(verts)
                verts.append((verts[a] + verts[b]) / 2 * (1 - offset))
                faces += [[a, m, c], [m, b, c], [a, b, m]]
                break
        else:
            faces.append(f)
    return np.array(verts), np.array(faces)


def box_mesh(x: float, y: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed box of x * y * z, resting on z = 0."""
    m = trimesh.creation.box((x, y, z))
    m.apply_translation([0, 0, z / 2])
    return m.vertices, m.faces


def needle(length: float = 0.06, diameter: float = 0.0015) -> tuple[np.ndarray, np.ndarray]:
    """A needle lying on the table: a cylinder of `length` along x."""
    m = trimesh.creation.cylinder(radius=diameter / 2, height=length, sections=24)
    m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    m.apply_translation([0, 0, diameter / 2])
    return m.vertices, m.faces


def wedge(angle_deg: float = 5.0, length: float = 0.05,
          height: float = 0.03) -> tuple[np.ndarray, np.ndarray]:
    """A prism whose top-view outline is an isosceles triangle with an `angle_deg` apex."""
    half = length * np.tan(np.radians(angle_deg) / 2)
    poly = shapely.Polygon([(0, 0), (length, -half), (length, half)])
    m = trimesh.creation.extrude_polygon(poly, height)
    return m.vertices, m.faces


def comb(teeth: int = 8, slot: float = 0.002, tooth: float = 0.003, depth: float = 0.02,
         spine: float = 0.008, height: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """A comb: `teeth` teeth `tooth` wide with `slot`-wide slots between, on a spine."""
    width = teeth * tooth + (teeth - 1) * slot
    parts = [shapely.box(0, 0, width, spine)]
    parts += [shapely.box(k * (tooth + slot), spine / 2, k * (tooth + slot) + tooth,
                          spine + depth) for k in range(teeth)]
    m = trimesh.creation.extrude_polygon(shapely.union_all(parts), height)
    return m.vertices, m.faces


def open_scan(diameter: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """A scanned bowl: the lower 70 % of a sphere, open at the top (a scan sees no inside)."""
    s = trimesh.creation.icosphere(subdivisions=3)
    keep = s.triangles_center[:, 2] < 0.4
    m = trimesh.Trimesh(s.vertices * diameter / 2, s.faces[keep])
    m.remove_unreferenced_vertices()
    return m.vertices, m.faces


def knot(size: float = 0.05, tube: float = 0.006, samples: int = 160) -> tuple[np.ndarray,
                                                                                np.ndarray]:
    """A trefoil knot: a closed tube of diameter `tube` around a trefoil, flattened so it lies on
    the table."""
    t = np.linspace(0, 2 * np.pi, samples, endpoint=False)
    path = np.c_[np.sin(t) + 2 * np.sin(2 * t), np.cos(t) - 2 * np.cos(2 * t),
                 -0.35 * np.sin(3 * t)] * size / 6
    ring = 12
    tang = np.roll(path, -1, 0) - np.roll(path, 1, 0)
    tang /= np.linalg.norm(tang, axis=1, keepdims=True)
    side = np.cross(tang, [0, 0, 1])
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    up = np.cross(side, tang)
    a = np.linspace(0, 2 * np.pi, ring, endpoint=False)
    verts = (path[:, None] + tube / 2 * (np.cos(a)[None, :, None] * side[:, None]
                                         + np.sin(a)[None, :, None] * up[:, None]))
    verts = verts.reshape(-1, 3)
    faces = []
    for i in range(samples):
        j = (i + 1) % samples
        for k in range(ring):
            q = (k + 1) % ring
            faces += [[i * ring + k, j * ring + k, j * ring + q],
                      [i * ring + k, j * ring + q, i * ring + q]]
    faces = np.array(faces)
    m = trimesh.Trimesh(verts, faces, process=False)
    if m.volume < 0:
        faces = faces[:, ::-1]
    return verts, faces


def dense_sphere(diameter: float = 0.05, subdivisions: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """A closed sphere of 20 * 4**subdivisions faces (327,680 at 7): the cost of a dense scan."""
    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    return s.vertices * diameter / 2, s.faces


@dataclass(frozen=True)
class StressMesh:
    """A hard mesh: its builder, the file suffix it is written as, the footprint (m) it is
    pressed at, and whether it is slow to build (CoACD, or a dense mesh: seconds to minutes)."""

    build: Callable[[], tuple[np.ndarray, np.ndarray]]
    footprint: float
    suffix: str = ".stl"
    decomposed: bool = False


STRESS_MESHES: dict[str, StressMesh] = {
    "near_duplicate_vertices": StressMesh(near_duplicate_sphere, 0.05),
    "slivers_m": StressMesh(lambda: sliver_sphere(0.05), 0.05, ".obj"),
    "slivers_mm": StressMesh(lambda: sliver_sphere(50.0), 0.05, ".obj"),
    "thin_plate": StressMesh(lambda: box_mesh(0.06, 0.04, 0.0015), 0.06),
    "needle": StressMesh(needle, 0.06),
    "object_2mm": StressMesh(lambda: box_mesh(0.002, 0.002, 0.002), 0.002),
    "object_300mm": StressMesh(lambda: box_mesh(0.3, 0.3, 0.03), 0.3),
    "wedge_5deg": StressMesh(wedge, 0.05),
    "comb_2mm_slots": StressMesh(comb, 0.045),
    "open_scan": StressMesh(open_scan, 0.05, ".ply", decomposed=True),
    "knot": StressMesh(knot, 0.05, decomposed=True),
    "sphere_327k_faces": StressMesh(dense_sphere, 0.05, ".ply", decomposed=True),
}
