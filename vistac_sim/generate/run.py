"""`vistac generate`: many configurations, in worker processes, into a dataset directory.

This module is the driver: it plans and bookkeeps, and imports nothing that builds a scene (no
meshes, MuJoCo or renderer; those live in `vistac_sim.generate.worker`, imported by the workers).
Objects are screened in the workers, then the work is cut into chunks of configurations that
share one object (so a worker builds each object's scene and renderer once). Workers take tasks
of consecutive chunks of the same object (`plan_tasks`), so each object's scene is built by about
one worker, not by all. A chunk is a pure function of (seed, config ids, config), so the dataset
is identical whatever the number of workers, and a resumed run redoes exactly the chunks that had
not committed their shard.
"""

from __future__ import annotations

import multiprocessing as mp
import shutil
import time
from collections.abc import Callable, Generator
from contextlib import closing
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np
from tqdm import tqdm

from vistac.dataset import MANIFEST, files
from vistac.dataset.schema import IMAGES, MASK_VALUES, MASKS, PARTIAL
from vistac.engine import EngineCfg, preflight
from vistac.folder_lock import hold
from vistac_sim.effects import build_pipeline
from vistac_sim.generate import shards
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.objects_report import screen_objects
from vistac_sim.generate.processes import (
    in_new_worker,
    in_worker,
    stop_fork_server,
    worker_pool,
)
from vistac_sim.generate.verify import check_complete
from vistac_sim.objects.specs import ObjectSpec, object_index, procedural_library

VERSIONED = ("mujoco", "numpy", "trimesh")  # what decides the bytes of a dataset


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
    if cfg.objects.paths:  # meshes are checked and decomposed here, once (cached for workers)
        from vistac_sim.objects.decomposition import default_cache_dir
        from vistac_sim.objects.library import mesh_library

        return mesh_library(cfg.objects, seed, cfg.hand.height, default_cache_dir())
    return procedural_library(cfg.objects, seed), []


def _screen(specs: list[ObjectSpec], cfg: GenerateCfg, workers: int, progress: bool):
    """Screen the objects in worker processes (this process imports no simulator); returns
    `screen_objects`' result and the versions of what the workers run (for the manifest)."""
    jobs = [(k, spec, cfg) for k, spec in enumerate(specs)]
    with worker_pool(min(workers, len(specs))) as pool:
        outcomes = (pool.imap if pool else map)(in_worker("screen_object"), jobs)
        screened = screen_objects(specs, cfg, outcomes, progress)
        versions = pool.apply(files.versions, VERSIONED) if pool else files.versions(*VERSIONED)
    return (*screened, versions)


def _chunk_runner(cfg: GenerateCfg, specs: list[ObjectSpec], out: Path, todo: list[Chunk],
                  workers: int, engine: EngineCfg) -> tuple[Generator[int], Callable[..., dict]]:
    """Where the `todo` chunks run (Ray tasks, this process, or a pool of worker processes) and
    the final merge after them (`shards.finalize`).

    Returns a generator of the number of configurations committed, as chunks (or a pool's
    tasks) commit (its workers stop when it is exhausted or closed), and the merge: after a
    pool, it runs in a new worker forked from the fork server, which imported pyarrow and pandas
    already (this process has not) and ends with the merge; otherwise in this process.
    """
    if engine.engine == "ray":
        from vistac_sim.generate.on_ray import run_chunks_on_ray

        return run_chunks_on_ray(cfg, specs, out, todo, engine, num_cpus=workers), shards.finalize
    if workers == 1 or len(todo) <= 1:
        return _run_here(cfg, specs, out, todo), shards.finalize
    return _run_in_pool(cfg, specs, out, todo, workers), partial(in_new_worker, shards.finalize)


def _run_here(cfg: GenerateCfg, specs: list[ObjectSpec], out: Path,
              todo: list[Chunk]) -> Generator[int]:
    from vistac_sim.generate import worker

    worker.init_worker(cfg, specs, str(out))
    try:
        yield from (worker.run_chunk(c) for c in todo)
    finally:
        worker.close_worker()


def _run_in_pool(cfg: GenerateCfg, specs: list[ObjectSpec], out: Path, todo: list[Chunk],
                 workers: int) -> Generator[int]:
    with worker_pool(workers, cfg, specs, str(out)) as pool:
        yield from pool.imap_unordered(in_worker("run_task"), plan_tasks(todo, workers))


def drop_unstarted_run(out: Path, existed: bool) -> None:
    """After a failed run: remove what it made if it committed no shard (nothing to resume)."""
    if (out / MANIFEST).exists() or not (out / PARTIAL).is_dir() or shards.finished_chunks(out):
        return
    for name in (PARTIAL, IMAGES, MASKS, "recordings"):
        shutil.rmtree(out / name, ignore_errors=True)
    if not existed and out.is_dir() and not any(out.iterdir()):
        out.rmdir()


# --------------------------------------------------------------------------------- the run
def generate(cfg: GenerateCfg, out: str | Path, workers: int = 0, resume: bool = False,
             progress: bool = True, engine: EngineCfg | None = None) -> dict:
    """Generate (or resume) a dataset of `cfg.n` configurations in `out`; returns the manifest.

    From a script, call it under ``if __name__ == "__main__":``: the workers' fork server
    imports the script's main module, as every `multiprocessing` start method but "fork" does.

    Args:
        cfg: the full generation config (its seed included).
        out: dataset folder to create (or to resume).
        workers: worker processes; 0 means all cores, 1 runs in this process (with the Ray
            engine: the CPUs of a local Ray instance).
        resume: continue an interrupted run made with the same settings (its committed
            files checked first); on a complete dataset made with them, check it and return
            its manifest with ``"already_complete": true`` (not written), doing nothing else.
        progress: show a progress bar with rate and ETA.
        engine: local processes (default) or Ray tasks (`vistac_sim.generate.on_ray`).

    Raises:
        UserError: bad options, bad meshes or objects without a valid grasp (strict), no
            usable object, an `out` that cannot be used or that another process holds, or
            (resume) damaged state in it.
    """
    out = Path(out)
    try:
        with hold(out, "generate"):
            existed = out.exists()
            try:
                return _generate(cfg, out, workers, resume, progress, engine or EngineCfg())
            except BaseException:  # inside the lock: never another process's run
                drop_unstarted_run(out, existed)
                raise
    finally:
        stop_fork_server()


def _generate(cfg: GenerateCfg, out: Path, workers: int, resume: bool, progress: bool,
              engine: EngineCfg) -> dict:
    t0 = time.perf_counter()
    preflight(engine)
    if resume and (out / MANIFEST).exists():  # finished: checked, then nothing to do
        return {**check_complete(out, cfg.to_dict()), "already_complete": True}
    workers = min(workers or mp.cpu_count(), mp.cpu_count())
    specs, skipped = object_specs(cfg, cfg.seed)
    specs, unusable, repairs, versions = _screen(specs, cfg, workers, progress)
    run_state = {"config": cfg.to_dict(), "objects": [s.__dict__ for s in specs]}
    done = shards.start_run(out, run_state, resume)
    chunks = plan_chunks(cfg.n, cfg.seed, len(specs), cfg.chunk_size)
    todo = [c for c in chunks if c.index not in done]
    workers = max(1, min(workers, len(todo)))  # no idle processes
    bar = tqdm(total=cfg.n, initial=sum(len(c.config_ids) for c in chunks if c.index in done),
               unit="cfg", desc="generate", disable=not progress, smoothing=0.1)
    committed, merge = _chunk_runner(cfg, specs, out, todo, workers, engine)
    with closing(committed):  # its workers stop here even if the loop is interrupted
        for count in committed:
            bar.update(count)
    bar.close()
    manifest = {
        "generator": "vistac generate",
        "config": cfg.to_dict(),
        "seed": cfg.seed,
        "versions": versions,
        "effects": build_pipeline(cfg.effects).describe(),
        "objects": [s.__dict__ for s in specs],
        "skipped_meshes": skipped,
        "skipped_objects": unusable,
        "mesh_repairs": repairs,
        "render": {"image_size": cfg.render.image_size, "view_extent_m": cfg.render.view_extent,
                   "px_per_m": cfg.render.image_size / cfg.render.view_extent,
                   "camera_xy": [0.0, 0.0]},
        "masks": {"folder": MASKS, "values": MASK_VALUES} if cfg.render.masks else None,
        "workers": workers,
        "engine": engine.engine,
        "resumed": bool(resume),
        "wall_time_s": round(time.perf_counter() - t0, 3),
    }
    return merge(out, len(chunks), cfg.n, manifest, cfg.split.by, cfg.split.fractions, cfg.seed)
