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


def timed_nap(x: float) -> tuple[float, float]:
    start = time.time()
    time.sleep(x)
    return start, time.time()


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


def _max_overlap(spans: list[tuple[float, float]]) -> int:
    events = sorted([(s, 1) for s, _ in spans] + [(e, -1) for _, e in spans])
    level = peak = 0
    for _, step in events:
        level += step
        peak = max(peak, level)
    return peak


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


def test_concurrency_follows_the_cpus_and_the_cap(ray):
    spans = RayRunner(ray, timed_nap).map([0.4] * 4)
    assert _max_overlap(spans) == 2
    capped = RayRunner(ray, timed_nap, max_concurrent=1)
    assert capped.concurrency == 1
    assert _max_overlap(capped.map([0.1] * 3)) == 1
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
