"""The plan of a `vistac generate` run: chunks of configurations, tasks of chunks, and which
packages decide a dataset's bytes.

Pure: it imports nothing of the other generate modules and builds no scene, so the driver, the
workers, Ray tasks and the tests can all use it. A chunk is a pure function of (seed, config
ids, config), so the dataset is identical whatever the number of workers, and a resumed run
redoes exactly the chunks that had not committed their shard.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vistac_sim.objects.specs import object_index

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
