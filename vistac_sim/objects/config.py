"""Which objects lie on the table."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from vistac.config import Config, ConfigError, param
from vistac_sim.objects.outlines import PROCEDURAL_FAMILIES


@dataclass(frozen=True)
class ObjectsCfg(Config):
    """The object library of a run: procedural families drawn from the seed, or user meshes."""

    families: tuple[str, ...] = param(
        PROCEDURAL_FAMILIES, choices=PROCEDURAL_FAMILIES, metavar="FAMILY",
        help=f"procedural families ({', '.join(PROCEDURAL_FAMILIES)})")
    paths: tuple[str, ...] = param(
        (), flag="--objects", metavar="PATH",
        help="mesh files or folders (STL, OBJ, PLY, GLB) instead of the built-in procedural "
        "families")
    n_objects: int = param(32, ge=1, le=100_000, help="size of the procedural object library")
    footprint: tuple[float, float] = param(
        (0.035, 0.075), ge=0.001, metavar=("MIN", "MAX"),
        why="an object smaller than 1 mm cannot be built as a mesh",
        help="longest top-view side of objects, metres")
    height: tuple[float, float] = param((0.03, 0.05), gt=0, le=1,
                                        help="m, extrusion height of procedural objects")
    min_height: float = param(0.0005, gt=0,
                              help="m, lowest object (after scaling) that can be pressed; flat "
                              "parts lower than twice the fingertip height are pressed at half "
                              "their height")
    min_wall: float = param(0.001, gt=0, help="m, thinnest wall a procedural outline may have")
    shape_tolerance: float = param(
        0.05, gt=0, le=1,
        help="farthest a mesh's convex collision pieces may lie from the mesh itself, as a "
        "fraction of the footprint (farther: decomposed again, finer, else the mesh is skipped)")
    strict: bool = param(False, help="a bad mesh in a folder aborts the run instead of being "
                         "skipped")

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("footprint", "height"):
            lo, hi = getattr(self, name)
            if lo > hi:
                raise ConfigError(name, f"MIN must be <= MAX, got {lo:g} > {hi:g}")
        if not self.families:
            raise ConfigError("families", "needs at least one family")
        # stored absolute: a manifest names the same files wherever the run is resumed from
        absolute = tuple(str(Path(p).expanduser().resolve()) for p in self.paths)
        object.__setattr__(self, "paths", absolute)
