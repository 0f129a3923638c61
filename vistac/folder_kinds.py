"""What kind of folder a command is about to write into: a dataset, a run, a tuning, an
experiment or an evaluation, read from the files that kind writes first.

Each writing command checks its ``--out`` under its folder lock (`vistac.folder_lock.hold`),
before any write: a folder of another kind is refused, naming what it holds, and so is a folder
that is not empty and holds none of the project's folders (a user's own files), naming some of
them. A command then goes on with its own checks (a finished run, an interrupted dataset, other
settings), so ``--resume`` never turns one kind of folder into another.

The kind is read from what the folder holds, so folders written before this check are known
too; a damaged ``config.json`` does not hide a kind, since each kind has other files of its own.
An evaluation, whose files (``metrics.json``, ``predictions.parquet``) are common names, also
writes a marker, ``.vistac-kind`` (`mark`), before its first file; a user's own
``metrics.json`` is not an evaluation's unless it holds what an evaluation writes.
"""

from __future__ import annotations

import json
from pathlib import Path

from vistac.errors import UserError

DATASET, RUN, TUNING, EXPERIMENT, EVALUATION = (
    "dataset", "run", "tuning", "experiment", "evaluation")

KIND_OF_COMMAND = {"generate": DATASET, "ingest": DATASET, "train": RUN, "tune": TUNING,
                   "experiment": EXPERIMENT, "evaluate": EVALUATION}
"""The kind of folder each writing command makes (the names `hold` is given)."""

MARKER = ".vistac-kind"
"""The file that names its folder's kind (``evaluation``), where the files do not say it."""

_CONFIG_KEYS = ((EXPERIMENT, "experiment"), (TUNING, "tune"), (RUN, "train"))
"""A ``config.json`` key that only one kind writes, in the order they are looked for."""

_OWN_FILES = (
    (DATASET, ("manifest.json", ".partial", "configs.parquet", "presses.parquet")),
    (TUNING, ("trials.csv", "pending.json", "best.json", "trials")),
    (EXPERIMENT, ("cells.csv",)),
    (RUN, ("checkpoints",)),
)
"""Files (or folders) only one kind writes, for a folder whose ``config.json`` is missing or
damaged."""

_NOT_FOREIGN = {RUN: ("eval",)}
"""What a kind's folder may hold before its own files appear (an evaluation beside a run)."""


def folder_kind(folder: str | Path) -> tuple[str, str] | None:
    """The kind of project folder `folder` is, and the file that says so.

    Returns:
        ``(kind, evidence)``, e.g. ``("run", "config.json")``, or None: no such folder, an
        empty one, or one that holds none of the project's files.
    """
    folder = Path(folder)
    if not folder.is_dir():
        return None
    marked = _read_json(folder / MARKER, text=True)
    if marked in KIND_OF_COMMAND.values():
        return marked, MARKER
    saved = _read_json(folder / "config.json")
    if isinstance(saved, dict):
        for kind, key in _CONFIG_KEYS:
            if key in saved:
                return kind, "config.json"
    for kind, names in _OWN_FILES:
        for name in names:
            if (folder / name).exists():
                return kind, name
    scored = _read_json(folder / "metrics.json")
    if isinstance(scored, dict) and {"metrics", "table", "n_predictions"} <= set(scored):
        return EVALUATION, "metrics.json"
    return None


def mark(folder: Path, kind: str) -> None:
    """Create `folder` (if need be) and record its kind in it (`MARKER`)."""
    from vistac.dataset.files import atomic_write_bytes

    folder.mkdir(parents=True, exist_ok=True)
    if folder_kind(folder) != (kind, MARKER):
        atomic_write_bytes(folder / MARKER, f"{kind}\n".encode())


def _read_json(path: Path, text: bool = False):
    """The parsed JSON (or, with `text`, the stripped text) of a small regular file `path`, or
    None (missing, not a regular file, over 1 MiB, unreadable)."""
    try:
        if not path.is_file() or path.stat().st_size > 1 << 20:
            return None
        raw = path.read_bytes()
        return raw.decode().strip() if text else json.loads(raw)
    except (OSError, UnicodeDecodeError, ValueError):
        return None


def foreign_entries(folder: Path, kind: str) -> list[str]:
    """The names in `folder` that no command of the project wrote there (temporaries of a
    killed write excepted), sorted."""
    allowed = _NOT_FOREIGN.get(kind, ())
    try:
        names = [p.name for p in folder.iterdir()]
    except OSError:
        return []
    return sorted(n for n in names if n not in allowed and n != MARKER
                  and not (n.startswith(".") and n.endswith(".tmp")))


def check_kind(out: str | Path, kind: str, option: str = "--out") -> None:
    """Refuse `out` when it holds a folder of another kind than `kind`, or when it is not empty
    and holds none of the project's folders.

    Raises:
        UserError: one line naming the folder, what it holds and what to do.
    """
    out = Path(out)
    if not out.is_dir():
        return
    found = folder_kind(out)
    if found is not None:
        other, evidence = found
        if other != kind:
            raise UserError(f"{option} {out}: holds {_a(other)} ({evidence}), not {_a(kind)}; "
                            "choose another " + option)
        return
    foreign = foreign_entries(out, kind)
    if foreign:
        shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3
                                          else "")
        raise UserError(f"{option} {out}: a folder that is not empty and holds no {kind} (it "
                        f"holds {shown}); choose another {option} or empty it")


def _a(kind: str) -> str:
    return ("an " if kind[0] in "aeiou" else "a ") + kind
