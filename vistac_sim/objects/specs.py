"""What to build, before anything is built: `ObjectSpec`, the procedural library, and which
object each configuration uses.

Light on purpose (no meshes, no MuJoCo): the `generate` driver plans a run from these alone;
`vistac_sim.objects.library` builds a spec into a `BuiltObject` inside the worker that needs it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vistac_sim.objects.config import ObjectsCfg


@dataclass(frozen=True)
class ObjectSpec:
    """What to build: a procedural family drawn from `seed`, or a mesh file."""

    object_id: str
    family: str  # a procedural family name, or "mesh"
    seed: int
    footprint: float  # m, longest side of the top-view outline
    height: float  # m, extrusion height (procedural only)
    path: str = ""  # mesh file (family "mesh")


def procedural_library(cfg: ObjectsCfg, seed: int) -> list[ObjectSpec]:
    """The procedural object library of a run: `n_objects` specs cycling through the families."""
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


def object_index(seed: int, config_id: int, n_objects: int) -> int:
    """Which object of the library configuration `config_id` uses."""
    return int(np.random.SeedSequence([seed, config_id, 7]).generate_state(1, np.uint64)[0]
               % n_objects)
