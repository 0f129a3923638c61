"""Where the work of `generate`, `tune` and the experiments runs: this process, worker processes
forked from a fork server, or Ray tasks on a cluster.

`EngineCfg` holds the options (``--engine``, ``--ray-address``, ``--max-concurrent``, and
for `generate` ``--ray-writes``);
`ray_session` starts a local Ray instance (or joins a cluster) for the length of a run;
`RayRunner` runs a batch of job configs as Ray tasks. Ray does the scheduling, the resource
accounting (each task asks for ``num_cpus``), the retries of tasks whose worker died
(``max_retries``) and the completion order (``ray.wait``); the runner only keeps at most
`concurrency` tasks in flight, so a long batch does not flood the object store and a sequential
optimiser can ask for just that many suggestions at a time.

Ray is an optional extra (``pip install 'vistac[ray]'``) and is imported only by `ray_session`.

The runners share one interface (`Runner`): ``run(items)`` yields ``(position, result)`` as
jobs finish, ``map(items)`` returns the results in order, ``concurrency`` says how many run at
once. A job is a picklable callable, item -> result; a job with a ``close()`` method is closed
in each process that ran it, at the end (its per-process state: scenes, renderers):

- `LocalRunner` (`vistac.runners`, with `Runner`): one item after the other in this process;
- `PoolRunner` (`vistac.fork_pool`): worker processes forked from a `ForkServer`, a process
  that imported the workers' modules once (each worker is a fork of it, so none imports them
  again);
- `RayRunner` (here): Ray tasks, on a local Ray instance or a cluster.

All are importable from here.

`check_workers` checks a ``--workers`` count (0: all cores).
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import socket
import sys
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from vistac.config import Config, ConfigError, param
from vistac.errors import UserError
from vistac.fork_pool import ForkServer, PoolRunner, RemoteTraceback, WorkerDied  # noqa: F401
from vistac.runners import LocalRunner, Runner, close_job  # noqa: F401

ENGINE_OPTIONS = ("engine", "ray_address", "max_concurrent")
WRITES_OPTIONS = ("ray_writes",)  # `generate` only: who writes what the tasks make
LOCAL_OBJECT_STORE_BYTES = 128 * 2**20  # a local instance's object store: results are small
# A task's runtime environment in which it sees only the GPUs Ray assigned to it: by default
# (Ray 2.60) a task that asks for no GPU is not hidden from the node's GPUs.
ONLY_ASSIGNED_GPUS = {"env_vars": {"RAY_ACCEL_ENV_VAR_OVERRIDE_ON_ZERO": "1"}}


@dataclass(frozen=True)
class EngineCfg(Config):
    """Which engine runs the tasks of a command, and where."""

    engine: Literal["local", "ray"] = param(
        "local", help="local: processes on this machine; ray: Ray tasks, on a local Ray "
        "instance or on the cluster of --ray-address")
    ray_address: str | None = param(
        None, metavar="ADDR", help="Ray cluster to join (e.g. HEAD_IP:6379); default: "
        "$RAY_ADDRESS, else a local Ray instance started for this run")
    max_concurrent: int | None = param(
        None, ge=1, metavar="K", help="with --engine ray: at most K tasks at once (default: "
        "as many as the cluster has CPUs)")
    ray_writes: Literal["driver", "workers"] = param(
        "driver", help="with --engine ray: who writes each chunk's images and shard. driver: "
        "the tasks send them back, no shared filesystem needed, one process writes it all; "
        "workers: each task writes into --out, which must then be a folder every node shares "
        "(the driver stops being the limit on a large cluster)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.engine == "local":
            for key in ("ray_address", "max_concurrent"):
                if getattr(self, key) is not None:
                    raise ConfigError(key, "needs --engine ray")
            if self.ray_writes != "driver":
                raise ConfigError("ray_writes", "needs --engine ray")

    @property
    def address(self) -> str | None:
        """The cluster to join: --ray-address, else $RAY_ADDRESS, else None (start one)."""
        return self.ray_address or os.environ.get("RAY_ADDRESS") or None


def import_ray() -> Any:
    """The `ray` module.

    Raises:
        UserError: Ray is not installed.
    """
    try:
        import ray
    except ImportError:
        raise UserError("--engine ray: Ray is not installed; pip install 'vistac[ray]'") from None
    return ray


def preflight(engine: EngineCfg) -> None:
    """Fail before a run touches its output when its engine cannot start.

    Checks that Ray is installed and that the cluster address (if any) answers.

    Raises:
        UserError: Ray is missing, or nothing listens at the address.
    """
    if engine.engine == "ray":
        if importlib.util.find_spec("ray") is None:  # not imported yet: see `_token_auth`
            import_ray()
        if engine.address:
            _check_reachable(engine.address)


@contextmanager
def ray_session(engine: EngineCfg, num_cpus: int | None = None) -> Iterator[Any]:
    """Ray, initialised for the length of the block; yields the `ray` module.

    Without an address a local instance is started with `num_cpus` CPUs (default: all cores),
    a small object store and no dashboard, and shut down at the end. With one (or
    ``RAY_ADDRESS``) the driver joins that cluster and leaves it at the end. A session that is
    already initialised (by the caller) is used as it is and left running.

    Raises:
        UserError: Ray is missing, or the cluster at the address cannot be joined.
    """
    if engine.address:
        _token_auth()
    ray = import_ray()
    if ray.is_initialized():
        yield ray
        return
    quiet = {"logging_level": "ERROR", "log_to_driver": False}
    if engine.address:
        _check_reachable(engine.address)
        try:
            ray.init(address=engine.address, **quiet)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise UserError(f"--ray-address {engine.address}: cannot join the Ray cluster "
                            f"({first})") from None
    else:  # "local": a fresh instance, even when a cluster runs on this machine
        ray.init(address="local", num_cpus=num_cpus or os.cpu_count(),
                 object_store_memory=LOCAL_OBJECT_STORE_BYTES, include_dashboard=False, **quiet)
    try:
        yield ray
    finally:
        ray.shutdown()


def _check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """Fail fast on a cluster address nothing listens at (Ray itself retries for minutes).

    Raises:
        UserError: no connection to HOST:PORT within `timeout_s`.
    """
    host, _, port = address.split("://")[-1].rpartition(":")
    if not host or not port.isdigit():
        return  # "auto" and other forms Ray resolves itself
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as exc:
        raise UserError(f"--ray-address {address}: no Ray cluster answers there ({exc}); "
                        "start one with `ray start --head`") from None


def _token_auth() -> None:
    """Join with Ray's token authentication when a token is at hand and no mode is set.

    `ray start --head` turns token authentication on by default (Ray 2.59 and later) with the
    token in ``~/.ray/auth_token``, but a driver joining an address does not send that token
    unless ``RAY_AUTH_MODE=token``, which Ray reads when it is imported. A token sent to a
    cluster without authentication is ignored.
    """
    token_at_hand = (os.environ.get("RAY_AUTH_TOKEN") or os.environ.get("RAY_AUTH_TOKEN_PATH")
                     or (Path.home() / ".ray" / "auth_token").is_file())
    if token_at_hand and "ray" not in sys.modules:
        os.environ.setdefault("RAY_AUTH_MODE", "token")


def check_workers(workers: int, option: str = "--workers") -> int:
    """`workers` checked (0: all cores) and capped at the cores, with a note when capped.

    Raises:
        UserError: a negative number.
    """
    cores = os.cpu_count() or 1
    if workers < 0:
        raise UserError(f"{option}: must be >= 0 (0: all {cores} cores), got {workers}")
    if workers > cores:
        print(f"note: {option} {workers} capped at the {cores} cores", file=sys.stderr)
    return min(workers or cores, cores)



def _bound(job: Callable[[Any], Any]) -> Callable[[Any], Any]:
    """The body of every task, bound to `job`: Ray ships a remote function once to each worker
    process and keeps it there, so the job's per-process state (a scene cache, say) lasts from
    one task to the next."""

    def task(item: Any) -> Any:
        return job(item)

    return task


class RayRunner(Runner):
    """Runs a batch of job configs as Ray tasks, yielding results as the tasks finish.

    Args:
        ray: The initialised `ray` module (from `ray_session`).
        job: A picklable callable, job config -> result; it is shipped once to each worker
            process, which keeps it (and its state) from one task to the next.
        returned_errors: Exception types that a job raises as a result (a failed trial, say):
            they are yielded in place of the result instead of ending the batch. Any other
            exception ends the batch (a `UserError` raised by a job is raised as itself).
        max_concurrent: At most this many tasks in flight (None: as many as fit the cluster's
            CPUs at `num_cpus` per task, and its GPUs at `num_gpus`).
        num_cpus: CPUs Ray reserves for each task.
        num_gpus: GPUs Ray reserves for each task (and makes visible to it; a task that asks
            for none sees none).
        max_retries: Times Ray re-runs a task whose worker process or node died.
        runtime_env: Ray's runtime environment of the tasks (e.g. `ONLY_ASSIGNED_GPUS`).

    Raises:
        UserError: the cluster has fewer CPUs or GPUs than one task asks for.
    """

    def __init__(self, ray: Any, job: Callable[[Any], Any],
                 returned_errors: tuple[type[BaseException], ...] = (),
                 max_concurrent: int | None = None, num_cpus: float = 1, num_gpus: float = 0,
                 max_retries: int = 3, runtime_env: dict | None = None):
        self.ray, self.returned_errors = ray, tuple(returned_errors)
        self._task = ray.remote(_bound(job)).options(
            num_cpus=num_cpus, num_gpus=num_gpus, max_retries=max_retries, runtime_env=runtime_env)
        have = ray.cluster_resources()
        fits = [int(have.get(kind, 0) // need)
                for kind, need in (("CPU", num_cpus), ("GPU", num_gpus)) if need > 0]
        if min(fits, default=1) < 1:
            raise UserError(f"--engine ray: a task asks for {num_cpus:g} CPU and {num_gpus:g} "
                            f"GPU, the cluster has {have.get('CPU', 0):g} CPU and "
                            f"{have.get('GPU', 0):g} GPU")
        fit = min(fits, default=1)
        self.concurrency = max(1, min(fit, max_concurrent or fit))

    def run(self, items: Iterable[Any]) -> Iterator[tuple[int, Any]]:
        """(position in `items`, result) of every job config, in the order they finish.

        Raises:
            UserError: a job raised one (as the job raised it).
            ray.exceptions.RayError: a job raised another error not in `returned_errors` (with
                the remote traceback), or its task failed more than `max_retries` times.
        """
        todo = enumerate(items)
        pending: dict[Any, int] = {}
        try:
            while True:
                for position, item in todo:
                    pending[self._task.remote(item)] = position
                    if len(pending) >= self.concurrency:
                        break
                if not pending:
                    return
                (ref,), _ = self.ray.wait(list(pending), num_returns=1)
                yield pending.pop(ref), self._result(ref)
        finally:  # an early stop (error, interrupt, a closed generator): drop what is left
            for ref in pending:
                self.ray.cancel(ref)

    def _result(self, ref: Any) -> Any:
        try:
            return self.ray.get(ref)
        except self.ray.exceptions.RayTaskError as exc:
            cause = exc.cause
            if isinstance(cause, self.returned_errors):
                return cause
            if isinstance(cause, UserError):
                raise cause from None
            raise
