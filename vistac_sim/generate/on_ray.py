"""`vistac generate --engine ray`: chunks run as Ray tasks.

Each chunk is one task (1 CPU, retried by Ray up to 3 times if its worker or node dies). A task
makes its chunk in memory (`make_chunk`: pure, deterministic given the seed and the chunk).
Who writes it (``--ray-writes``):

- ``driver`` (default): the task returns the rows, presses and PNG bytes and the driver writes
  them (`commit_chunk`) into the output folder exactly as a local worker does. The nodes need no
  shared filesystem and the dataset lands only on the driver's disk; but one process receives
  and writes everything, which bounds a large cluster (``benchmarks/ray_overhead.py``).
- ``workers``: the task commits its chunk itself (`commit_chunk`, as a local worker does) into
  ``--out``, which must be the same folder on every node (a shared filesystem); the driver only
  counts. Before a worker writes, it checks that it sees the run's folder (a marker file the
  driver wrote) and the driver's package versions.

Either way the dataset is byte-identical to a local run with the same seed: the same chunks,
made by the same code, written by the same function. Resume works as locally: a chunk counts as
done once its shard is committed, and a killed run redoes only the others.

Every node must run the same environment as the driver (same vistac, MuJoCo, NumPy, trimesh);
the versions each task reports are checked and a mismatch stops the run. User mesh files
(``--objects``) must exist at the same path on every node.
"""

from __future__ import annotations

import secrets
import socket
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from vistac.dataset import files
from vistac.dataset.schema import PARTIAL
from vistac.engine import EngineCfg, RayRunner, ray_session
from vistac.errors import UserError
from vistac_sim.generate.chunks import ChunkMaker, commit_chunk
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.plan import VERSIONED, Chunk
from vistac_sim.objects.specs import ObjectSpec

if TYPE_CHECKING:
    from vistac_sim.generate.configuration import Configuration

TASK_CPUS = 1
TASK_RETRIES = 3
SCENES_PER_WORKER = 64  # a Ray worker gets chunks of any object

@dataclass
class MadeChunk:
    """What a task sends back: the chunk's configurations (none once the worker committed
    them itself) and where they were made."""

    index: int
    configurations: list[Configuration]
    node: str
    versions: dict[str, str]
    committed: int | None = None  # configurations the worker wrote itself


@dataclass(frozen=True)
class ChunkJob:
    """The job of every task of a run: chunk -> `MadeChunk` (picklable, shipped once to each
    Ray worker process, which keeps it and so its scenes from one chunk to the next)."""

    cfg: GenerateCfg
    specs: tuple[ObjectSpec, ...]
    out: str | None = None  # set: the worker commits into this shared folder itself
    marker: str = ""  # a file the driver wrote under out/.partial: proof of the same folder
    versions: tuple[tuple[str, str], ...] = ()  # the driver's (checked before a worker writes)
    maker: ChunkMaker = field(init=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "maker", ChunkMaker(self.cfg, self.specs, SCENES_PER_WORKER))

    def __call__(self, chunk: Chunk) -> MadeChunk:
        # Made first: making imports MuJoCo the simulator's way (`vistac_sim.mj`, which picks
        # the headless GL backend), where `files.versions` would import it plainly.
        made = self.maker.make(chunk)
        node, versions = socket.gethostname(), files.versions(*VERSIONED)
        if self.out is not None:
            self.check_writable(node, versions)
        if self.out is None:
            return MadeChunk(chunk.index, made, node, versions)
        return MadeChunk(chunk.index, [], node, versions, commit_chunk(Path(self.out),
                                                                       chunk.index, made))

    def check_writable(self, node: str, versions: dict[str, str]) -> None:
        """Before a worker writes: same versions as the driver, and the driver's --out folder.

        Raises:
            UserError: naming the node and what differs.
        """
        if versions != dict(self.versions):
            raise _version_error(node, versions, dict(self.versions))
        if not (Path(self.out) / PARTIAL / self.marker).is_file():
            raise UserError(f"--ray-writes workers: node {node} does not see the driver's "
                            f"--out {self.out}; it must be a folder every node shares (NFS, "
                            "say), or use --ray-writes driver")


def _version_error(node: str, theirs: dict[str, str], mine: dict[str, str]) -> UserError:
    return UserError(f"--engine ray: node {node} runs {theirs}, this driver {mine}; install the "
                     "same environment on every node")


def run_chunks_on_ray(cfg: GenerateCfg, specs: list[ObjectSpec], out: Path, todo: list[Chunk],
                      engine: EngineCfg, num_cpus: int | None = None) -> Iterator[int]:
    """Make the `todo` chunks as Ray tasks and commit each into `out`; yields chunk sizes.

    Args:
        num_cpus: CPUs of a local Ray instance (ignored when joining a cluster).

    Raises:
        UserError: Ray missing, the cluster unreachable, or a node with other versions.
    """
    expected = files.versions(*VERSIONED)
    job = ChunkJob(cfg, tuple(specs))
    if engine.ray_writes == "workers":
        marker = f"shared-{secrets.token_hex(8)}"
        (out / PARTIAL / marker).touch()
        job = ChunkJob(cfg, tuple(specs), str(out.absolute()), marker,
                       tuple(sorted(expected.items())))
    with ray_session(engine, num_cpus=num_cpus) as ray:
        runner = RayRunner(ray, job, max_concurrent=engine.max_concurrent, num_cpus=TASK_CPUS,
                           max_retries=TASK_RETRIES)
        for _, made in runner.run(todo):
            if made.versions != expected:
                raise _version_error(made.node, made.versions, expected)
            if made.committed is not None:
                yield made.committed
            else:
                yield commit_chunk(out, made.index, made.configurations)
