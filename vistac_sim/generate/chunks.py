"""Chunk work of `vistac generate`: make a chunk in memory, commit it to the dataset folder.

`ChunkWork` is the job a runner of `vistac.engine` runs: a picklable callable, task of chunks
-> configurations committed, that builds its rig cache on its first call in each process and
keeps it for the next (`close` releases it). Making a chunk needs the simulator (meshes, MuJoCo,
a renderer), which this module imports only when it first makes one: the driver can hand the
job to forked workers without importing the simulator itself, and the workers have it from the
fork server's preload (`vistac_sim.generate.WORKER_MODULES`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from vistac.dataset import files
from vistac.dataset.recordings import recording_name
from vistac.dataset.schema import IMAGES, MASKS
from vistac_sim.effects import build_pipeline
from vistac_sim.generate import shards
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.plan import Chunk
from vistac_sim.objects.specs import ObjectSpec

if TYPE_CHECKING:  # the simulator: imported where a chunk is made
    from vistac_sim.effects.registry import Pipeline
    from vistac_sim.generate.configuration import Configuration
    from vistac_sim.generate.rigs import RigCache


def make_chunk(chunk: Chunk, cfg: GenerateCfg, scenes: RigCache,
               pipeline: Pipeline) -> list[Configuration]:
    """Every configuration of a chunk, in memory: pure and deterministic given `cfg.seed`."""
    from vistac_sim.generate.configuration import make_configuration

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
    try:
        with open(path, "wb") as fh:
            fh.write(data)
    except OSError as exc:  # a full disk: one line naming the file
        raise files.write_error(path, exc) from None


class ChunkMaker:
    """Makes the chunks of one run: its config, objects and the rig cache of this process.

    Picklable: the rig cache (renderers) is not pickled but built on the first chunk made in
    each process, and kept for the next ones (`close` releases it).

    Args:
        cfg: The run's config.
        specs: The run's (screened) objects.
        cache_size: Object scenes kept at once (a local worker's tasks hold one object each,
            so a few suffice; a Ray worker gets chunks of any object).
    """

    def __init__(self, cfg: GenerateCfg, specs: Sequence[ObjectSpec], cache_size: int = 4):
        self.cfg, self.specs, self.cache_size = cfg, tuple(specs), cache_size
        self._scenes: RigCache | None = None
        self._pipeline: Pipeline | None = None

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_scenes": None, "_pipeline": None}

    def make(self, chunk: Chunk) -> list[Configuration]:
        """The configurations of `chunk`, in memory (`make_chunk`)."""
        if self._scenes is None:
            from vistac_sim.generate.rigs import RigCache
            from vistac_sim.objects.decomposition import default_cache_dir

            self._pipeline = build_pipeline(self.cfg.effects)
            self._scenes = RigCache(list(self.specs), self.cfg, size=self.cache_size,
                                      cache_dir=default_cache_dir())
        return make_chunk(chunk, self.cfg, self._scenes, self._pipeline)

    def close(self) -> None:
        """Close this process's scenes (their renderers)."""
        if self._scenes is not None:
            self._scenes.close()
            self._scenes = self._pipeline = None


class ChunkWork:
    """The job of a local run: a task (consecutive chunks of one object) -> configurations
    made and committed into `out`.

    Args:
        cfg: The run's config.
        specs: The run's (screened) objects.
        out: The dataset folder.
    """

    def __init__(self, cfg: GenerateCfg, specs: Sequence[ObjectSpec], out: Path):
        self.maker, self.out = ChunkMaker(cfg, specs), Path(out)

    def __call__(self, task: Sequence[Chunk]) -> int:
        return sum(self.run_chunk(c) for c in task)

    def run_chunk(self, chunk: Chunk) -> int:
        """Make one chunk and commit it; returns its size."""
        return commit_chunk(self.out, chunk.index, self.maker.make(chunk))

    def close(self) -> None:
        self.maker.close()
