"""Batches of a `SampleSet` through a torch `DataLoader`, in a given order, from a given batch.

`loader` asks the dataset for (epoch, index) keys, so every sample is the same whatever the
order, the batch it starts from (a resumed epoch) or the number of worker processes; `collate`
stacks the samples into the dict a training step takes.

Workers: 0 by default, the samples rendered in the training process when their batch is asked
for, by the dataset's threads (`SampleSet.__getitems__`) while the training step waits. On a
small CPU a rendering process beside torch's own threads oversubscribes the cores (on 2 cores a
training step measured 4 to 8 times slower), while rendering a batch costs a fraction of its
training step (about a quarter of its CPU time for the default recipe); with more cores to
spare, ``workers`` render batches ahead, each worker with one torch thread.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np
import torch
from torch.utils.data import DataLoader, Sampler

from vistac_learn.data.samples import SampleSet, collate


class EpochBatches(Sampler[list[tuple[int, int]]]):
    """The batches of an epoch as lists of (epoch, sample index) keys.

    Args:
        order: Sample indices in the order they are served.
        batch_size: Samples per batch (the last batch may be smaller).
        epoch: The epoch (augmentation and press draws depend on it).
        start: First batch served (a resumed epoch skips those done).
    """

    def __init__(self, order: Sequence[int], batch_size: int, epoch: int = 0, start: int = 0):
        if batch_size < 1:
            raise ValueError(f"batch_size must be at least 1, not {batch_size}")
        self.order = np.asarray(order, dtype=np.int64)
        self.batch_size, self.epoch, self.start = batch_size, int(epoch), int(start)

    @property
    def total(self) -> int:
        """Batches in the whole epoch, those skipped by `start` included."""
        return (len(self.order) + self.batch_size - 1) // self.batch_size

    def __len__(self) -> int:
        return max(self.total - self.start, 0)

    def __iter__(self) -> Iterator[list[tuple[int, int]]]:
        for b in range(self.start, self.total):
            part = self.order[b * self.batch_size:(b + 1) * self.batch_size]
            yield [(self.epoch, int(i)) for i in part]


def _one_thread(_worker: int) -> None:
    torch.set_num_threads(1)


def loader(ds: SampleSet, batch_size: int, epoch: int = 0, order: Sequence[int] | None = None,
           start: int = 0, workers: int = 0) -> DataLoader:
    """A `DataLoader` over `ds`: batches of `batch_size` samples in `order` (default: index
    order) from batch `start` on, collated by `collate`.

    Args:
        ds: The samples.
        batch_size: Samples per batch.
        epoch: Epoch of the samples' draws.
        order: Sample indices in serving order (a permutation for training).
        start: First batch (a resumed epoch).
        workers: Worker processes rendering batches ahead (0: in this process, when asked).
    """
    order = np.arange(len(ds)) if order is None else order
    return DataLoader(ds, batch_sampler=EpochBatches(order, batch_size, epoch, start),
                      collate_fn=collate, num_workers=workers,
                      worker_init_fn=_one_thread if workers else None)
