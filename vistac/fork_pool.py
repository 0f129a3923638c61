"""`PoolRunner`: a job run over a batch of items by worker processes forked from a
`ForkServer`, a fresh process that imports the heavy modules (the simulator) once; errors come
back with the worker's traceback (`RemoteTraceback`), a dead worker is `WorkerDied`.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.util
import multiprocessing as mp
import os
import pickle
import signal
import sys
import traceback
import types
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import closing
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from typing import Any

from vistac.runners import Runner, close_job


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

    Use it as a context manager (`start` on entry, `stop` on exit). Unlike `multiprocessing`'s
    own "spawn" and "forkserver", the server does not import the calling program's main module
    (`_without_main`): its work is the project's own functions, so it starts the same from a
    script (guarded by ``if __name__ == "__main__":`` or not), ``python -c``, a script read on
    stdin, `runpy`, a notebook or an embedded interpreter.

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
            with _without_main():
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

    def _death(self) -> str:
        """Why the server is gone, for `WorkerDied`."""
        process = self._process
        if process is not None:
            process.join(5)
        code = getattr(process, "exitcode", None)
        msg = "the fork server of the workers died" + (
            f" (exit status {code})" if code is not None else "")
        return msg

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
            raise WorkerDied(self._death()) from None
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


def spawn_problem() -> str | None:
    """Why this interpreter cannot start worker processes, or None: the program "spawn" runs
    (`sys.executable`, or what `multiprocessing.set_executable` set) must be an executable
    file, which an embedding application's interpreter need not have."""
    from multiprocessing import spawn

    exe = spawn.get_executable()
    exe = os.fsdecode(exe) if exe else ""
    if not exe or not os.path.isfile(exe) or not os.access(exe, os.X_OK):
        return (f"this interpreter cannot start worker processes ({exe or 'its program'} is "
                "not an executable file)")
    return None


@contextlib.contextmanager
def _without_main() -> Iterator[None]:
    """While a process is started by "spawn": a bare ``__main__`` module in place of this
    program's, so that the new process does not import (run) the program's main module.

    Spawn records the main module's file or module name for the child to import again; a script
    read on stdin (``<stdin>``), a notebook's or an embedded interpreter's main module cannot be
    imported there (the child dies at start-up), and a script without the ``__main__`` guard
    would run again. The start itself writes what the child needs at once, so the real module
    is back before `Process.start` returns.
    """
    main = sys.modules.get("__main__")
    sys.modules["__main__"] = types.ModuleType("__main__")
    try:
        yield
    finally:
        if main is None:
            del sys.modules["__main__"]
        else:
            sys.modules["__main__"] = main


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
        except Exception:  # noqa: BLE001 - as the standard library's fork server: the job's
            pass  # own import will say why, in one line (e.g. a GL backend that cannot start)
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
