"""A run folder's own files, ``config.json`` and ``metrics.csv``: read checked, written safely.

A truncated, hand-edited or foreign file is one `UserError` naming the file, what is wrong and
what to do about it (the caller's `fix`), never a traceback. Checkpoints are read by
`vistac_learn.train.checkpoints.load_checkpoint`.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

from vistac.dataset.files import atomic_write_bytes, atomic_write_json, check_file
from vistac.errors import UserError

if TYPE_CHECKING:
    from vistac_learn.train.config import TrainCfg

CONFIG = "config.json"
METRICS = "metrics.csv"


def read_run_config(run: Path, fix: str) -> dict:
    """The parsed ``config.json`` of a run folder, with its ``train`` and ``dataset`` parts.

    Args:
        run: The run folder.
        fix: What the user can do about a damaged file (the end of the error's line).

    Raises:
        UserError: missing, unreadable, not JSON, or without the parts a run writes.
    """
    path = Path(run) / CONFIG
    check_file(path)
    try:
        meta = json.loads(path.read_bytes())
    except FileNotFoundError:
        raise UserError(f"{path}: missing (not a vistac run folder)") from None
    except OSError as exc:
        raise UserError(f"{path}: unreadable ({exc.strerror or exc}); {fix}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: not valid JSON ({exc}); {fix}") from None
    dataset = meta.get("dataset") if isinstance(meta, dict) else None
    if not isinstance(meta, dict) or not isinstance(meta.get("train"), dict) \
            or not isinstance(dataset, dict) \
            or not all(isinstance(dataset.get(k), str) for k in ("path", "fingerprint")):
        raise UserError(f"{path}: not a run's config (needs train settings and the dataset's "
                        f"path and fingerprint); {fix}")
    return meta


def run_settings(run: Path, meta: dict, fix: str) -> TrainCfg:
    """The `TrainCfg` of a run's parsed ``config.json`` (keys of other versions ignored).

    Raises:
        UserError: settings a run cannot have (a hand-edited file).
    """
    import dataclasses

    from vistac_learn.train.config import TrainCfg

    known = {f.name for f in dataclasses.fields(TrainCfg)}
    # a run written before the recipe had test-time augmentation was evaluated without it, and
    # one written before appearance augmentation (or its axis probability) trained without it
    settings = {"tta": False, "appearance": 0.0, "appearance_axes": 0.5, **meta["train"]}
    try:
        return TrainCfg(**{k: v for k, v in settings.items() if k in known})
    except (UserError, TypeError, ValueError) as exc:
        raise UserError(f"{Path(run) / CONFIG}: its train settings are not valid ({exc}); "
                        f"{fix}") from None


def read_metrics(path: Path, fix: str) -> list[dict[str, float]]:
    """The rows of a run's ``metrics.csv``, every value a number, epochs 1, 2, ... in order.

    Raises:
        UserError: missing, unreadable, a cut or edited row, epochs out of order.
    """
    try:
        with path.open(newline="") as fh:
            raw = list(csv.DictReader(fh))
    except FileNotFoundError:
        raise UserError(f"{path}: missing; {fix}") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise UserError(f"{path}: unreadable ({exc}); {fix}") from None
    rows = []
    for i, r in enumerate(raw):
        try:
            row = {k: float(v) for k, v in r.items()}
        except (TypeError, ValueError):  # a cut line (None) or text where a number belongs
            raise UserError(f"{path}: line {i + 2} is damaged (not a row of numbers); "
                            f"{fix}") from None
        if "epoch" not in row or row["epoch"] != i + 1 or not math.isfinite(row["epoch"]):
            raise UserError(f"{path}: line {i + 2}: epoch {row.get('epoch')} where {i + 1} "
                            f"belongs; {fix}")
        rows.append(row)
    return rows


def append_metrics(path: Path, rows: list[dict]) -> None:
    """Append rows to a run's ``metrics.csv`` (header written when the file is new)."""
    new = not path.exists() or path.stat().st_size == 0
    with path.open("a", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0].keys()))
        if new:
            w.writeheader()
        w.writerows(rows)


def restore_metrics(path: Path, history: list[dict]) -> None:
    """Make ``metrics.csv`` hold exactly a checkpoint's `history`: rows a kill kept from being
    appended are added, a cut or edited table is written again."""
    buf = io.StringIO(newline="")
    if history:
        w = csv.DictWriter(buf, fieldnames=list(history[0].keys()))
        w.writeheader()
        w.writerows(history)
    want = buf.getvalue().encode()
    if not path.exists() or path.read_bytes() != want:
        atomic_write_bytes(path, want)


def mark_diverged(run: Path, epoch: int, message: str) -> None:
    """Record in ``config.json`` that the run stopped on a diverging loss (a rerun into the
    folder then starts over)."""
    path = Path(run) / CONFIG
    meta = json.loads(path.read_text())
    atomic_write_json(path, meta | {"diverged": {"epoch": epoch, "message": message}})


def is_diverged(run: Path) -> bool:
    """Whether the run in `run` stopped on a diverging loss (`mark_diverged`)."""
    try:
        return bool(json.loads((Path(run) / CONFIG).read_text()).get("diverged"))
    except (OSError, ValueError, AttributeError):
        return False
