"""User meshes: finding, reading, checking and repairing them, scaling to a footprint, the
section at a height.

What is truly broken (unreadable, no triangles, NaN or infinite vertices, flat, a triangle soup
that is no surface) is refused with the file named. Everything else is repaired: vertices
closer than 1e-6 of the mesh's size welded (by distance), sliver faces merged into their
neighbours (T-junctions closed), degenerate and repeated faces dropped, holes closed
with a fan of triangles, winding made consistent and the normals turned outwards. A mesh that
stays open after that is still used: it is collided through its convex decomposition (which needs
no closed surface) and its faces, oriented outwards as well as they can be, give the normals.
Every repair runs on the mesh scaled to a
unit size, so a file in metres and the same file in millimetres are repaired alike.
`mesh.metadata["repairs"]` lists what was done.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np
import shapely
import trimesh
from shapely.geometry import Polygon

from vistac.errors import UserError

MESH_SUFFIXES = (".stl", ".obj", ".ply", ".glb", ".gltf", ".off")
MIN_SHARED_EDGES = 0.5  # an open surface joins most of its edges to two faces; a soup does not


def find_mesh_files(paths: list[str] | tuple[str, ...]) -> list[Path]:
    """Expand files and folders into a sorted list of mesh files; a missing path is an error."""
    files: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(f for f in p.rglob("*") if f.suffix.lower() in MESH_SUFFIXES)
            for f in found:
                if f.is_symlink() and not os.path.exists(f):  # dangling, or a loop (ELOOP)
                    raise UserError(f"{f}: a symbolic link that leads to no file (dangling, or "
                                    "a loop back to itself); remove it or point it at a mesh")
            found = [f for f in found if os.path.isfile(f)]  # folders named like meshes
            if not found:
                raise UserError(f"{p}: folder holds no mesh files ({', '.join(MESH_SUFFIXES)})")
            files += found
        elif p.is_file():
            files.append(p)
        else:
            raise UserError(f"{p}: no such file or folder")
    return files


def load_mesh(path: str | os.PathLike) -> trimesh.Trimesh:
    """Read, check and repair one mesh file.

    Raises:
        UserError: naming the file and the reason: unreadable format, points only, empty,
            non-finite vertices, zero volume, or a triangle soup that forms no surface.
    """
    path = Path(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise UserError(f"{path}: cannot read mesh ({type(exc).__name__}: {exc})") from None
    if not isinstance(loaded, trimesh.Trimesh):
        raise UserError(f"{path}: holds no triangles (points or lines only)")
    if len(loaded.faces) == 0:
        raise UserError(f"{path}: empty mesh (no triangles)")
    if not np.isfinite(loaded.vertices).all():
        raise UserError(f"{path}: vertex coordinates are NaN or infinite")
    return repair_mesh(loaded.vertices, loaded.faces, str(path))


WELD_TOL = 1e-6
"""Vertices closer than this (a fraction of the mesh's longest side) are one vertex."""
SLIVER_TOL = 1e-5
"""A face narrower than this (its height over its longest edge, a fraction of the mesh's longest
side) is a sliver: a T-junction's filler or a collapsed needle."""


def repair_mesh(vertices: np.ndarray, faces: np.ndarray, name: str = "mesh") -> trimesh.Trimesh:
    """A checked, repaired mesh from raw arrays (see the module's docstring).

    Every repair runs on the mesh scaled to a unit longest side (and is scaled back after), so
    its outcome does not depend on the file's units.

    Raises:
        UserError: "zero volume" (flat or degenerate) or "not a surface" (triangle soup).
    """
    vertices = np.asarray(vertices, float)
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    lo = vertices.min(axis=0) if len(vertices) else np.zeros(3)
    size = float((vertices.max(axis=0) - lo).max()) if len(vertices) else 0.0
    if size <= 0:
        raise UserError(f"{name}: zero volume (the mesh is flat or degenerate)")
    mesh, notes = _repair_unit(vertices - lo, faces, size, name)
    mesh.apply_scale(size)
    mesh.apply_translation(lo)
    mesh.metadata["repairs"] = notes
    return mesh


def _repair_unit(vertices: np.ndarray, faces: np.ndarray, size: float,
                 name: str) -> tuple[trimesh.Trimesh, list[str]]:
    """`repair_mesh` on vertices shifted to the origin, scaled here to a unit longest side."""
    notes: list[str] = []
    unit_v = vertices / size
    welded, faces = weld_vertices(unit_v, faces, WELD_TOL)
    if len(welded) < len(unit_v):
        notes.append(f"welded {len(unit_v) - len(welded)} vertices closer than {WELD_TOL:g} of "
                     "the size")
    faces, merged, dropped = merge_slivers(welded, faces, SLIVER_TOL)
    if merged:
        notes.append(f"merged {merged} sliver faces into their neighbours")
    if dropped:
        notes.append(f"dropped {dropped} sliver faces with no neighbour to merge into")
    mesh = trimesh.Trimesh(welded, faces, process=False)
    n_face = len(mesh.faces)
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    if len(mesh.faces) < n_face:
        notes.append(f"dropped {n_face - len(mesh.faces)} degenerate or repeated faces")
    ext = mesh.extents if len(mesh.faces) else np.zeros(3)
    if len(mesh.faces) == 0 or ext.min() <= 1e-9 * max(ext.max(), 1e-30):
        raise UserError(f"{name}: zero volume (the mesh is flat or degenerate)")
    shared = float(np.mean(np.bincount(mesh.edges_unique_inverse) == 2))
    if shared < MIN_SHARED_EDGES:
        raise UserError(f"{name}: not a surface (triangle soup: only {100 * shared:.0f} % of "
                        "edges join two faces)")
    if not mesh.is_watertight:
        filled = _fill_holes(mesh)
        if filled is not None:
            mesh = filled
            notes.append("filled holes")
    before = mesh.faces.copy()
    trimesh.repair.fix_winding(mesh)
    if mesh.is_watertight and mesh.is_winding_consistent:
        if mesh.volume < 0:
            mesh.invert()
        if abs(mesh.volume) <= 1e-9 * ext.prod():
            raise UserError(f"{name}: zero volume (the mesh encloses no space)")
    else:
        _orient_outwards(mesh)
        notes.append("open surface: collided through its convex decomposition")
    if not np.array_equal(before, mesh.faces):
        notes.append("fixed winding / normals")
    return mesh, notes


def weld_vertices(vertices: np.ndarray, faces: np.ndarray,
                  tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices closer than `tol` (chains included) made one (the first of each group); faces
    renumbered. By distance, not by rounding to a grid: two vertices 1e-9 apart on either side
    of a grid line are welded too."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    n = len(vertices)
    pairs = cKDTree(vertices).query_pairs(tol, output_type="ndarray")
    if len(pairs) == 0:
        used = np.unique(faces)
        if len(used) == n:
            return vertices, faces
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    # the first vertex of each group stands for it; unreferenced vertices are left out
    first = np.full(label.max() + 1, n)
    np.minimum.at(first, label, np.arange(n))
    keep = np.unique(first[label[faces.ravel()]])
    new_index = np.full(n, -1)
    new_index[keep] = np.arange(len(keep))
    return vertices[keep], new_index[first[label]][faces]


def merge_slivers(vertices: np.ndarray, faces: np.ndarray,
                  tol: float) -> tuple[np.ndarray, int, int]:
    """Faces narrower than `tol` merged away: a sliver (a, b, m) whose apex m lies on its longest
    edge ab (a T-junction's filler) is removed and the face across ab is split at m, so the
    surface stays closed; one whose neighbour is missing (or a sliver too) is dropped.
    Faces with a repeated vertex (welded needles) are dropped by the caller.

    Returns:
        The new faces, how many slivers were merged, how many dropped.
    """
    tri = vertices[faces]
    edges = np.roll(tri, -1, axis=1) - tri  # edge k runs from corner k to corner k + 1
    length = np.linalg.norm(edges, axis=2)
    area2 = np.linalg.norm(np.cross(edges[:, 0], -edges[:, 2]), axis=1)
    longest = length.argmax(axis=1)
    height = area2 / np.maximum(length.max(axis=1), 1e-300)
    distinct = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (
        faces[:, 2] != faces[:, 0])
    slivers = np.flatnonzero((height < tol) & distinct)
    if len(slivers) == 0:
        return faces, 0, 0
    out = [list(f) for f in faces.tolist()]
    alive = np.ones(len(out), bool)
    by_edge: dict[tuple[int, int], int] = {}
    for i, f in enumerate(out):
        for k in range(3):
            by_edge[(f[k], f[(k + 1) % 3])] = i
    is_sliver = np.zeros(len(out), bool)
    is_sliver[slivers] = True
    merged = dropped = 0
    for s in slivers.tolist():
        k = int(longest[s])
        a, b, m = out[s][k], out[s][(k + 1) % 3], out[s][(k + 2) % 3]
        alive[s] = False
        n = by_edge.get((b, a))
        if n is None or not alive[n] or is_sliver[n]:
            dropped += 1
            continue
        f = out[n]
        j = f.index(b)
        d = f[(j + 2) % 3]  # f is (b, a, d) turned
        out[n] = [b, m, d]
        out.append([m, a, d])
        alive = np.append(alive, True)
        is_sliver = np.append(is_sliver, False)
        for face_id, g in ((n, out[n]), (len(out) - 1, out[-1])):
            for q in range(3):
                by_edge[(g[q], g[(q + 1) % 3])] = face_id
        merged += 1
    return np.asarray(out, np.int64)[alive], merged, dropped


def _fill_holes(mesh: trimesh.Trimesh) -> trimesh.Trimesh | None:
    """Close every hole with a fan of triangles around its centroid; None if it stays open.

    A boundary edge a->b of a face gets the fill face (b, a, c), so the fill is wound like its
    neighbours.
    """
    directed = mesh.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.sort(directed, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    boundary = directed[counts[inverse.ravel()] == 1]
    if len(boundary) == 0:
        return None
    loops = trimesh.graph.connected_components(boundary, min_len=3)
    verts = [mesh.vertices]
    faces = [mesh.faces]
    for loop in loops:
        centre = len(mesh.vertices) + len(verts) - 1
        verts.append(mesh.vertices[loop].mean(axis=0)[None])
        edges = boundary[np.isin(boundary[:, 0], loop)]
        faces.append(np.c_[edges[:, 1], edges[:, 0], np.full(len(edges), centre)])
    out = trimesh.Trimesh(np.concatenate(verts), np.concatenate(faces), process=False)
    if not (out.is_watertight and out.is_winding_consistent):
        return None
    return out


def _orient_outwards(mesh: trimesh.Trimesh) -> None:
    """Flip each connected piece of an open mesh whose faces mostly face its own centre."""
    groups = trimesh.graph.connected_components(mesh.face_adjacency,
                                                nodes=np.arange(len(mesh.faces)))
    centres, normals, areas = mesh.triangles_center, mesh.face_normals, mesh.area_faces
    flip = np.zeros(len(mesh.faces), bool)
    for g in groups:
        c = np.average(centres[g], axis=0, weights=areas[g] + 1e-30)
        if np.sum(((centres[g] - c) * normals[g]).sum(1) * areas[g]) < 0:
            flip[g] = True
    if flip.any():
        mesh.faces[flip] = mesh.faces[flip][:, ::-1]
        mesh._cache.clear()


def scale_to_footprint(mesh: trimesh.Trimesh, footprint: float) -> trimesh.Trimesh:
    """Scale uniformly so the longest top-view side is `footprint`; centre xy, rest on z = 0."""
    mesh = mesh.copy()
    lo, hi = mesh.bounds
    mesh.apply_translation([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    mesh.apply_scale(footprint / max(hi[0] - lo[0], hi[1] - lo[1]))
    return mesh


def mesh_section(mesh: trimesh.Trimesh, z: float, name: str = "mesh") -> Polygon:
    """Largest polygon of the mesh's cross-section at height z (object frame)."""
    sec = mesh.section(plane_origin=[0, 0, z], plane_normal=[0, 0, 1])
    if sec is None:
        raise UserError(f"{name}: the object is lower than the fingertip ({z * 1000:.1f} mm)")
    planar, to_3d = sec.to_2D()
    polys = [shapely.transform(p, lambda xy, m=to_3d: _apply_2d(m, xy))
             for p in planar.polygons_full]
    if not polys:
        raise UserError(f"{name}: the cross-section at fingertip height is not a closed outline")
    return max(polys, key=lambda p: p.area)


def _apply_2d(matrix: np.ndarray, xy: np.ndarray) -> np.ndarray:
    pts = np.c_[xy, np.zeros(len(xy)), np.ones(len(xy))] @ matrix.T
    return pts[:, :2]
