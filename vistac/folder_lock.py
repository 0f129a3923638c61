"""One writer per output folder: an exclusive lock held for the length of a command.

Every command that writes a folder (generate, ingest, train, tune, experiments, evaluate) holds
`hold(out)` while it works, and, once it holds it, checks that the folder is of its kind
(`vistac.folder_kinds`). The lock is an advisory ``flock`` on a small file beside the real
folder, ``<parent>/.<name>.lock``, so it exists before the folder does and never shows up among
the folder's own files. The folder's path is resolved first (symbolic links, ``..``), so a
folder reached by two names has one lock. The operating system releases a ``flock`` when its
process dies, however it dies (``kill -9`` included), so a stale lock of a dead process is simply
taken over: there is no pid to check and no timeout to guess. The file records its holder (pid,
host, command, start time) for the error a second process gets; it is removed when the holder
finishes.

Limits: ``flock`` is honoured between processes of one machine; on network file systems that do
not forward it, two machines writing one folder are not kept apart.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import socket
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from vistac.errors import UserError
from vistac.folder_kinds import KIND_OF_COMMAND, check_kind


def lock_path(out: str | Path) -> Path:
    """The lock file of folder `out`: ``.<name>.lock`` beside the folder it really is (every
    symbolic link on the way followed, so two names of one folder share one lock)."""
    folder = Path(os.path.realpath(os.path.abspath(out)))
    return folder.parent / f".{folder.name or 'root'}.lock"


def holder(path: Path) -> str:
    """Who holds the lock file `path`, in words (read from the file)."""
    try:
        info = json.loads(path.read_text())
        started = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(float(info["started"])))
        return (f"pid {int(info['pid'])} on {str(info['host'])[:64]}, "
                f"'{str(info['command'])[:40]}' started {started}")
    except (OSError, ValueError, KeyError, TypeError):
        return "another process (just starting)"


@contextlib.contextmanager
def hold(out: str | Path, command: str = "", kind: str | None = None) -> Iterator[Path]:
    """Hold the exclusive lock of folder `out` for the block, and check its kind.

    Args:
        out: The output folder (it need not exist yet).
        command: What holds it, for a second process's error (e.g. ``"generate"``).
        kind: The kind of folder the command writes (`vistac.folder_kinds`); default: the
            kind of `command` (none for other names).

    Yields:
        The lock file's path.

    Raises:
        UserError: another live process holds the folder (the message names it); the folder
            holds another kind of folder, or is not empty and holds none (`check_kind`).
    """
    path = lock_path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise UserError(f"--out {out}: in use by {holder(path)}; wait for it to finish or "
                            "choose another --out") from None
        try:  # the holder before us may have removed the file between our open and our lock
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        info = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.time(),
                "command": command or " ".join(sys.argv[:2])}
        os.ftruncate(fd, 0)
        os.write(fd, json.dumps(info).encode())
        kind = kind or KIND_OF_COMMAND.get(command)
        if kind is not None:  # under the lock: nobody else writes the folder meanwhile
            check_kind(out, kind)
        yield path
    finally:
        with contextlib.suppress(OSError):
            path.unlink()  # before the release: a waiting process then opens a new file
        os.close(fd)
