"""`vistac.engine`: the engine options, and `RayRunner` (order, concurrency, retries, errors)."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import pytest

from vistac.config import ConfigError
from vistac.engine import ONLY_ASSIGNED_GPUS, EngineCfg, RayRunner
from vistac.errors import UserError


@pytest.fixture(scope="module")
def ray(ray_local):
    """The module's Ray; the jobs below (defined in this test module, which Ray's workers
    cannot import) are shipped by value."""
    ray_local.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    return ray_local


def square(x: int) -> int:
    return x * x


def env_of(name: str) -> str | None:
    return os.environ.get(name)


class Rendezvous:
    """Marks itself running in `folder`, waits until `peers` tasks run at once (at most `wait`
    seconds) and returns the most it saw running. The runner's cap is an upper bound that no
    timing can break; the wait makes tasks that do run together see each other."""

    def __init__(self, folder: Path, peers: int, wait: float):
        self.folder, self.peers, self.wait = folder, peers, wait

    def __call__(self, x: int) -> int:
        me = self.folder / f"running_{x}"
        me.touch()
        try:
            deadline, seen = time.monotonic() + self.wait, 0
            while seen < self.peers and time.monotonic() < deadline:
                seen = max(seen, len(list(self.folder.glob("running_*"))))
                time.sleep(0.005)
            return seen
        finally:
            me.unlink()


class CrashOnce:
    """Kills its worker process the first time it sees an item (a marker file remembers)."""

    def __init__(self, folder: Path):
        self.folder = folder

    def __call__(self, x: int) -> int:
        marker = self.folder / f"seen_{x}"
        if not marker.exists():
            marker.touch()
            os._exit(1)
        return x + 100


class Picky:
    def __call__(self, x: int) -> int:
        if x == 1:
            raise ValueError("diverged")
        if x == 2:
            raise UserError("--lr: must be > 0, got -1")
        if x == 3:
            raise KeyError("a bug")
        return x


def test_engine_cfg_defaults_and_checks(monkeypatch):
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    assert EngineCfg().engine == "local" and EngineCfg(engine="ray").address is None
    monkeypatch.setenv("RAY_ADDRESS", "head:6379")
    assert EngineCfg(engine="ray").address == "head:6379"
    assert EngineCfg(engine="ray", ray_address="other:6379").address == "other:6379"
    with pytest.raises(ConfigError, match="ray_address: needs --engine ray"):
        EngineCfg(ray_address="head:6379")
    with pytest.raises(ConfigError, match="max_concurrent: must be >= 1"):
        EngineCfg(engine="ray", max_concurrent=0)


def test_results_in_item_order_and_as_they_finish(ray):
    runner = RayRunner(ray, square)
    assert runner.concurrency == 2  # the instance's CPUs
    assert runner.map(range(7)) == [x * x for x in range(7)]
    assert sorted(runner.run([3, 1, 2])) == [(0, 9), (1, 1), (2, 4)]
    assert runner([]) == []


def test_concurrency_follows_the_cpus_and_the_cap(ray, tmp_path):
    for name in ("pair", "four", "capped"):
        (tmp_path / name).mkdir()
    # two tasks on the instance's 2 CPUs run together: each waits until it sees the other
    assert RayRunner(ray, Rendezvous(tmp_path / "pair", 2, wait=120.0)).map([0, 1]) == [2, 2]
    # never more than 2 at once, even when a task would wait for a third
    most = RayRunner(ray, Rendezvous(tmp_path / "four", 3, wait=0.3)).map(range(4))
    assert 1 <= max(most) <= 2
    capped = RayRunner(ray, Rendezvous(tmp_path / "capped", 2, wait=0.3), max_concurrent=1)
    assert capped.concurrency == 1
    assert capped.map(range(3)) == [1, 1, 1]
    assert RayRunner(ray, square, max_concurrent=8).concurrency == 2
    assert RayRunner(ray, square, num_cpus=2).concurrency == 1
    with pytest.raises(UserError, match="asks for 4 CPU and 0 GPU, the cluster has 2 CPU"):
        RayRunner(ray, square, num_cpus=4)
    with pytest.raises(UserError, match="asks for 1 CPU and 1 GPU, the cluster has 2 CPU and 0"):
        RayRunner(ray, square, num_gpus=1)


def test_a_dead_worker_is_retried_by_ray(ray, tmp_path):
    assert RayRunner(ray, CrashOnce(tmp_path), max_retries=1).map([1, 2]) == [101, 102]
    with pytest.raises(ray.exceptions.WorkerCrashedError):
        RayRunner(ray, CrashOnce(tmp_path), max_retries=0).map([3])


def test_errors_returned_raised_or_propagated(ray):
    results = RayRunner(ray, Picky(), returned_errors=(ValueError,)).map([0, 1, 4])
    assert results[0] == 0 and results[2] == 4
    assert isinstance(results[1], ValueError) and str(results[1]) == "diverged"
    with pytest.raises(UserError, match="--lr: must be > 0") as info:
        RayRunner(ray, Picky()).map([2])
    assert type(info.value) is UserError  # as the job raised it: one line for the CLI
    with pytest.raises(ray.exceptions.RayTaskError, match="a bug"):
        RayRunner(ray, Picky(), returned_errors=(ValueError,)).map([3])


def test_a_task_asking_for_no_gpu_sees_none_in_only_assigned_gpus(ray):
    runner = RayRunner(ray, env_of, runtime_env=ONLY_ASSIGNED_GPUS)
    assert runner.map(["CUDA_VISIBLE_DEVICES"]) == [""]


class Counting:
    """Counts the items its process ran: state a job keeps from one task to the next."""

    def __init__(self):
        self.seen = 0

    def __call__(self, x: int) -> tuple[int, int]:
        self.seen += 1
        return os.getpid(), self.seen


def test_each_worker_process_keeps_the_job_and_its_state(ray):
    results = RayRunner(ray, Counting(), max_concurrent=1).map(range(8))
    for pid in {p for p, _ in results}:  # each process counts its own tasks, from 1 on
        counts = [n for p, n in results if p == pid]
        assert counts == list(range(1, len(counts) + 1))
    assert max(n for _, n in results) > 1  # the job was not shipped again with each task
