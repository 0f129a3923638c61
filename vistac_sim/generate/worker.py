"""What a `generate` worker process does: screen an object, make and commit chunks.

The driver (`vistac_sim.generate.run`) plans and never builds a scene itself; everything that
needs meshes, MuJoCo or a renderer lives here, imported once by the fork server that the workers
fork from (`processes.worker_context`), or in the driver's own process when it runs with one worker.
A chunk is a pure function of (seed, config ids, config), so the dataset is identical whatever
the number of workers.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vistac.dataset import files
from vistac.dataset.recordings import recording_name
from vistac.dataset.schema import IMAGES, MASKS
from vistac.errors import UserError
from vistac_sim.effects import build_pipeline
from vistac_sim.effects.registry import Pipeline
from vistac_sim.generate import shards
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.configuration import Configuration, make_configuration
from vistac_sim.generate.rigs import NoValidGrasp, ObjectRig, RigCache, draw_grasp
from vistac_sim.generate.run import Chunk
from vistac_sim.objects.decomposition import default_cache_dir
from vistac_sim.objects.library import build_object
from vistac_sim.objects.specs import ObjectSpec


# ------------------------------------------------------------------------- screening an object
def screen_object(job: tuple[int, ObjectSpec, GenerateCfg]
                  ) -> tuple[str | None, dict[str, int], list[str]]:
    """Build object `k` of the library and draw grasps (seeded by the run's seed and `k`) until
    one passes every check.

    Returns:
        None or the reason to skip it, its rejected draws by reason, the repairs made to its mesh.
    """
    k, spec, cfg = job
    rng = np.random.default_rng([cfg.seed, k, 0x5C4EE7])
    try:
        obj = build_object(spec, cfg.hand.height, cfg.objects.min_wall, default_cache_dir(),
                           cfg.objects.min_height)
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
        return f"no valid grasp in {sum(counts.values())} draws", counts, notes
    finally:
        scene.close()
    return None, {}, notes


# ------------------------------------------------------------------------- make, then commit
def make_chunk(chunk: Chunk, cfg: GenerateCfg, scenes: RigCache,
               pipeline: Pipeline) -> list[Configuration]:
    """Every configuration of a chunk, in memory: pure and deterministic given `cfg.seed`."""
    return [make_configuration(cid, cfg.seed, scenes, cfg, pipeline, chunk.object_index)
            for cid in chunk.config_ids]


def commit_chunk(out: Path, chunk_index: int, made: list[Configuration]) -> int:
    """Write a made chunk's images (and recordings), then commit its shard; returns its size."""
    if any(c.recording is not None for c in made):
        (out / "recordings").mkdir(exist_ok=True)
    if any(c.mask is not None for c in made):
        (out / MASKS).mkdir(exist_ok=True)
    for c in made:
        _write_image(out / IMAGES / c.row["image"], c.png)
        if c.mask is not None:
            _write_image(out / MASKS / c.row["image"], c.mask)
        if c.recording is not None:
            cid = c.row["config_id"]
            files.atomic_write_bytes(out / "recordings" / recording_name(cid), c.recording)
    cpath, ppath = shards.shard_paths(out, chunk_index)
    shards.write_shard(ppath, [p for c in made for p in c.presses])
    shards.write_shard(cpath, [c.row for c in made])  # written last: commits the chunk
    return len(made)


def _write_image(path: Path, data: bytes) -> None:
    """Write one image in place (no temporary file and rename): an image only counts once its
    chunk's shard is committed, after this write returned, and a resumed run rewrites the images
    of every uncommitted chunk, so a torn image can never stay in a dataset."""
    with open(path, "wb") as fh:
        fh.write(data)


# ------------------------------------------------------------------------------ worker process
_WORKER: dict = {}


def init_worker(cfg: GenerateCfg, specs: list[ObjectSpec], out: str) -> None:
    """Set up this process for a run's chunks (pool initializer)."""
    # Tasks hold one object each, so a few cached scenes suffice and memory does not grow with
    # the size of the object library.
    _WORKER.update(cfg=cfg, out=Path(out), pipeline=build_pipeline(cfg.effects),
                   scenes=RigCache(specs, cfg, size=4, cache_dir=default_cache_dir()))


def close_worker() -> None:
    """Close this process's scenes (their renderers)."""
    if "scenes" in _WORKER:
        _WORKER.pop("scenes").close()


def run_task(task: list[Chunk]) -> int:
    """Make and commit a task's chunks (consecutive chunks of one object)."""
    return sum(run_chunk(c) for c in task)


def run_chunk(chunk: Chunk) -> int:
    """Make a chunk in this worker and commit it to the (local) output folder."""
    made = make_chunk(chunk, _WORKER["cfg"], _WORKER["scenes"], _WORKER["pipeline"])
    return commit_chunk(_WORKER["out"], chunk.index, made)
