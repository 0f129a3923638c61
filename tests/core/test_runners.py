"""`vistac.engine`'s local runners: `LocalRunner`, and `PoolRunner` on a `ForkServer` (results,
order, errors, a worker's state and its close, a dead worker, an early stop). `RayRunner` is
tested in tests/scale/test_ray_runner.py."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from multiprocessing import active_children
from pathlib import Path

import pytest

from vistac.engine import ForkServer, LocalRunner, PoolRunner, RemoteTraceback, WorkerDied
from vistac.errors import UserError


def square(x: int) -> int:
    if x < 0:
        raise UserError(f"negative: {x}")
    if x == 13:
        raise ValueError("unlucky")
    return x * x


def die(x: int) -> int:
    if x == 2:
        os._exit(7)
    return x


def slow(x: float) -> int:
    time.sleep(x)
    return os.getpid()


class Counting:
    """A job with per-process state: how many items this process ran, and a file per close."""

    def __init__(self, folder: str):
        self.folder, self.seen = folder, 0

    def __call__(self, item: int) -> tuple[int, int]:
        self.seen += 1
        return os.getpid(), self.seen

    def close(self) -> None:
        with open(os.path.join(self.folder, f"closed_{os.getpid()}"), "w") as fh:
            fh.write(str(self.seen))


@pytest.fixture(scope="module")
def server():
    with ForkServer() as forks:
        yield forks
    assert not active_children()  # stopped and waited for


def test_pool_runner_yields_every_result_with_its_position(server):
    runner = PoolRunner(server, square, 2)
    assert runner.concurrency == 2
    done = dict(runner.run(range(7)))
    assert done == {i: i * i for i in range(7)}
    assert runner.map([3, 1, 2]) == [9, 1, 4]
    assert runner.map([]) == []


def test_a_job_error_is_raised_with_the_workers_traceback_and_a_returned_error_yielded(server):
    with pytest.raises(ValueError, match="unlucky") as info:
        PoolRunner(server, square, 2).map([1, 13, 2])
    assert isinstance(info.value.__cause__, RemoteTraceback)
    assert "in square" in str(info.value.__cause__)
    with pytest.raises(UserError, match="negative: -1"):
        PoolRunner(server, square, 1).map([-1])
    results = PoolRunner(server, square, 2, returned_errors=(ValueError,)).map([2, 13])
    assert results[0] == 4 and isinstance(results[1], ValueError)
    assert PoolRunner(server, square, 2).map([5]) == [25]  # the server serves on after errors


def test_each_worker_keeps_its_state_and_closes_it(server, tmp_path):
    results = PoolRunner(server, Counting(str(tmp_path)), 2).map(range(10))
    pids = {pid for pid, _ in results}
    assert 1 <= len(pids) <= 2 and os.getpid() not in pids
    for pid in pids:  # each worker counts its own items, from 1 on: the job was not re-made
        counts = sorted(n for p, n in results if p == pid)
        assert counts == list(range(1, len(counts) + 1))
        assert (tmp_path / f"closed_{pid}").read_text() == str(len(counts))


def test_a_dead_worker_is_an_error_and_an_early_stop_stops_the_workers(server):
    with pytest.raises(WorkerDied, match=r"die: its worker process died .*exit status 7"):
        PoolRunner(server, die, 2).map([0, 1, 2, 3])
    runs = PoolRunner(server, slow, 2).run([0.0, 60.0, 60.0])
    _, pid = next(runs)
    runs.close()  # the two sleeping workers are stopped, not waited for
    assert PoolRunner(server, square, 1).map([4]) == [16]
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # the workers are gone (waited for by the server)


def test_a_killed_server_is_an_error_not_a_hang():
    with ForkServer() as forks:
        assert PoolRunner(forks, square, 1).map([3]) == [9]
        os.kill(forks._process.pid, signal.SIGKILL)
        with pytest.raises(WorkerDied, match="the fork server of the workers died"):
            PoolRunner(forks, square, 1).map([3])


def test_a_script_with_or_without_a_main_guard_starts_workers(tmp_path):
    """The server does not import the calling script's main module (issue 31): a script that
    starts workers at import time, without the ``__main__`` guard, works like a guarded one
    (it used to start them again in the server, which died: WorkerDied)."""
    script = tmp_path / "unguarded.py"
    for code in ("from vistac.engine import ForkServer, PoolRunner\n"
                 "with ForkServer() as forks:\n"
                 "    print(PoolRunner(forks, abs, 1).map([-3]))\n",
                 "from vistac.engine import ForkServer, PoolRunner\n"
                 "if __name__ == '__main__':\n"
                 "    with ForkServer() as forks:\n"
                 "        print(PoolRunner(forks, abs, 1).map([-3]))\n"):
        script.write_text(code)
        res = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                             timeout=120)
        assert res.returncode == 0 and res.stdout.strip() == "[3]", res.stderr[-2000:]


def test_call_runs_in_a_new_worker(server):
    assert server.call(pow, 2, 10) == 1024
    assert server.call(os.getpid) not in (os.getpid(), server.call(os.getpid))


def test_local_runner_runs_in_order_here_and_closes_the_job(tmp_path):
    job = Counting(str(tmp_path))
    assert LocalRunner(job).map(range(3)) == [(os.getpid(), 1), (os.getpid(), 2),
                                              (os.getpid(), 3)]
    assert (tmp_path / f"closed_{os.getpid()}").read_text() == "3"
    got = LocalRunner(square, (ValueError,)).map([13, 2])
    assert isinstance(got[0], ValueError) and got[1] == 4
    with pytest.raises(ValueError):
        LocalRunner(square).map([13])


# A driver that starts two workers on long items, prints the server's and the workers' process
# ids, and kills itself with SIGKILL.
KILLED_DRIVER = """
import os, signal, sys
sys.path.insert(0, sys.argv[1])
from test_runners import slow
from vistac.engine import ForkServer, PoolRunner
server = ForkServer().start()
runs = PoolRunner(server, slow, 2).run([0.0, 60.0, 0.0, 60.0])
print(server._process.pid, next(runs)[1], next(runs)[1], flush=True)
os.kill(os.getpid(), signal.SIGKILL)
"""


def _gone(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return True
    return state in ("Z", "X")  # a zombie whose parent died: nothing runs any more


def test_a_killed_driver_leaves_no_server_and_no_worker_running():
    done = subprocess.run([sys.executable, "-c", KILLED_DRIVER, str(Path(__file__).parent)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == -signal.SIGKILL, done.stderr
    pids = [int(p) for p in done.stdout.split()]
    assert len(set(pids)) == 3  # the server and two workers, each busy with a 60 s item
    deadline = time.monotonic() + 30
    while not all(_gone(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert all(_gone(p) for p in pids)
