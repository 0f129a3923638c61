"""Objects on the table: procedural extrusions and user meshes, with convex collision pieces.

An object is described by a light, picklable `ObjectSpec` (what to build) and built into a
`BuiltObject` (meshes in the object frame: xy centred on the footprint, table at z = 0) inside the
worker that needs it. The full-resolution mesh stays the visual and the reference for surface
normals; MuJoCo collides the convex `pieces` (it would otherwise collide a mesh as its hull).

Press height: the fingertip axis runs at `HandCfg.height` (12 mm), or at half the object's height
for an object lower than twice that, so flat and low parts (plates, a tube lying down) are
pressed on the middle of their side walls (the table does not collide with the fingers). Objects
lower than `ObjectsCfg.min_height` are refused.
"""

from __future__ import annotations

import colorsys
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from shapely.geometry import Polygon

from vistac.errors import UserError
from vistac_sim.objects import outlines
from vistac_sim.objects.config import ObjectsCfg
from vistac_sim.objects.decomposition import (
    collision_fidelity,
    convex_decomposition,
    pieces_section,
)
from vistac_sim.objects.meshes import (
    find_mesh_files,
    load_mesh,
    mesh_section,
    scale_to_footprint,
)
from vistac_sim.objects.specs import ObjectSpec, procedural_library

__all__ = ["ObjectSpec", "BuiltObject", "build_object", "extruded_object", "mesh_library",
           "press_height", "procedural_library"]


@dataclass
class BuiltObject:
    """A built object, ready for the scene, grasp sampling and normal look-ups."""

    spec: ObjectSpec
    mesh: trimesh.Trimesh  # full-resolution, object frame
    pieces: list[trimesh.Trimesh]  # convex collision pieces, object frame
    section: Polygon  # cross-section at the press height (object frame, xy)
    rgb: tuple[float, float, float]
    press_height: float | None = None  # m, fingertip axis above the table (None: the hand's)
    vertical_walls: bool = True  # the pieces' section is the same at every height (extrusions)

    @property
    def object_id(self) -> str:
        return self.spec.object_id


def press_height(object_height: float, finger_height: float, min_height: float = 0.0005,
                 name: str = "object") -> float:
    """Height of the fingertip axis for an object of `object_height` (module docstring).

    Raises:
        UserError: the object is lower than `min_height`.
    """
    if object_height < min_height:
        raise UserError(f"{name}: too low to press ({object_height * 1000:.2f} mm < "
                        f"{min_height * 1000:g} mm, objects.min_height)")
    return min(finger_height, object_height / 2)


FINER_CONCAVITY = 0.02
FINER_PIECES = 48
"""CoACD's concavity threshold and most pieces for a second decomposition when the first lies
too far from the mesh (the first: CoACD's default 0.05, at most 16 pieces)."""


def build_object(spec: ObjectSpec, finger_height: float, min_wall: float = 0.001,
                 cache_dir: Path | None = None, min_height: float = 0.0005,
                 shape_tolerance: float = 0.05) -> BuiltObject:
    """Build the meshes, collision pieces and press-height section of one object.

    A mesh's section is the section of its collision pieces (what the fingers will touch). The
    pieces are measured against the mesh the labels' normals come from (`collision_fidelity`);
    farther than `shape_tolerance` x the footprint, the mesh is decomposed again, finer
    (`FINER_CONCAVITY`), and refused if it stays that far. The measure and what was done are
    added to ``mesh.metadata["repairs"]``.

    Raises:
        UserError: naming the file: unreadable or broken, too low, no section at the press
            height, or collision pieces farther from the mesh than the tolerance.
    """
    rng = np.random.default_rng(spec.seed)
    rgb = _object_colour(rng)
    if spec.family != "mesh":
        poly = outlines.outline(spec.family, rng, spec.footprint, min_wall)
        obj = extruded_object(spec, poly, rgb)
        obj.press_height = press_height(spec.height, finger_height, min_height, spec.object_id)
        return obj
    mesh = scale_to_footprint(load_mesh(spec.path), spec.footprint)
    z = press_height(float(mesh.bounds[1, 2]), finger_height, min_height, spec.path)
    outline = extrusion_outline(mesh)
    if outline is not None:  # a prism (most CAD plates and brackets): its exact pieces
        obj = BuiltObject(spec=spec, mesh=mesh, pieces=[
            trimesh.creation.extrude_polygon(p, float(mesh.bounds[1, 2]))
            for p in outlines.convex_pieces(outline)], section=outline, rgb=rgb, press_height=z)
        mesh.metadata.setdefault("repairs", []).append(
            f"an extrusion: collided as its {len(obj.pieces)} exact convex piece(s)")
        return obj
    pieces = _faithful_pieces(mesh, spec, cache_dir, shape_tolerance)
    section = pieces_section(pieces, z)
    if section.is_empty:
        raise UserError(f"{spec.path}: its collision pieces have no section at the press height "
                        f"({z * 1000:.1f} mm)")
    if section.geom_type != "Polygon":
        section = max(section.geoms, key=lambda g: g.area)
    return BuiltObject(spec=spec, mesh=mesh, pieces=pieces, section=section, rgb=rgb,
                       press_height=z, vertical_walls=False)


def extrusion_outline(mesh: trimesh.Trimesh, tol: float = 1e-6) -> Polygon | None:
    """The top-view outline of a closed mesh that is a straight extrusion of it from the table
    (every face horizontal or vertical, volume = outline area x height), else None."""
    if not mesh.is_watertight:
        return None
    nz = np.abs(mesh.face_normals[:, 2])
    if not np.all((nz < tol) | (nz > 1 - tol)):
        return None
    height = float(mesh.bounds[1, 2] - mesh.bounds[0, 2])
    try:
        outline = mesh_section(mesh, height / 2)
    except UserError:
        return None
    if abs(outline.area * height - mesh.volume) > 1e-4 * mesh.volume:
        return None
    return outline


def _faithful_pieces(mesh: trimesh.Trimesh, spec: ObjectSpec, cache_dir: Path | None,
                     tolerance: float) -> list[trimesh.Trimesh]:
    """The mesh's convex collision pieces, measured against it (see `build_object`)."""
    notes = mesh.metadata.setdefault("repairs", [])
    limit = tolerance * spec.footprint
    pieces = convex_decomposition(mesh, cache_dir)
    fid = collision_fidelity(mesh, pieces)
    if fid["hausdorff"] > limit:
        finer = convex_decomposition(mesh, cache_dir, threshold=FINER_CONCAVITY,
                                     max_pieces=FINER_PIECES)
        finer_fid = collision_fidelity(mesh, finer)
        if finer_fid["hausdorff"] < fid["hausdorff"]:
            notes.append(f"decomposed again at concavity {FINER_CONCAVITY:g} (up to "
                         f"{FINER_PIECES} pieces): "
                         f"{fid['hausdorff'] * 1000:.2f} mm -> "
                         f"{finer_fid['hausdorff'] * 1000:.2f} mm")
            pieces, fid = finer, finer_fid
    ratio = fid["volume_ratio"]
    notes.append(f"collision shape: {len(pieces)} convex piece(s), within "
                 f"{fid['hausdorff'] * 1000:.3f} mm of the mesh "
                 f"({100 * fid['hausdorff'] / spec.footprint:.2f} % of the footprint)"
                 + ("" if np.isnan(ratio) else f", volume ratio {ratio:.4f}"))
    if fid["hausdorff"] > limit:
        raise UserError(f"{spec.path}: its collision shape lies {fid['hausdorff'] * 1000:.2f} mm "
                        f"from the mesh ({100 * fid['hausdorff'] / spec.footprint:.1f} % of the "
                        f"footprint; objects.shape_tolerance {100 * tolerance:g} %), even "
                        "decomposed finer")
    return pieces


def extruded_object(spec: ObjectSpec, poly: Polygon,
                    rgb: tuple[float, float, float] = (0.25, 0.3, 0.7)) -> BuiltObject:
    """An outline extruded to `spec.height`, collided as its exact convex pieces."""
    mesh = trimesh.creation.extrude_polygon(poly, spec.height)
    pieces = [trimesh.creation.extrude_polygon(p, spec.height)
              for p in outlines.convex_pieces(poly)]
    return BuiltObject(spec=spec, mesh=mesh, pieces=pieces, section=poly, rgb=rgb)


def _object_colour(rng: np.random.Generator) -> tuple[float, float, float]:
    """A colour far from the index green and thumb red: hues of yellow, cyan, blue or purple."""
    hue = rng.choice([rng.uniform(35, 65), rng.uniform(185, 290)]) / 360.0
    return tuple(float(c) for c in colorsys.hsv_to_rgb(hue, rng.uniform(0.35, 0.75),
                                                        rng.uniform(0.35, 0.8)))


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
            build_object(spec, finger_height, cache_dir=cache_dir, min_height=cfg.min_height,
                         shape_tolerance=cfg.shape_tolerance)
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
