"""Writing dataset files: atomic bytes and JSON, deterministic Parquet tables, the manifest.

Also the checks every command makes of its output folder before it starts (`check_out_dir`) and
the clean-up of the temporaries a killed process left behind (`remove_stale_temporaries`).
"""

from __future__ import annotations

import errno
import json
import os
import platform
import stat
import sys
from collections.abc import Iterable
from importlib import import_module
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from vistac.dataset.schema import FINGERS, LABEL_COLUMNS, MANIFEST, SPLITS, label_columns
from vistac.errors import UserError

if TYPE_CHECKING:
    import pandas as pd


def temporary_path(path: Path) -> Path:
    """The temporary file `path` is written through: ``.<name>.<pid>.tmp`` next to it."""
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write `data` to `path` through a temporary file and a rename (none is left on error).

    Raises:
        UserError: the file cannot be written (a full disk, no permission), naming it.
    """
    tmp = temporary_path(path)
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except OSError as exc:
        raise write_error(path, exc) from None
    finally:
        tmp.unlink(missing_ok=True)


class WriteError(UserError, OSError):
    """A file that could not be written, in one line naming it (an `OSError` too, so that a
    caller that tolerates a failed write, e.g. of a cache, still does)."""


def write_error(path: Path, exc: OSError) -> WriteError:
    """The one line of a write to `path` that failed with `exc`; a full disk says what to do
    (the system's error for a full disk names neither the file nor that)."""
    reason = exc.strerror or str(exc)
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        reason += "; free some space there and run the command again"
    err = WriteError(f"{path}: cannot be written: {reason}")
    err.errno = exc.errno
    return err


def atomic_write_json(path: Path, obj: Any) -> None:
    """Write `obj` as indented JSON with sorted keys (the manifest's format), atomically."""
    atomic_write_bytes(path, (json.dumps(obj, indent=2, sort_keys=True) + "\n").encode())


def write_manifest(root: Path, manifest: dict[str, Any]) -> None:
    """Write a dataset's `manifest.json`: its last file, the mark of a complete dataset."""
    atomic_write_json(root / MANIFEST, manifest)


PARQUET_OPTIONS = {"compression": "zstd", "write_statistics": False}
"""How every dataset table is written (deterministic bytes for identical rows)."""


def write_table(path: Path, frame: pd.DataFrame) -> None:
    """Write a table as Parquet, atomically, with deterministic bytes for identical rows."""
    table = pa.Table.from_pandas(frame, preserve_index=False).replace_schema_metadata(None)
    write_row_groups(path, table.schema, [table])


def write_row_groups(path: Path, schema: pa.Schema, tables: Iterable[pa.Table]) -> None:
    """Write `tables` (each of `schema`) as the row groups of one Parquet file, atomically.

    Only one of `tables` is held at a time, so a table larger than memory can be written from a
    generator.
    """
    tmp = temporary_path(path)
    try:
        with pq.ParquetWriter(tmp, schema, **PARQUET_OPTIONS) as writer:
            for table in tables:
                writer.write_table(table, row_group_size=max(1, len(table)))
        os.replace(tmp, path)
    except OSError as exc:
        raise write_error(path, exc) from None
    finally:
        tmp.unlink(missing_ok=True)


def remove_stale_temporaries(folder: Path) -> int:
    """Delete the ``.*.<pid>.tmp`` files in `folder` whose process no longer runs (a kill).

    Returns:
        How many were removed.
    """
    removed = 0
    for p in Path(folder).glob(".*.tmp"):
        pid = p.name.rsplit(".", 2)[-2]
        if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
            p.unlink(missing_ok=True)
            removed += 1
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    return True


_NOT_FILES = ((stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISDIR, "a folder"),
              (stat.S_ISCHR, "a device"), (stat.S_ISBLK, "a device"),
              (stat.S_ISSOCK, "a socket"))


def not_a_file(path: str | Path) -> str | None:
    """What `path` is when it exists but is not a regular file (symbolic links followed), e.g.
    ``"a named pipe (FIFO)"``; None for a regular file, or for nothing there (the reader then
    says "missing" in its own words).

    Reading a named pipe or a device waits for a writer that may never come; every reader of
    data (images, tables, JSON, checkpoints, scene, space and texture files) asks first.
    """
    try:
        mode = os.stat(path).st_mode
    except OSError:  # missing, a loop of links, no permission: the read says so
        return None
    return next((what for test, what in _NOT_FILES if test(mode)),
                None if stat.S_ISREG(mode) else "not a regular file")


def broken_link(path: str | Path) -> str | None:
    """Why `path` cannot be followed when it is a symbolic link that leads nowhere (its target
    is missing, or it loops back on itself), else None."""
    path = Path(path)
    if not path.is_symlink():
        return None
    try:
        path.stat()
    except FileNotFoundError:
        return f"a symbolic link to {os.readlink(path)}, which does not exist"
    except OSError as exc:  # ELOOP
        return f"a symbolic link that cannot be followed ({exc.strerror or exc})"
    return None


def check_file(path: str | Path, option: str = "") -> None:
    """Refuse `path` if it exists and is not a regular file (`not_a_file`).

    Args:
        path: The file about to be read.
        option: The option that named it, for the message (e.g. ``"--space"``).

    Raises:
        UserError: one line naming the file and what it is.
    """
    what = not_a_file(path)
    if what is not None:
        where = f"{option} {path}" if option else str(path)
        raise UserError(f"{where}: is {what}, not a regular file; give a file")


def locale_problem(text: str) -> str | None:
    """Why `text` (a path or an argument) cannot be used under this process's locale, or None.

    Under a C or POSIX locale with Python's UTF-8 mode off (``PYTHONUTF8=0``), file names are
    ASCII: the bytes of a non-ASCII name arrive as lone surrogates, which no file, Parquet or
    image library can write or open (a good dataset used to be called "unreadable"); under a
    UTF-8 locale, so do the bytes of a name that is not UTF-8 (e.g. Latin-1).
    """
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        shown = text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
        if sys.getfilesystemencoding().lower().replace("-", "") == "utf8":
            return f"{shown}: a name that is not valid UTF-8 text; rename it"
        env = os.environ
        locale = env.get("LC_ALL") or env.get("LC_CTYPE") or env.get("LANG") or "C"
        return (f"{shown}: not ASCII, and this process reads names as "
                f"{sys.getfilesystemencoding()} (locale {locale}, PYTHONUTF8 off); run with "
                "LC_ALL=C.UTF-8 (or PYTHONUTF8=1)")
    return None


def check_out_dir(path: str | Path, option: str = "--out") -> Path:
    """Check, before any work, that `path` can become (or is) an output folder.

    The folder may exist (its contents are each command's business) or not yet; its nearest
    existing parent must then be a writable folder.

    Returns:
        The absolute path.

    Raises:
        UserError: `path` (or a parent) is a file, or the folder cannot be written.
    """
    problem = locale_problem(str(path))
    if problem is not None:
        raise UserError(f"{option} {problem}")
    path = Path(path).expanduser().absolute()
    if path.exists() and not path.is_dir():
        raise UserError(f"{option} {path}: exists and is not a folder")
    existing = path
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise UserError(f"{option} {path}: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise UserError(f"{option} {path}: {existing} is not writable")
    return path


LABEL_TOLERANCE = 1e-3
"""Largest difference of a label's length from 1 (labels are written as float64 unit vectors)."""


def bad_label(labels: Any) -> tuple[int, str] | None:
    """The first row of `labels` that is not a finite unit vector per finger, and why; None
    when every row is one. Checked before a dataset is declared written or checked.

    Args:
        labels: A table (DataFrame, Arrow table or mapping) with the label columns.
    """
    columns = {c: np.asarray(labels[c], float) for c in LABEL_COLUMNS}
    for f in FINGERS:
        r_y, r_z = (columns[c] for c in label_columns(f))
        with np.errstate(all="ignore"):
            norms = np.hypot(r_y, r_z)
        bad = ~np.isfinite(norms) | (np.abs(norms - 1) > LABEL_TOLERANCE)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            what = ("not finite" if not np.isfinite(norms[i]) else
                    f"not a unit vector (length {norms[i]:.4g})")
            return i, f"({f}) label (r_y, r_z) = ({r_y[i]:.4g}, {r_z[i]:.4g}) is {what}"
    return None


def table_counts(split, object_id, presses: int) -> dict[str, Any]:
    """The manifest's counts of a dataset's tables: configurations, presses, splits, objects.

    Args:
        split, object_id: the configs table's columns (any array-like).
        presses: the number of rows of the presses table.
    """
    split = np.asarray(split)
    return {"configs": len(split), "presses": int(presses),
            "split": {s: int((split == s).sum()) for s in SPLITS},
            "objects": len(np.unique(np.asarray(object_id)))}


def versions(*modules: str) -> dict[str, str]:
    """The manifest's versions: vistac, each named module and Python."""
    import vistac

    return {"vistac": vistac.__version__,
            **{m: import_module(m).__version__ for m in modules},
            "python": platform.python_version()}
