"""The worker processes of `vistac generate`: a fork server that imports the simulator once.

Light on purpose (only `multiprocessing`): `vistac generate` starts the fork server with
`start_fork_server` before it imports its own table and dataset code, so that the server's
imports (MuJoCo, meshes, renderer: about two seconds) run beside the driver's.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import sys
from contextlib import contextmanager
from functools import partial

from vistac.errors import UserError

WORKER_MODULE = "vistac_sim.generate.worker"
# What the fork server imports for its workers: the worker module, and pandas, which pyarrow
# imports on its first table (a shard): once in the server, not once per worker.
PRELOAD = [WORKER_MODULE, "pandas"]


def start_fork_server() -> None:
    """Start the workers' fork server now (it imports the worker module in the background);
    the first pool forks its workers from it."""
    from multiprocessing import forkserver

    worker_context()
    forkserver.ensure_running()


def worker_context() -> mp.context.BaseContext:
    """Processes for workers: forked from a fork server that imported the simulator once.

    The server starts fresh (no GL context, no threads of this process) and imports the worker
    module and what it needs; each worker is a fork of it, so workers do not import MuJoCo,
    trimesh, pandas and SciPy again (about a second of CPU each), and each makes its own GL
    context.
    """
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(PRELOAD)
    return ctx


@contextmanager
def worker_pool(workers: int, *initargs):
    """A pool of `workers` forked workers (initialised with `initargs` for chunks), or None for
    one worker: the work then runs in this process."""
    if workers == 1:
        yield None
        return
    init = in_worker("init_worker") if initargs else None
    with worker_context().Pool(workers, initializer=init, initargs=initargs) as processes:
        yield processes


def in_new_worker(fn, *args):
    """`fn(*args)` (a picklable, module-level function) in one new worker forked from the fork
    server (so with its imports), which ends with the call; returns its result.

    Raises:
        RuntimeError: when the worker dies before it answers (killed, out of memory).
    """
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    with ProcessPoolExecutor(1, mp_context=worker_context()) as pool:
        try:
            return pool.submit(fn, *args).result()
        except BrokenProcessPool as exc:
            raise RuntimeError(f"{fn.__name__}: its worker process died before it finished "
                               "(killed or out of memory)") from exc


def stop_fork_server() -> None:
    """Stop this process's fork server, if one runs, and wait for it: a run leaves no process
    behind, and its workers' CPU time counts among this process's children (`getrusage`).

    `ForkServer._stop` is the standard library's own way (private, there since Python 3.8); it
    does nothing when no server runs.
    """
    from multiprocessing import forkserver

    stop = getattr(forkserver._forkserver, "_stop", None)
    if stop is not None:
        stop()


def in_worker(name: str) -> partial:
    """`vistac_sim.generate.worker.<name>`, as a picklable callable that does not import the
    worker module here (the workers have it preloaded)."""
    return partial(_call_worker, name)


def _call_worker(name: str, *args):
    from vistac_sim.generate import worker

    return getattr(worker, name)(*args)


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
