"""What `vistac generate --resume` checks before it trusts a folder: the run state, the images
and recordings of committed chunks, and a complete dataset's tables and files.

Images are written in place and only count once their chunk's shard is committed, but a crash of
the machine (not of the process) can still leave a committed image short or zero-filled, and a
user can delete one. A file is checked by its structure, not decoded: a PNG must start with its
signature and IHDR chunk and end with its IEND chunk; a recording must end with a newline.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from vistac.dataset.files import bad_label, not_a_file
from vistac.dataset.recordings import recording_name
from vistac.dataset.schema import CONFIGS, IMAGES, LABEL_COLUMNS, MANIFEST, MASKS, PRESSES
from vistac.errors import UserError

PNG_HEAD = b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR"
PNG_TAIL = b"\x00\x00\x00\x00IEND\xaeB`\x82"


def damaged_png(path: Path) -> str | None:
    """Why the PNG at `path` cannot be read back (missing, empty, torn, not a file), or None
    if whole."""
    if not_a_file(path):
        return f"{not_a_file(path)}, not a file"
    try:
        with open(path, "rb") as fh:
            head = fh.read(len(PNG_HEAD))
            size = fh.seek(0, 2)
            if size < len(PNG_HEAD) + len(PNG_TAIL):
                return "truncated" if size else "empty"
            fh.seek(size - len(PNG_TAIL))
            tail = fh.read()
    except FileNotFoundError:
        return "missing"
    except OSError as exc:
        return f"unreadable ({exc.strerror or exc})"
    if head != PNG_HEAD:
        return "not a PNG"
    if tail != PNG_TAIL:
        return "truncated"
    return None


def damaged_recording(path: Path) -> str | None:
    """Why the recording CSV at `path` cannot be read back, or None if whole."""
    if not_a_file(path):
        return f"{not_a_file(path)}, not a file"
    try:
        with open(path, "rb") as fh:
            size = fh.seek(0, 2)
            if size == 0:
                return "empty"
            fh.seek(size - 1)
            last = fh.read(1)
    except FileNotFoundError:
        return "missing"
    except OSError as exc:
        return f"unreadable ({exc.strerror or exc})"
    return None if last == b"\n" else "truncated"


def damaged_files(out: Path, images: list[str], recordings: list[str],
                  masks: bool = False) -> list[tuple[Path, str]]:
    """(file, why) of each damaged image (names under images/), mask (the same names under
    masks/, if the run writes them) and recording (under recordings/) of a dataset `out`."""
    folders = (IMAGES, MASKS) if masks else (IMAGES,)
    bad = [(out / f / n, damaged_png(out / f / n)) for f in folders for n in images]
    bad += [(out / "recordings" / n, damaged_recording(out / "recordings" / n))
            for n in recordings]
    return [(p, why) for p, why in bad if why is not None]


def read_run_state(path: Path) -> dict[str, Any]:
    """The `.partial/run.json` of an interrupted run.

    Raises:
        UserError: missing, not JSON or not a table, naming the file and what to do.
    """
    what_to_do = "this run cannot be resumed: rerun without --resume to start it over"
    try:
        state = json.loads(path.read_text())
    except FileNotFoundError:
        raise UserError(f"{path}: missing; {what_to_do}") from None
    except (OSError, ValueError) as exc:  # ValueError: bad JSON or bad UTF-8
        raise UserError(f"{path}: damaged ({type(exc).__name__}); {what_to_do}") from None
    if not isinstance(state, dict):
        raise UserError(f"{path}: damaged (not a table of settings); {what_to_do}")
    return state


def check_complete(out: Path, config: dict[str, Any]) -> dict[str, Any]:
    """The manifest of the complete dataset in `out` made with `config`, once its tables read
    back and every image (and recording) they list is whole.

    Raises:
        UserError: a damaged manifest or table, another config, or a damaged file, each named
            with what to do.
    """
    path = out / MANIFEST
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise UserError(f"{path}: damaged ({type(exc).__name__}); delete {out} and generate "
                        "again") from None
    if not isinstance(manifest, dict) or manifest.get("complete") is not True:
        raise UserError(f"{path}: not the manifest of a complete dataset; delete {out} and "
                        "generate again")
    made = manifest.get("config")
    if made != config:
        keys = sorted(k for k in set(made or {}) | set(config)
                      if (made or {}).get(k) != config.get(k))
        raise UserError(f"{out}: holds a complete dataset made with other settings "
                        f"({', '.join(keys) or 'config'}); choose another --out")
    try:
        names = pq.read_table(out / CONFIGS, columns=["config_id", "image"])
        labels = pq.read_table(out / PRESSES, columns=LABEL_COLUMNS)
    except (OSError, pa.ArrowException) as exc:
        raise UserError(f"{out}: a table does not read back ({' '.join(str(exc).split())}); "
                        f"delete {out} and generate again") from None
    bad = bad_label(labels)
    if bad is not None:
        raise UserError(f"{out / PRESSES}: row {bad[0]}: {bad[1]}; the dataset in {out} is not "
                        "usable: delete it and generate again")
    images = names["image"].to_pylist()
    recordings = ([recording_name(int(i)) for i in names["config_id"].to_pylist()]
                  if (config.get("recording") or {}).get("write") else [])
    bad = damaged_files(out, images, recordings, bool((config.get("render") or {}).get("masks")))
    if bad:
        (p, why), more = bad[0], len(bad) - 1
        also = f" (and {more} more file(s))" if more else ""
        raise UserError(f"{p}: {why}{also}; the dataset in {out} is not complete: delete it "
                        "and generate again")
    return manifest
