"""`vistac generate`: many configurations, in worker processes, into a dataset directory.

Work is cut into chunks of configurations that share one object (so a worker builds each object's
scene and renderer once). Workers take tasks of consecutive chunks of the same object
(`plan_tasks`), so each object's scene is built by about one worker, not by all. A chunk is a
pure function of (seed, config ids, config), so the dataset is identical whatever the number of
workers, and a resumed run redoes exactly the chunks that had not committed their shard.
"""

from __future__ import annotations

import multiprocessing as mp
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from vistac.dataset import files
from vistac.dataset.schema import IMAGES
from vistac.engine import EngineCfg, preflight
from vistac_sim.effects import build_pipeline
from vistac_sim.effects.registry import Pipeline
from vistac_sim.generate import shards
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.configuration import Configuration, make_configuration, object_index
from vistac_sim.generate.objects_report import screen_objects
from vistac_sim.generate.scenes import SceneCache
from vistac_sim.objects.decomposition import default_cache_dir
from vistac_sim.objects.library import ObjectSpec, mesh_library, procedural_library
from vistac_sim.recording.layout import recording_name


@dataclass(frozen=True)
class Chunk:
    """One unit of work: configuration ids that all use object `object_index`."""

    index: int
    object_index: int
    config_ids: tuple[int, ...]


def plan_chunks(n: int, seed: int, n_objects: int, chunk_size: int) -> list[Chunk]:
    """Group configuration ids by object, then cut each group into chunks of `chunk_size`."""
    objs = np.array([object_index(seed, i, n_objects) for i in range(n)], dtype=int)
    chunks = []
    for k in range(n_objects):
        ids = np.flatnonzero(objs == k)
        for start in range(0, len(ids), chunk_size):
            part = tuple(int(i) for i in ids[start:start + chunk_size])
            chunks.append(Chunk(len(chunks), k, part))
    return chunks


def plan_tasks(todo: list[Chunk], workers: int, per_worker: int = 8) -> list[list[Chunk]]:
    """Group consecutive chunks of one object into tasks of at most ~1/(workers * per_worker)
    of the work, so that a worker builds an object's scene once and the last tasks stay short."""
    limit = max(1, -(-sum(len(c.config_ids) for c in todo) // (workers * per_worker)))
    tasks: list[list[Chunk]] = []
    size = 0
    for c in todo:
        if tasks and tasks[-1][-1].object_index == c.object_index and size < limit:
            tasks[-1].append(c)
            size += len(c.config_ids)
        else:
            tasks.append([c])
            size = len(c.config_ids)
    return tasks


def object_specs(cfg: GenerateCfg, seed: int) -> tuple[list[ObjectSpec], list[dict]]:
    """The object library of a run (procedural, or user meshes) and the skipped meshes."""
    if cfg.objects.paths:
        return mesh_library(cfg.objects, seed, cfg.hand.height, default_cache_dir())
    return procedural_library(cfg.objects, seed), []


# ------------------------------------------------------------------------- make, then commit
def make_chunk(chunk: Chunk, cfg: GenerateCfg, scenes: SceneCache,
               pipeline: Pipeline) -> list[Configuration]:
    """Every configuration of a chunk, in memory: pure and deterministic given `cfg.seed`."""
    return [make_configuration(cid, cfg.seed, scenes, cfg, pipeline) for cid in chunk.config_ids]


def commit_chunk(out: Path, chunk_index: int, made: list[Configuration]) -> int:
    """Write a made chunk's images (and recordings), then commit its shard; returns its size."""
    if any(c.recording is not None for c in made):
        (out / "recordings").mkdir(exist_ok=True)
    for c in made:
        _write_image(out / IMAGES / c.row["image"], c.png)
        if c.recording is not None:
            cid = c.row["config_id"]
            files.atomic_write_bytes(out / "recordings" / recording_name(cid), c.recording)
    cpath, ppath = shards.shard_paths(out, chunk_index)
    files.write_table(ppath, [p for c in made for p in c.presses])
    files.write_table(cpath, [c.row for c in made])  # written last: commits the chunk
    return len(made)


# ------------------------------------------------------------------------------ worker process
_WORKER: dict = {}


def _init_worker(cfg: GenerateCfg, specs: list[ObjectSpec], out: str) -> None:
    # Tasks hold one object each, so a few cached scenes suffice and memory does not grow with
    # the size of the object library.
    _WORKER.update(cfg=cfg, out=Path(out), pipeline=build_pipeline(cfg.effects),
                   scenes=SceneCache(specs, cfg, size=4, cache_dir=default_cache_dir()))


def _write_image(path: Path, data: bytes) -> None:
    """Write one image in place (no temporary file and rename): an image only counts once its
    chunk's shard is committed, after this write returned, and a resumed run rewrites the images
    of every uncommitted chunk, so a torn image can never stay in a dataset."""
    with open(path, "wb") as fh:
        fh.write(data)


def _run_task(task: list[Chunk]) -> int:
    return sum(map(_run_chunk, task))


def _run_chunk(chunk: Chunk) -> int:
    """Make a chunk in this worker and commit it to the (local) output folder."""
    made = make_chunk(chunk, _WORKER["cfg"], _WORKER["scenes"], _WORKER["pipeline"])
    return commit_chunk(_WORKER["out"], chunk.index, made)


def worker_context() -> mp.context.BaseContext:
    """Processes for workers: forked from a fork server that imported the simulator once.

    The server starts fresh (no GL context, no threads of this process) and imports this module
    and what it needs; each worker is a fork of it, so workers do not import MuJoCo, trimesh,
    pandas and SciPy again (about a second of CPU each), and each makes its own GL context.
    """
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload([__name__])
    return ctx


def _run_local(cfg: GenerateCfg, specs: list[ObjectSpec], out: Path, todo: list[Chunk],
               workers: int) -> Iterator[int]:
    """Make and commit the `todo` chunks in this process or a pool; yields chunk sizes."""
    if workers == 1 or len(todo) <= 1:
        _init_worker(cfg, specs, str(out))
        yield from map(_run_chunk, todo)
        _WORKER["scenes"].close()
    else:
        ctx = worker_context()
        with ctx.Pool(workers, initializer=_init_worker, initargs=(cfg, specs, str(out))) as pool:
            yield from pool.imap_unordered(_run_task, plan_tasks(todo, workers))


# --------------------------------------------------------------------------------- the run
def generate(cfg: GenerateCfg, out: str | Path, workers: int = 0, resume: bool = False,
             progress: bool = True, engine: EngineCfg | None = None) -> dict:
    """Generate (or resume) a dataset of `cfg.n` configurations in `out`; returns the manifest.

    Args:
        cfg: the full generation config (its seed included).
        out: dataset folder to create (or to resume).
        workers: worker processes; 0 means all cores, 1 runs in this process (with the Ray
            engine: the CPUs of a local Ray instance).
        resume: continue an interrupted run made with the same settings.
        progress: show a progress bar with rate and ETA.
        engine: local processes (default) or Ray tasks (`vistac_sim.generate.on_ray`).

    Raises:
        UserError: bad options, bad meshes or objects without a valid grasp (strict), no
            usable object, or an `out` that cannot be used.
    """
    t0 = time.perf_counter()
    out = Path(out)
    engine = engine or EngineCfg()
    preflight(engine)
    workers = min(workers or mp.cpu_count(), mp.cpu_count())
    specs, skipped = object_specs(cfg, cfg.seed)
    specs, unusable, repairs = screen_objects(specs, cfg, progress)
    run_state = {"config": cfg.to_dict(), "objects": [s.__dict__ for s in specs]}
    done = shards.start_run(out, run_state, resume)
    chunks = plan_chunks(cfg.n, cfg.seed, len(specs), cfg.chunk_size)
    todo = [c for c in chunks if c.index not in done]
    workers = max(1, min(workers, len(todo)))  # no idle processes
    bar = tqdm(total=cfg.n, initial=sum(len(c.config_ids) for c in chunks if c.index in done),
               unit="cfg", desc="generate", disable=not progress, smoothing=0.1)
    if engine.engine == "ray":
        from vistac_sim.generate.on_ray import run_chunks_on_ray

        committed = run_chunks_on_ray(cfg, specs, out, todo, engine, num_cpus=workers)
    else:
        committed = _run_local(cfg, specs, out, todo, workers)
    for count in committed:
        bar.update(count)
    bar.close()
    manifest = {
        "generator": "vistac generate",
        "config": cfg.to_dict(),
        "seed": cfg.seed,
        "versions": files.versions("mujoco", "numpy", "trimesh"),
        "effects": build_pipeline(cfg.effects).describe(),
        "objects": [s.__dict__ for s in specs],
        "skipped_meshes": skipped,
        "skipped_objects": unusable,
        "mesh_repairs": repairs,
        "render": {"image_size": cfg.render.image_size, "view_extent_m": cfg.render.view_extent,
                   "px_per_m": cfg.render.image_size / cfg.render.view_extent,
                   "camera_xy": [0.0, 0.0]},
        "workers": workers,
        "engine": engine.engine,
        "resumed": bool(resume),
        "wall_time_s": round(time.perf_counter() - t0, 3),
    }
    return shards.finalize(out, len(chunks), manifest, cfg.split.by, cfg.split.fractions,
                            cfg.seed)
