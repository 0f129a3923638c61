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

- `LocalRunner`: one item after the other in this process;
- `PoolRunner`: worker processes forked from a `ForkServer`, a process that imported the
  workers' modules once (each worker is a fork of it, so none imports them again);
- `RayRunner`: Ray tasks, on a local Ray instance or a cluster.

`check_workers` checks a ``--workers`` count (0: all cores).
"""

from __future__ import annotations

import importlib
import importlib.util
import multiprocessing as mp
import os
import pickle
import signal
import socket
import sys
import traceback
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import closing, contextmanager
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any, Literal

from vistac.config import Config, ConfigError, param
from vistac.errors import UserError

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


# ------------------------------------------------------------------------------- runners
class Runner:
    """Runs a job over a batch of items (see the module's docstring).

    Attributes:
        concurrency: Jobs at once.
        returned_errors: Exception types that a job raises as a result (a failed trial,
            say): they are yielded in place of the result instead of ending the batch.
    """

    concurrency: int = 1
    returned_errors: tuple[type[BaseException], ...] = ()

    def run(self, items: Iterable[Any]) -> Iterator[tuple[int, Any]]:
        """(position in `items`, result) of every item, in the order they finish."""
        raise NotImplementedError

    def map(self, items: Iterable[Any]) -> list[Any]:
        """The results of every item, in the order of `items`."""
        return list(self.ordered(items))

    __call__ = map

    def ordered(self, items: Iterable[Any]) -> Iterator[Any]:
        """The results in the order of `items`, each as soon as it and those before it are
        done (a progress bar can follow them)."""
        waiting: dict[int, Any] = {}
        next_position = 0
        runs = self.run(items)
        try:
            for position, result in runs:
                waiting[position] = result
                while next_position in waiting:
                    yield waiting.pop(next_position)
                    next_position += 1
        finally:
            runs.close()


def close_job(job: Any) -> None:
    """Close a job's per-process state, if it has any (its ``close()``)."""
    close = getattr(job, "close", None)
    if callable(close):
        close()


class LocalRunner(Runner):
    """Runs the items one after the other in this process.

    Args:
        job: Item -> result.
        returned_errors: Exception types a job raises as its result (yielded in its place);
            any other exception propagates.
    """

    def __init__(self, job: Callable[[Any], Any],
                 returned_errors: tuple[type[BaseException], ...] = ()):
        self.job, self.returned_errors = job, tuple(returned_errors)

    def run(self, items: Iterable[Any]) -> Iterator[tuple[int, Any]]:
        """(position, result) of each item, in order (items are drawn one at a time)."""
        try:
            for position, item in enumerate(items):
                try:
                    result = self.job(item)
                except self.returned_errors as exc:
                    result = exc
                yield position, result
        finally:
            close_job(self.job)


class WorkerDied(RuntimeError):
    """A worker process died before it answered (killed, out of memory)."""


class RemoteTraceback(Exception):
    """The traceback of an exception raised in a worker process (its ``__cause__``)."""

    def __str__(self) -> str:
        return "\n" + str(self.args[0] if self.args else "")


class ForkServer:
    """A process that imports `preload` once and forks worker processes from itself.

    It starts fresh (spawned: no GL context, no threads of this process), imports the modules
    in `preload` (MuJoCo, meshes, renderer, pandas: about two seconds), then forks the workers
    of each `PoolRunner` and `call`; so no worker imports them again, and the imports run beside
    this process's own from `start` on. It runs the work it is given one batch at a time,
    ignores SIGINT (this process stops it) and exits when this process does; `stop` waits for it,
    so its workers' CPU time counts among this process's children (`getrusage`).

    Use it as a context manager (`start` on entry, `stop` on exit). The server imports the
    calling script's main module, as every `multiprocessing` start method but "fork" does.

    Args:
        preload: Modules the server imports before it forks any worker.
    """

    def __init__(self, preload: Sequence[str] = ()):
        self.preload = tuple(preload)
        self._process: Any = None
        self._conn: Connection | None = None

    def start(self) -> ForkServer:
        """Start the server (if it is not running); returns it."""
        if self._process is None:
            ctx = mp.get_context("spawn")
            self._conn, theirs = ctx.Pipe()
            self._process = ctx.Process(target=_serve_forks, args=(theirs, self.preload),
                                        name="vistac-fork-server", daemon=True)
            self._process.start()
            theirs.close()
        return self

    def stop(self) -> None:
        """Stop the server and wait for it (and so for all its workers)."""
        if self._process is None:
            return
        process, conn = self._process, self._conn
        self._process = self._conn = None
        try:
            conn.send(None)
        except OSError:
            pass
        conn.close()
        process.join(30)
        if process.is_alive():
            process.terminate()
            process.join()

    __enter__ = start

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def call(self, fn: Callable[..., Any], *args: Any) -> Any:
        """`fn(*args)` (a picklable function) in one new worker, which ends with the call.

        Raises:
            WorkerDied: the worker died before it answered (killed, out of memory).
        """
        return PoolRunner(self, _Apply(fn), 1).map([args])[0]

    def _batch(self, job: Callable[[Any], Any], workers: int,
               items: list[Any]) -> Iterator[tuple]:
        """The server's messages about one batch: ``("result", position, ok, value)`` and
        ``("died", None, status)``, until the batch is over.

        Raises:
            WorkerDied: the server itself is gone (killed).
        """
        conn = self.start()._conn
        over = False
        try:
            conn.send(("batch", job, workers, items))
            while True:
                message = conn.recv()
                if message[0] == "over":
                    over = True
                    return
                yield message
        except (EOFError, OSError):
            over = True
            raise WorkerDied("the fork server of the workers died") from None
        finally:
            if not over:  # stopped early: the server stops the workers, then says "over"
                try:
                    conn.send(("stop",))
                    while conn.recv()[0] != "over":
                        pass
                except (EOFError, OSError):
                    pass


@dataclass(frozen=True)
class _Apply:
    """An item of arguments -> ``fn(*item)``: the job of `ForkServer.call`."""

    fn: Callable[..., Any]

    def __call__(self, args: tuple) -> Any:
        return self.fn(*args)


class PoolRunner(Runner):
    """Runs the items in `workers` processes forked from `server`, at most one item at a time
    each (the job is pickled once, and each worker keeps its state from item to item).

    Args:
        server: The fork server (started if it is not).
        job: A picklable callable, item -> result.
        workers: Worker processes (at most one per item).
        returned_errors: As for `LocalRunner`.

    Raises (from `run`):
        WorkerDied: a worker died before it answered (the others are stopped).
        Exception: what a job raised (not in `returned_errors`), with the worker's traceback
            as its ``__cause__``.
    """

    def __init__(self, server: ForkServer, job: Callable[[Any], Any], workers: int,
                 returned_errors: tuple[type[BaseException], ...] = ()):
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.server, self.job, self.concurrency = server, job, workers
        self.returned_errors = tuple(returned_errors)

    def run(self, items: Iterable[Any]) -> Iterator[tuple[int, Any]]:
        items = list(items)
        if not items:
            return
        with closing(self.server._batch(self.job, self.concurrency, items)) as messages:
            for message in messages:
                if message[0] == "died":
                    raise WorkerDied(f"{_name(self.job)}: its worker process died before it "
                                     f"finished (killed or out of memory; {message[2]})")
                _, position, ok, value = message
                if ok or isinstance(value[0], self.returned_errors):
                    yield position, value if ok else value[0]
                else:
                    exc, text = value
                    raise exc from RemoteTraceback(text)


def _name(job: Any) -> str:
    fn = job.fn if isinstance(job, _Apply) else job
    return getattr(fn, "__name__", type(fn).__name__)


# ------------------------------------------------------------ inside the fork server
def _serve_forks(conn: Connection, preload: tuple[str, ...]) -> None:
    """The fork server's main loop: batches until this process says stop (or exits)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for name in preload:
        try:
            importlib.import_module(name)
        except ImportError:  # as the standard library's fork server: the job will say
            pass
    while True:
        try:
            message = conn.recv()
        except EOFError:
            return
        if message is None:
            return
        if message[0] == "batch" and not _run_batch(conn, *message[1:]):
            return


@dataclass
class _Worker:
    """The fork server's side of one worker: its process, its pipe, the items it was handed
    and has not answered yet (in order)."""

    pid: int
    pipe: Connection
    handed: deque = field(default_factory=deque)


def _run_batch(conn: Connection, job: Callable[[Any], Any], workers: int,
               items: list[Any]) -> bool:
    """Fork the workers of one batch, hand them the items, pass their results on; stop them
    early when this batch's driver says so. Returns whether to go on serving.

    A worker holds one item more than it runs while enough are left for every worker (so it
    never waits for this process between two items); near the end only idle workers get one.
    """
    todo = deque(enumerate(items))
    crew: list[_Worker] = []
    serving = True

    def hand(worker: _Worker) -> None:
        while todo and len(worker.handed) < (2 if len(todo) >= len(crew) else 1):
            position, item = todo.popleft()
            worker.pipe.send((position, item))
            worker.handed.append(position)

    try:
        for _ in range(min(workers, len(items))):
            mine, theirs = mp.Pipe()
            pid = os.fork()
            if pid == 0:  # the worker
                status = 1
                try:
                    for other in (conn, mine, *(w.pipe for w in crew)):
                        other.close()
                    _work(job, theirs)
                    status = 0
                finally:
                    os._exit(status)
            theirs.close()
            crew.append(_Worker(pid, mine))
        for worker in crew:
            hand(worker)
        while any(w.handed for w in crew):
            ready = wait([conn, *(w.pipe for w in crew if w.handed)])
            if conn in ready:  # the driver stopped early, or went away
                try:
                    serving = conn.recv() is not None
                except EOFError:
                    serving = False
                return serving
            for worker in (w for w in crew if w.pipe in ready):
                try:
                    position, ok, value = worker.pipe.recv()
                except EOFError:
                    _, status = os.waitpid(worker.pid, 0)
                    crew.remove(worker)
                    worker.handed.clear()
                    conn.send(("died", None, f"exit status "
                               f"{os.waitstatus_to_exitcode(status)}"))
                    return serving
                worker.handed.remove(position)
                conn.send(("result", position, ok, value))
                hand(worker)
        return serving
    finally:
        for worker in crew:  # those still busy are stopped; the others end on None
            try:
                if worker.handed:
                    os.kill(worker.pid, signal.SIGTERM)
                else:
                    worker.pipe.send(None)
            except OSError:  # it died meanwhile
                pass
            worker.pipe.close()
            os.waitpid(worker.pid, 0)
        if serving:
            conn.send(("over",))


def _work(job: Callable[[Any], Any], pipe: Connection) -> None:
    """A worker: (position, item) from `pipe` through the job until None (or the server's
    end); answers (position, ok, result or error)."""
    try:
        while True:
            try:
                handed = pipe.recv()
            except EOFError:
                return
            if handed is None:
                return
            position, item = handed
            try:
                answer = (position, True, job(item))
            except Exception as exc:
                answer = (position, False, _portable(exc))
            try:
                pipe.send(answer)
            except (pickle.PicklingError, TypeError, AttributeError) as exc:
                error = RuntimeError(f"cannot send the result back: {exc}")
                pipe.send((position, False, _portable(error)))
    finally:
        close_job(job)


def _portable(exc: Exception) -> tuple[Exception, str]:
    """An exception and its traceback as text, in a form that pickles."""
    text = "".join(traceback.format_exception(exc))
    try:
        pickle.loads(pickle.dumps(exc))
    except Exception:
        exc = RuntimeError(f"{type(exc).__name__}: {exc}")
    return exc, text


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
