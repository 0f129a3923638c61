"""`vistac generate`: many configurations, in worker processes, into a dataset directory.

This module is the driver: it plans (`plan`) and bookkeeps (`shards`), and imports nothing that
builds a scene (no meshes, MuJoCo or renderer: those live in `chunks` and `screening`, which the
workers import, or this process when it runs with one worker). Objects are screened in the
workers, then the work is cut into chunks of configurations that share one object (so a worker
builds each object's scene and renderer once), grouped into tasks of consecutive chunks of the
same object. Where they run is a runner of `vistac.engine`: this process (`LocalRunner`),
workers forked from a fork server (`PoolRunner`), or Ray tasks (`on_ray`).
"""

from __future__ import annotations

import multiprocessing as mp
import shutil
import time
from collections.abc import Callable, Iterator
from contextlib import closing, nullcontext
from pathlib import Path

from vistac.dataset import MANIFEST, files
from vistac.dataset.schema import IMAGES, MASK_VALUES, MASKS, PARTIAL
from vistac.engine import EngineCfg, ForkServer, LocalRunner, PoolRunner, preflight
from vistac.folder_lock import hold
from vistac.progress import bar as progress_bar
from vistac_sim.effects import build_pipeline
from vistac_sim.generate import WORKER_MODULES, shards
from vistac_sim.generate.chunks import ChunkWork
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.objects_report import screen_objects
from vistac_sim.generate.plan import VERSIONED, Chunk, plan_chunks, plan_tasks
from vistac_sim.generate.screening import screen_object
from vistac_sim.generate.verify import check_complete
from vistac_sim.objects.specs import ObjectSpec, procedural_library


def object_specs(cfg: GenerateCfg, seed: int) -> tuple[list[ObjectSpec], list[dict]]:
    """The object library of a run (procedural, or user meshes) and the skipped meshes."""
    if cfg.objects.paths:  # meshes are checked and decomposed here, once (cached for workers)
        from vistac_sim.objects.decomposition import default_cache_dir
        from vistac_sim.objects.library import mesh_library

        return mesh_library(cfg.objects, seed, cfg.hand.height, default_cache_dir())
    return procedural_library(cfg.objects, seed), []


def _screen(specs: list[ObjectSpec], cfg: GenerateCfg, workers: int, progress: bool,
            server: ForkServer | None):
    """Screen the objects in worker processes (this process imports no simulator); returns
    `screen_objects`' result and the versions of what the workers run (for the manifest)."""
    jobs = [(k, spec, cfg) for k, spec in enumerate(specs)]
    if server is None or workers == 1:
        screened = screen_objects(specs, cfg, map(screen_object, jobs), progress)
        return (*screened, files.versions(*VERSIONED))
    runner = PoolRunner(server, screen_object, min(workers, len(specs)))
    with closing(runner.ordered(jobs)) as outcomes:
        screened = screen_objects(specs, cfg, outcomes, progress)
    return (*screened, server.call(files.versions, *VERSIONED))


def _chunk_runner(cfg: GenerateCfg, specs: list[ObjectSpec], out: Path, todo: list[Chunk],
                  workers: int, engine: EngineCfg,
                  server: ForkServer | None) -> tuple[Iterator[int], Callable[..., dict]]:
    """Where the `todo` chunks run (Ray tasks, this process, or workers forked from `server`)
    and the final merge after them (`shards.finalize`).

    Returns a generator of the number of configurations committed, as chunks (or tasks of
    chunks) commit (its workers stop when it is exhausted or closed), and the merge: after
    forked workers, it runs in one more worker (the server imported pyarrow and pandas already,
    this process has not); otherwise in this process.
    """
    if engine.engine == "ray":
        from vistac_sim.generate.on_ray import run_chunks_on_ray

        return run_chunks_on_ray(cfg, specs, out, todo, engine, num_cpus=workers), shards.finalize
    work = ChunkWork(cfg, specs, out)
    if server is None or workers == 1 or len(todo) <= 1:
        return _counts(LocalRunner(work).run([c] for c in todo)), shards.finalize
    runs = PoolRunner(server, work, workers).run(plan_tasks(todo, workers))
    return _counts(runs), lambda *args: server.call(shards.finalize, *args)


def _counts(runs: Iterator[tuple[int, int]]) -> Iterator[int]:
    """The configurations committed, from a runner's (position, count); closing this closes
    the runner's batch (its workers stop)."""
    with closing(runs):
        for _, count in runs:
            yield count


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
             progress: bool = True, engine: EngineCfg | None = None,
             server: ForkServer | None = None) -> dict:
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
        server: the fork server of the workers, started already (it imports `WORKER_MODULES`
            while this process goes on); default: one of the run's own, unless `workers` is 1.
            Whoever starts a server stops it.

    Raises:
        UserError: bad options, bad meshes or objects without a valid grasp (strict), no
            usable object, an `out` that cannot be used or that another process holds, or
            (resume) damaged state in it.
    """
    out = Path(out)
    engine = engine or EngineCfg()
    own = server is None and workers != 1  # Ray runs the chunks, the server screens
    with ForkServer(WORKER_MODULES) if own else nullcontext(server) as forks:
        with hold(out, "generate"):
            existed = out.exists()
            try:
                return _generate(cfg, out, workers, resume, progress, engine, forks)
            except BaseException:  # inside the lock: never another process's run
                drop_unstarted_run(out, existed)
                raise


def _generate(cfg: GenerateCfg, out: Path, workers: int, resume: bool, progress: bool,
              engine: EngineCfg, server: ForkServer | None) -> dict:
    t0 = time.perf_counter()
    preflight(engine)
    if resume and (out / MANIFEST).exists():  # finished: checked, then nothing to do
        return {**check_complete(out, cfg.to_dict()), "already_complete": True}
    workers = min(workers or mp.cpu_count(), mp.cpu_count())
    specs, skipped = object_specs(cfg, cfg.seed)
    specs, unusable, repairs, versions = _screen(specs, cfg, workers, progress, server)
    run_state = {"config": cfg.to_dict(), "objects": [s.__dict__ for s in specs]}
    done = shards.start_run(out, run_state, resume)
    chunks = plan_chunks(cfg.n, cfg.seed, len(specs), cfg.chunk_size)
    todo = [c for c in chunks if c.index not in done]
    workers = max(1, min(workers, len(todo)))  # no idle processes
    bar = progress_bar(total=cfg.n, initial=sum(len(c.config_ids) for c in chunks
                                                if c.index in done),
                       unit="cfg", desc="generate", enabled=progress, lines="each", smoothing=0.1)
    committed, merge = _chunk_runner(cfg, specs, out, todo, workers, engine, server)
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
