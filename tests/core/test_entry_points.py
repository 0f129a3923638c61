"""The API's worker processes start from every Python entry point (issue 31): a script read on
stdin, ``python -c``, `runpy`, a notebook-like main module whose file cannot be imported, and a
script without the ``if __name__ == "__main__":`` guard. The fork server used to import the
caller's main module and died at start-up (a `WorkerDied` traceback) for all but the guarded
script and ``-c``.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

# workers forked from the server answer with their parent's pid: the server's, not this one's
SERVER = """
import os
from vistac.fork_pool import ForkServer
with ForkServer(()) as server:
    pid = server.call(os.getppid)
assert pid != os.getpid(), pid
print("served", flush=True)
"""

ENTRY_POINTS = {
    "stdin": lambda script: ([sys.executable, "-"], script.read_text()),
    "dash-c": lambda script: ([sys.executable, "-c", script.read_text()], None),
    "script-unguarded": lambda script: ([sys.executable, str(script)], None),
    "runpy": lambda script: ([sys.executable, "-c", "import runpy, sys; "
                              f"runpy.run_path({str(script)!r}, run_name='__main__')"], None),
    # a notebook's kernel: the main module names a file that is not a Python script
    "notebook": lambda script: ([sys.executable, "-c", "import __main__, sys; "
                                 "__main__.__file__ = '/nonexistent/Untitled.ipynb'; "
                                 f"exec(open({str(script)!r}).read())"], None),
}


SLOW = {"dash-c", "runpy"}  # -c worked before; runpy fails as the unguarded script did


@pytest.mark.parametrize("entry", [pytest.param(e, marks=pytest.mark.slow) if e in SLOW else e
                                   for e in ENTRY_POINTS])
def test_the_fork_server_starts_from_every_entry_point(entry, tmp_path):
    script = tmp_path / "job.py"
    script.write_text(SERVER)
    argv, stdin = ENTRY_POINTS[entry](script)
    res = subprocess.run(argv, input=stdin, capture_output=True, text=True, timeout=120,
                         cwd=tmp_path)
    assert res.returncode == 0 and "Traceback" not in res.stderr, res.stderr[-2000:]
    assert res.stdout.strip() == "served"


@pytest.mark.slow  # 10 s: the simulator's imports in the server (the start is tested above)
def test_generate_with_workers_from_a_script_on_stdin(tmp_path):
    """The issue's case: ``python - <<EOF ... vistac.generate(cfg, out, workers=2)``."""
    out = tmp_path / "d"
    script = (
        "import vistac\nfrom vistac.config import apply\n"
        "cfg = apply(vistac.GenerateCfg(n=4, repeats=1, chunk_size=2),\n"
        "            {'objects': {'n_objects': 1}, 'render': {'image_size': 32}})\n"
        f"ds = vistac.generate(cfg, {str(out)!r}, workers=2)\n"
        "print(len(ds))\n")
    res = subprocess.run([sys.executable, "-"], input=script, capture_output=True, text=True,
                         timeout=300, cwd=tmp_path)
    assert res.returncode == 0 and "Traceback" not in res.stderr, res.stderr[-2000:]
    assert res.stdout.strip() == "4"
    assert len(pd.read_parquet(Path(out) / "configs.parquet")) == 4


def test_an_interpreter_that_cannot_start_workers_generates_in_process(tmp_path):
    """An embedding application whose interpreter cannot be started again (what "spawn" would
    run is not an executable file): the default workers fall back to this process, with a note
    on stderr, instead of a traceback."""
    out = tmp_path / "d"
    script = (
        "import multiprocessing\nmultiprocessing.set_executable('/nonexistent/host-app')\n"
        "import vistac\nfrom vistac.config import apply\n"
        "cfg = apply(vistac.GenerateCfg(n=2, repeats=1),\n"
        "            {'objects': {'n_objects': 1}, 'render': {'image_size': 32}})\n"
        f"print(len(vistac.generate(cfg, {str(out)!r})))\n")
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=300, cwd=tmp_path)
    assert res.returncode == 0 and "Traceback" not in res.stderr, res.stderr[-2000:]
    assert res.stdout.strip() == "2"
    assert "note: workers: this interpreter cannot start worker processes (/nonexistent/" \
        "host-app is not an executable file); generating in this process" in res.stderr
