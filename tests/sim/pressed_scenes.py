"""A pressed procedural scene for the image-effect tests (one owner for the helper)."""

from __future__ import annotations

import numpy as np

from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.rigs import ObjectRig, solve
from vistac_sim.objects.library import build_object, procedural_library
from vistac_sim.physics.checks import RejectedSample


def pressed_scene(cfg: GenerateCfg, spec_index: int = 0, seed: int = 1) -> ObjectRig:
    """Procedural object `spec_index` pressed by the first grasp of `seed` that gives labels."""
    spec = procedural_library(cfg.objects, 3)[spec_index]
    scene = ObjectRig(build_object(spec, cfg.hand.height), cfg)
    rng = np.random.default_rng(seed)
    while True:
        try:
            solve(scene, scene.sampler.sample(rng), cfg)
            return scene
        except RejectedSample:
            continue
