"""`vistac generate --engine ray`: chunks run as Ray tasks, the driver commits what comes back.

Each chunk is one task (1 CPU, retried by Ray up to 3 times if its worker or node dies). A task
makes its chunk in memory (`make_chunk`: pure, deterministic given the seed and the chunk) and
returns the rows, presses and PNG bytes; the driver writes them (`commit_chunk`) into the output
folder exactly as a local worker does. So the nodes need no shared filesystem, the dataset lands
only on the driver's disk, and it is byte-identical to a local run with the same seed: the same
chunks, made by the same code, written by the same function. Resume works as locally: a chunk
counts as done once its shard is committed, and a killed run redoes only the others.

Every node must run the same environment as the driver (same vistac, MuJoCo, NumPy, trimesh);
the driver checks the versions each task reports and stops on a mismatch. User mesh files
(``--objects``) must exist at the same path on every node.
"""

from __future__ import annotations

import hashlib
import json
import socket
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from vistac.dataset import files
from vistac.engine import EngineCfg, RayRunner, ray_session
from vistac.errors import UserError
from vistac_sim.effects import build_pipeline
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.configuration import Configuration
from vistac_sim.generate.run import Chunk, commit_chunk, make_chunk
from vistac_sim.generate.scenes import SceneCache
from vistac_sim.objects.decomposition import default_cache_dir
from vistac_sim.objects.library import ObjectSpec

VERSIONED = ("mujoco", "numpy", "trimesh")  # what decides the bytes of a chunk
TASK_CPUS = 1
TASK_RETRIES = 3


@dataclass
class MadeChunk:
    """What a task sends back: the chunk's configurations and where they were made."""

    index: int
    configurations: list[Configuration]
    node: str
    versions: dict[str, str]


@dataclass(frozen=True)
class ChunkJob:
    """The job of every task of a run: chunk -> `MadeChunk` (picklable, shipped once)."""

    cfg: GenerateCfg
    specs: tuple[ObjectSpec, ...]

    @property
    def key(self) -> str:
        text = json.dumps([self.cfg.to_dict(), [s.__dict__ for s in self.specs]], sort_keys=True)
        return hashlib.sha1(text.encode()).hexdigest()

    def __call__(self, chunk: Chunk) -> MadeChunk:
        scenes, pipeline = _worker_state(self)
        made = make_chunk(chunk, self.cfg, scenes, pipeline)
        return MadeChunk(chunk.index, made, socket.gethostname(), files.versions(*VERSIONED))


_STATE: dict = {}  # per worker process: the scenes (and renderers) of the current run


def _worker_state(job: ChunkJob) -> tuple[SceneCache, object]:
    """The scene cache and effect pipeline of `job`'s run, built once per worker process."""
    if _STATE.get("key") != job.key:
        if "scenes" in _STATE:
            _STATE["scenes"].close()
        _STATE.update(key=job.key, pipeline=build_pipeline(job.cfg.effects),
                      scenes=SceneCache(list(job.specs), job.cfg, size=64,
                                        cache_dir=default_cache_dir()))
    return _STATE["scenes"], _STATE["pipeline"]


def run_chunks_on_ray(cfg: GenerateCfg, specs: list[ObjectSpec], out: Path, todo: list[Chunk],
                      engine: EngineCfg, num_cpus: int | None = None) -> Iterator[int]:
    """Make the `todo` chunks as Ray tasks and commit each into `out`; yields chunk sizes.

    Args:
        num_cpus: CPUs of a local Ray instance (ignored when joining a cluster).

    Raises:
        UserError: Ray missing, the cluster unreachable, or a node with other versions.
    """
    expected = files.versions(*VERSIONED)
    with ray_session(engine, num_cpus=num_cpus) as ray:
        runner = RayRunner(ray, ChunkJob(cfg, tuple(specs)), max_concurrent=engine.max_concurrent,
                           num_cpus=TASK_CPUS, max_retries=TASK_RETRIES)
        for _, made in runner.run(todo):
            if made.versions != expected:
                raise UserError(f"--engine ray: node {made.node} runs {made.versions}, this "
                                f"driver {expected}; install the same environment on every node")
            yield commit_chunk(out, made.index, made.configurations)
