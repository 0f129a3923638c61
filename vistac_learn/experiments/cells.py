"""The resumable grid of training jobs behind every experiment: `Cell` and `run_cells`.

An experiment is a list of cells; each cell is one training job (`JobCfg`, run by
`vistac_learn.train.job.run_job` through a runner, so that the jobs can be Ray tasks) and turns
into one row of ``cells.csv``. Cells come in phases: a cell of phase 1 may start from a run of
phase 0 (a fine-tuned model from its pretrained one), so phase 0 finishes first.

Experiment folder (``--out X``):

- ``config.json``: the experiment's settings and the base training config; a rerun with other
  settings is refused (naming what differs) instead of mixing two experiments.
- ``cells.csv``: one row per finished cell (written atomically after each cell, in a fixed cell
  order); a row never changes once written. A rerun of the same command skips these cells.
- ``runs/...``: each cell's run folder; a cell a kill interrupted continues its run
  (``resume="auto"``) from its last checkpoint.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from vistac.config import to_dict
from vistac.dataset.files import atomic_write_bytes, atomic_write_json
from vistac.errors import UserError
from vistac.progress import bar as progress_bar
from vistac_learn.train.job import JobCfg, JobResult, LocalJobRunner
from vistac_learn.train.loop import TrainingDiverged

CELLS = "cells.csv"
CONFIG = "config.json"
STATUS_COLUMNS = ("status", "best_epoch", "seconds", "run")


@dataclass(frozen=True)
class Cell:
    """One training job of an experiment.

    Attributes:
        key: Unique name of the cell (e.g. ``finetune/0.33/1``).
        fields: Its identity columns in ``cells.csv`` (e.g. arm, fraction, seed).
        job: The training job.
        phase: Cells of a phase start after every cell of the phases before has finished.
        needs: Key of a cell of an earlier phase whose run this one starts from; when that
            cell did not finish ``ok`` (its loss diverged), this one is not trained: its row
            says ``skipped``.
    """

    key: str
    fields: dict[str, Any]
    job: JobCfg
    phase: int = 0
    needs: str | None = None


def open_experiment(cfg: Any, base: Any, kind: str) -> Path:
    """Check (or create) the experiment folder ``cfg.out`` for these settings; return it.

    Args:
        cfg: The experiment's config (its ``out`` is the folder).
        base: The runs' training settings (their data and out are set per cell).
    """
    meta = {"experiment": kind,
            "settings": {k: v for k, v in to_dict(cfg).items() if k != "out"},
            "train": {k: v for k, v in to_dict(base).items() if k not in ("data", "out")}}
    out = Path(cfg.out)
    check_folder(out, meta, kind)
    return out


def check_folder(out: Path, meta: dict[str, Any], kind: str) -> None:
    """Refuse an --out that holds another experiment, or other files; then record `meta`.

    Raises:
        UserError: naming the folder and the settings that differ.
    """
    path = out / CONFIG
    saved = _read_config(path) if path.exists() else None
    if path.exists() and saved is None:  # damaged: recorded again from these settings (each
        atomic_write_json(path, meta)  # cell's run checks its own settings when it continues)
        return
    if saved is not None:
        if saved.get("experiment") != kind:
            raise UserError(f"--out {out}: holds a {saved.get('experiment')} experiment, not "
                            f"{kind}; choose another --out")
        diff = _differences(saved, json.loads(json.dumps(meta)))
        if diff:
            raise UserError(f"--out {out}: holds this experiment with other settings "
                            f"({', '.join(diff)}); rerun with the same options to continue it, "
                            "or choose another --out")
        return
    if out.exists() and any(out.iterdir()):
        raise UserError(f"--out {out}: a folder that is not empty and holds no experiment; "
                        "choose another")
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(path, meta)


def _read_config(path: Path) -> dict | None:
    """An experiment's parsed ``config.json``, or None when it is damaged."""
    try:
        saved = json.loads(path.read_bytes())
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    return saved if isinstance(saved, dict) else None


def _differences(saved: dict, meta: dict, prefix: str = "") -> list[str]:
    out = []
    for k in sorted(set(saved) | set(meta)):
        a, b = saved.get(k), meta.get(k)
        if isinstance(a, dict) and isinstance(b, dict):
            out += _differences(a, b, f"{prefix}{k}.")
        elif a != b:
            out.append(f"{prefix}{k}")
    return out


def read_rows(path: Path) -> list[dict[str, Any]]:
    """The rows of a ``cells.csv`` (numbers as floats or ints, other values as strings).

    A damaged row (cut short, extra fields, an unknown status) or file is left out: its cell
    runs again, continuing its run folder, and records what it recorded before.
    """
    if not path.exists():
        return []
    try:
        with path.open(newline="") as fh:
            raw = list(csv.DictReader(fh))
    except (OSError, UnicodeDecodeError, csv.Error):
        return []
    return [{k: _parse(v) for k, v in r.items()} for r in raw
            if None not in r and None not in r.values() and r.get("cell")
            and r.get("status") in ("ok", "diverged", "skipped")]


def _parse(v: str) -> Any:
    for kind in (int, float):
        try:
            return kind(v)
        except ValueError:
            pass
    return v


def write_rows(path: Path, rows: list[dict[str, Any]], columns: Sequence[str]) -> None:
    """Write rows (in the given order) atomically as CSV."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    atomic_write_bytes(path, buf.getvalue().encode())


def run_cells(out: Path, cells: Sequence[Cell], columns: Sequence[str],
              measure: Callable[[Cell, JobResult], dict[str, float]],
              on_rows: Callable[[list[dict[str, Any]]], None],
              runner: Any = None, max_cells: int | None = None,
              progress: bool = True) -> list[dict[str, Any]]:
    """Run the cells not yet in ``out/cells.csv`` (phase by phase); return every row.

    Args:
        out: The experiment folder (checked with `check_folder` before).
        cells: Every cell of the experiment, in the order of ``cells.csv``.
        columns: The measured columns (``measure``'s keys), after the identity columns.
        measure: A finished cell's measured values from its job's result.
        on_rows: Called with the finished rows after each cell (writes the summary, report and
            plots).
        runner: Runs job configs (``run(items)`` yields (position, result)); default
            `LocalJobRunner`. A job whose loss diverged is a row with status ``diverged``.
        max_cells: Stop after this many new cells (a rerun continues).
        progress: Show a progress bar of cells.

    Returns:
        The finished rows, in cell order.
    """
    runner = runner or LocalJobRunner()
    path = out / CELLS
    order = {c.key: i for i, c in enumerate(cells)}
    rows = {r["cell"]: r for r in read_rows(path) if r.get("cell") in order}
    header = ["cell", *cells[0].fields, *columns, *STATUS_COLUMNS] if cells else []

    def ordered() -> list[dict[str, Any]]:
        return sorted(rows.values(), key=lambda r: order[r["cell"]])

    todo = [c for c in cells if c.key not in rows]
    if max_cells is not None:
        todo = todo[:max_cells]
    bar = progress_bar(total=len(cells), initial=len(rows), desc="cells", unit="cell",
                       enabled=progress, lines="each")
    if rows:
        on_rows(ordered())
    for phase in sorted({c.phase for c in todo}):
        batch = []
        for c in (c for c in todo if c.phase == phase):
            if c.needs in rows and rows[c.needs]["status"] != "ok":
                rows[c.key] = {"cell": c.key, **c.fields, **dict.fromkeys(columns, math.nan),
                               "status": "skipped", "best_epoch": 0, "seconds": 0.0,
                               "run": ""}
                write_rows(path, ordered(), header)
                bar.update(1)
            else:
                batch.append(c)

        def jobs(batch=batch) -> Iterator[JobCfg]:
            for c in batch:
                bar.set_postfix_str(c.key)
                yield c.job

        for position, result in runner.run(jobs()):
            cell = batch[position]
            rows[cell.key] = _row(cell, columns, measure, result)
            write_rows(path, ordered(), header)
            on_rows(ordered())
            bar.update(1)
    bar.close()
    return ordered()


def _row(cell: Cell, columns: Sequence[str], measure, result) -> dict[str, Any]:
    row = {"cell": cell.key, **cell.fields}
    if isinstance(result, TrainingDiverged):
        return row | dict.fromkeys(columns, math.nan) | {
            "status": "diverged", "best_epoch": 0, "seconds": 0.0, "run": cell.job.train.out}
    return row | measure(cell, result) | {
        "status": "ok", "best_epoch": result.best_epoch, "seconds": round(result.seconds, 2),
        "run": result.run}


def mean_std(values: Sequence[float]) -> tuple[float, float, int]:
    """(mean, sample std (0 for one value), count) of the finite values; NaN when none."""
    v = np.asarray([x for x in values if isinstance(x, int | float) and math.isfinite(x)])
    if len(v) == 0:
        return math.nan, math.nan, 0
    return float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else 0.0, len(v)


def summarise(rows: list[dict[str, Any]], by: Sequence[str],
              metrics: Sequence[str]) -> list[dict[str, Any]]:
    """Mean and std over seeds of each metric, per group of the `by` columns (first-seen order).

    Returns:
        One dict per group: the `by` values, ``n`` (finished seeds), ``<metric>_mean`` and
        ``<metric>_std``.
    """
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault(tuple(r[k] for k in by), []).append(r)
    out = []
    for key, members in groups.items():
        s = dict(zip(by, key, strict=True))
        s["n"] = sum(1 for m in members if m["status"] == "ok")
        for m in metrics:
            mean, std, _ = mean_std([x[m] for x in members])
            s[f"{m}_mean"], s[f"{m}_std"] = mean, std
        out.append(s)
    return out


def pm(mean: float, std: float, digits: int = 1) -> str:
    """``mean +- std`` for a report table (``-`` when not measured)."""
    if not math.isfinite(mean):
        return "-"
    return f"{mean:.{digits}f} ± {std:.{digits}f}"
