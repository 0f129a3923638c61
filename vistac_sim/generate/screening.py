"""Screening one object before a `vistac generate` run: build it and draw a valid grasp.

Runs in the workers (it builds a scene, with the simulator it imports when called: the driver
hands it to forked workers without importing the simulator); `objects_report.screen_objects`
keeps or skips the objects from what this returns.
"""

from __future__ import annotations

import numpy as np

from vistac.errors import UserError
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.objects.specs import ObjectSpec


def screen_object(job: tuple[int, ObjectSpec, GenerateCfg]
                  ) -> tuple[str | None, dict[str, int], list[str]]:
    """Build object `k` of the library and draw grasps (seeded by the run's seed and `k`) until
    one passes every check.

    Returns:
        None or the reason to skip it, its rejected draws by reason, the repairs made to its mesh.
    """
    from vistac_sim.generate.rigs import NoValidGrasp, ObjectRig, draw_grasp
    from vistac_sim.objects.decomposition import default_cache_dir
    from vistac_sim.objects.library import build_object

    k, spec, cfg = job
    rng = np.random.default_rng([cfg.seed, k, 0x5C4EE7])
    try:
        obj = build_object(spec, cfg.hand.height, cfg.objects.min_wall, default_cache_dir(),
                           cfg.objects.min_height, cfg.objects.shape_tolerance)
        scene = ObjectRig(obj, cfg, render=False)
    except UserError as exc:
        return str(exc), {}, []
    except Exception as exc:  # one object must never abort a run
        return f"cannot build the object ({type(exc).__name__}: {exc})", {}, []
    notes = list(obj.mesh.metadata.get("repairs", []))
    try:
        draw_grasp(scene, rng, cfg)
    except NoValidGrasp as exc:
        counts = dict(sorted(exc.redraws.items()))
        return exc.summary(), counts, notes
    finally:
        scene.close()
    return None, {}, notes
