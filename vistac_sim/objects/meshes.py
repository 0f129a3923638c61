"""User meshes: finding, reading and checking them, scaling to a footprint, the finger-height
section."""

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


def find_mesh_files(paths: list[str] | tuple[str, ...]) -> list[Path]:
    """Expand files and folders into a sorted list of mesh files; a missing path is an error."""
    files: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(f for f in p.rglob("*") if f.suffix.lower() in MESH_SUFFIXES)
            if not found:
                raise UserError(f"{p}: folder holds no mesh files ({', '.join(MESH_SUFFIXES)})")
            files += found
        elif p.is_file():
            files.append(p)
        else:
            raise UserError(f"{p}: no such file or folder")
    return files


def load_mesh(path: str | os.PathLike) -> trimesh.Trimesh:
    """Read and check one mesh file.

    Raises:
        UserError: naming the file and the reason: unreadable format, points only, empty,
            non-finite vertices, zero volume, or not a closed surface (open or non-manifold soup).
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
    mesh = loaded
    if len(mesh.faces) == 0:
        raise UserError(f"{path}: empty mesh (no triangles)")
    if not np.isfinite(mesh.vertices).all():
        raise UserError(f"{path}: vertex coordinates are NaN or infinite")
    mesh = trimesh.Trimesh(mesh.vertices, mesh.faces, process=True)  # merge duplicate vertices
    ext = mesh.extents
    if ext.min() <= 1e-9 * max(ext.max(), 1e-30):
        raise UserError(f"{path}: zero volume (the mesh is flat or degenerate)")
    soup = f"{path}: not a closed surface (open or non-manifold triangle soup)"
    was_open = not mesh.is_watertight
    if was_open:
        trimesh.repair.fill_holes(mesh)  # small holes only; a soup stays open or encloses nothing
    if not mesh.is_watertight or not mesh.is_winding_consistent:
        raise UserError(soup)
    if mesh.volume < 0:
        mesh.invert()
    if abs(mesh.volume) <= 1e-9 * ext.prod():
        raise UserError(soup if was_open else f"{path}: zero volume (the mesh encloses no space)")
    return mesh


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
