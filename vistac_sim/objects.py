"""Objects on the table: procedural extrusions and user meshes, with convex collision pieces.

An object is described by a light, picklable `ObjectSpec` (what to build) and built into a
`SceneObject` (meshes in the object frame: xy centred on the footprint, table at z = 0) inside the
worker that needs it. The full-resolution mesh stays the visual and the reference for surface
normals; MuJoCo collides the convex `pieces` (it would otherwise collide a mesh as its hull).
"""

from __future__ import annotations

import colorsys
import hashlib
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely
import trimesh
from shapely.geometry import Polygon

from vistac_sim import outlines
from vistac_sim.config import ObjectsCfg
from vistac_sim.errors import UserError

MESH_SUFFIXES = (".stl", ".obj", ".ply", ".glb", ".gltf", ".off")


@dataclass(frozen=True)
class ObjectSpec:
    """What to build: a procedural family drawn from `seed`, or a mesh file."""

    object_id: str
    family: str  # a procedural family name, or "mesh"
    seed: int
    footprint: float  # m, longest side of the top-view outline
    height: float  # m, extrusion height (procedural only)
    path: str = ""  # mesh file (family "mesh")


@dataclass
class SceneObject:
    """A built object, ready for the scene, grasp sampling and normal look-ups."""

    spec: ObjectSpec
    mesh: trimesh.Trimesh  # full-resolution, object frame
    pieces: list[trimesh.Trimesh]  # convex collision pieces, object frame
    section: Polygon  # cross-section at fingertip height (object frame, xy)
    rgb: tuple[float, float, float]

    @property
    def object_id(self) -> str:
        return self.spec.object_id


def procedural_library(cfg: ObjectsCfg, seed: int) -> list[ObjectSpec]:
    """The procedural object library of a run: `n_objects` specs cycling through the families."""
    for fam in cfg.families:
        if fam not in outlines.families():
            known = ", ".join(outlines.families())
            raise UserError(f"unknown object family {fam!r}; known: {known}")
    root = np.random.SeedSequence([seed, 0xB0B])
    specs = []
    for k, child in enumerate(root.spawn(cfg.n_objects)):
        rng = np.random.default_rng(child)
        fam = cfg.families[k % len(cfg.families)]
        specs.append(
            ObjectSpec(
                object_id=f"{fam}_{k:03d}",
                family=fam,
                seed=int(rng.integers(2**31)),
                footprint=float(rng.uniform(*cfg.footprint)),
                height=float(rng.uniform(*cfg.height)),
            )
        )
    return specs


def build_object(spec: ObjectSpec, finger_height: float, min_wall: float = 0.001,
                 cache_dir: Path | None = None) -> SceneObject:
    """Build the meshes, collision pieces and finger-height section of one object."""
    rng = np.random.default_rng(spec.seed)
    rgb = _object_colour(rng)
    if spec.family == "mesh":
        mesh = scale_to_footprint(load_mesh(spec.path), spec.footprint)
        section = mesh_section(mesh, finger_height, spec.path)
        pieces = convex_decomposition(mesh, cache_dir)
    else:
        poly = outlines.outline(spec.family, rng, spec.footprint, min_wall)
        return extruded_object(spec, poly, rgb)
    return SceneObject(spec=spec, mesh=mesh, pieces=pieces, section=section, rgb=rgb)


def extruded_object(spec: ObjectSpec, poly: Polygon,
                    rgb: tuple[float, float, float] = (0.25, 0.3, 0.7)) -> SceneObject:
    """An outline extruded to `spec.height`, collided as its exact convex pieces."""
    mesh = trimesh.creation.extrude_polygon(poly, spec.height)
    pieces = [trimesh.creation.extrude_polygon(p, spec.height)
              for p in outlines.convex_pieces(poly)]
    return SceneObject(spec=spec, mesh=mesh, pieces=pieces, section=poly, rgb=rgb)


def _object_colour(rng: np.random.Generator) -> tuple[float, float, float]:
    """A colour far from the index green and thumb red: hues of yellow, cyan, blue or purple."""
    hue = rng.choice([rng.uniform(35, 65), rng.uniform(185, 290)]) / 360.0
    return tuple(float(c) for c in colorsys.hsv_to_rgb(hue, rng.uniform(0.35, 0.75),
                                                        rng.uniform(0.35, 0.8)))


# ----------------------------------------------------------------------------------- user meshes
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


def convex_decomposition(mesh: trimesh.Trimesh, cache_dir: Path | None,
                         threshold: float = 0.05) -> list[trimesh.Trimesh]:
    """Convex pieces of a mesh: itself if convex, else CoACD, cached on disk by mesh hash."""
    if mesh.convex_hull.volume - mesh.volume <= 1e-3 * mesh.volume:
        return [mesh.convex_hull]
    key = hashlib.sha256(
        mesh.vertices.astype("<f8").tobytes() + mesh.faces.astype("<i8").tobytes()
        + f"coacd-{threshold}".encode()
    ).hexdigest()[:32]
    cache = Path(cache_dir or default_cache_dir()) / f"{key}.npz"
    if cache.exists():
        data = np.load(cache)
        return [trimesh.Trimesh(data[f"v{i}"], data[f"f{i}"]) for i in range(int(data["n"]))]
    import coacd

    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(mesh.vertices, mesh.faces), threshold=threshold, seed=0)
    pieces = [trimesh.Trimesh(np.asarray(v), np.asarray(f)).convex_hull for v, f in parts]
    cache.parent.mkdir(parents=True, exist_ok=True)
    tmp = cache.with_suffix(f".{os.getpid()}.tmp.npz")
    arrays = {f"v{i}": p.vertices for i, p in enumerate(pieces)}
    arrays.update({f"f{i}": p.faces for i, p in enumerate(pieces)})
    np.savez(tmp, n=len(pieces), **arrays)
    os.replace(tmp, cache)
    return pieces


def default_cache_dir() -> Path:
    """Where convex decompositions are cached ($VISTAC_CACHE or ~/.cache/vistac/coacd)."""
    root = os.environ.get("VISTAC_CACHE") or Path.home() / ".cache" / "vistac"
    return Path(root) / "coacd"


def mesh_library(cfg: ObjectsCfg, seed: int, finger_height: float,
                 cache_dir: Path | None = None) -> tuple[list[ObjectSpec], list[dict]]:
    """Specs for the user meshes of `cfg.paths`; bad meshes are skipped (or fatal if strict).

    Each mesh is checked, scaled and decomposed once here (the decomposition is cached), so the
    workers only read the cache. Returns the specs and the skipped files with their reasons.
    """
    files = find_mesh_files(cfg.paths)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0x3E5]))
    specs, skipped = [], []
    for k, f in enumerate(files):
        footprint = float(rng.uniform(*cfg.footprint))
        spec = ObjectSpec(object_id=f"{f.stem}_{k:03d}", family="mesh",
                          seed=int(rng.integers(2**31)), footprint=footprint, height=0.0,
                          path=str(f.resolve()))
        try:
            build_object(spec, finger_height, cache_dir=cache_dir)
        except UserError as exc:
            if cfg.strict or len(files) == 1:
                raise
            warnings.warn(f"skipping mesh: {exc}", stacklevel=2)
            skipped.append({"path": str(f), "reason": str(exc)})
            continue
        specs.append(spec)
    if not specs:
        raise UserError("no usable mesh among " + ", ".join(map(str, cfg.paths)))
    return specs, skipped
