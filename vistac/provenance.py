"""Where a result came from: the record every benchmark results JSON carries.

`provenance(datasets)` returns ``command`` (argv), ``commit`` and ``dirty`` (the git state of
the checkout the code was imported from, None outside a checkout), ``date`` (UTC, ISO 8601),
``machine`` (cores, CPU model, memory, GPU or none, Python and torch versions) and
``datasets`` (each dataset folder read, with its fingerprint), so that a figure can be
traced to the code, the machine and the data that produced it.
"""

from __future__ import annotations

import datetime as _dt
import os
import platform
import shlex
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _git(*args: str) -> str | None:
    try:
        out = subprocess.run(["git", "-C", str(REPO), *args], capture_output=True, text=True,
                             timeout=30, check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip()


RESULTS_DIR = "benchmarks/results/"
"""Where the benchmarks write: changes there are their own outputs, not a dirty checkout."""


def git_state() -> tuple[str | None, bool | None]:
    """(commit, whether tracked files other than the benchmarks' results differ from it) of the
    checkout holding this package; (None, None) for an installed copy outside a git checkout."""
    commit = _git("rev-parse", "HEAD")
    if commit is None:
        return None, None
    status = _git("status", "--porcelain", "--untracked-files=no")
    if status is None:
        return commit, None
    changed = [line.split(maxsplit=1)[1].split(" -> ")[-1] for line in status.splitlines()
               if line.strip()]
    return commit, any(not path.startswith(RESULTS_DIR) for path in changed)


def cpu_model() -> str:
    """The processor's model name (``/proc/cpuinfo``), else what `platform` says."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def gpu() -> str | None:
    """The CUDA device torch sees (name), or None: without torch imported, none is asked."""
    torch = sys.modules.get("torch")
    if torch is None or not torch.cuda.is_available():
        return None
    return torch.cuda.get_device_name(0)


def machine() -> dict:
    """Cores, CPU model, memory, GPU, OS and versions of the machine measuring."""
    try:
        mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30
    except (ValueError, OSError, AttributeError):
        mem = None
    torch = sys.modules.get("torch")
    return {"cores": os.cpu_count(), "cpu": cpu_model(),
            "memory_gib": round(mem, 1) if mem else None, "gpu": gpu(),
            "platform": platform.platform(), "python": platform.python_version(),
            "torch": getattr(torch, "__version__", None),
            "torch_threads": torch.get_num_threads() if torch is not None else None}


def dataset_fingerprints(datasets) -> dict[str, str | None]:
    """Each dataset folder -> its fingerprint (`DatasetTables.fingerprint`), None for one that
    cannot be read."""
    from vistac.dataset import open_tables
    from vistac.errors import UserError

    out = {}
    for d in datasets:
        try:
            out[str(d)] = open_tables(d).fingerprint()
        except (UserError, OSError):
            out[str(d)] = None
    return out


def provenance(datasets=()) -> dict:
    """The record a results JSON carries (see the module's description)."""
    commit, dirty = git_state()
    return {"command": shlex.join(["python", *sys.argv]), "commit": commit, "dirty": dirty,
            "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "machine": machine(), "datasets": dataset_fingerprints(datasets)}
