"""The state of an unfinished `vistac generate` run: committed shards, resume, the final tables.

A dataset is complete only when `manifest.json` exists with ``"complete": true``; it is written
last, atomically, after `configs.parquet` and `presses.parquet`. While a run is in progress its
state lives in `.partial/` (the run's config and one committed shard per finished chunk), so an
interrupted run, even one killed with SIGKILL, can never pass for a complete dataset and can be
resumed from its finished shards.
"""

from __future__ import annotations

import os
import shutil
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from vistac.dataset import FORMAT_VERSION, MANIFEST, assign_splits
from vistac.dataset.card import write_card
from vistac.dataset.files import (
    atomic_write_json,
    bad_label,
    remove_stale_temporaries,
    table_counts,
    temporary_path,
    write_error,
    write_manifest,
    write_row_groups,
)
from vistac.dataset.recordings import recording_name
from vistac.dataset.schema import (
    CONFIGS,
    IMAGES,
    LABEL_COLUMNS,
    MASKS,
    PARTIAL,
    PRESSES,
    redraw_counts,
    with_declared_types,
)
from vistac.errors import UserError
from vistac_sim.generate.verify import damaged_files, read_run_state

SHARD = ".arrow"
"""Shards are Arrow IPC files: ~5x cheaper to write and read back than Parquet, and they only
live in `.partial/` until the final tables are written."""


def shard_paths(out: Path, chunk: int) -> tuple[Path, Path]:
    """(configs, presses) shard files of one chunk; the configs file is the commit marker."""
    d = out / PARTIAL / "shards"
    return d / f"chunk_{chunk:05d}.configs{SHARD}", d / f"chunk_{chunk:05d}.presses{SHARD}"


def write_shard(path: Path, rows: list[dict]) -> None:
    """Write one shard table from its rows, atomically (a temporary file, then a rename)."""
    table = with_declared_types(pa.Table.from_pylist(rows))
    tmp = temporary_path(path)
    try:
        with pa.OSFile(str(tmp), "wb") as fh, pa.ipc.new_file(fh, table.schema) as writer:
            writer.write_table(table)
        os.replace(tmp, path)
    except OSError as exc:  # a full disk: one line naming the file
        raise write_error(path, exc) from None
    finally:
        tmp.unlink(missing_ok=True)


def finished_chunks(out: Path) -> set[int]:
    """Chunks whose shard was committed (the configs file is written last) and reads back.

    A shard whose files do not read back (truncated, damaged) is deleted, so that its chunk is
    made again.
    """
    d = out / PARTIAL / "shards"
    if not d.is_dir():
        return set()
    done = set()
    for cpath in d.glob(f"chunk_*.configs{SHARD}"):
        chunk = int(cpath.name[6:11])
        if all(_readable(p) for p in shard_paths(out, chunk)):
            done.add(chunk)
        else:
            for p in shard_paths(out, chunk):
                p.unlink(missing_ok=True)
    return done


def _readable(path: Path) -> bool:
    try:
        with pa.OSFile(str(path)) as fh:
            pa.ipc.open_file(fh)  # reads the footer, which a truncated file lacks
    except (OSError, pa.ArrowException):
        return False
    return True


def start_run(out: Path, run_state: dict, resume: bool) -> set[int]:
    """Prepare `out` for a run and return the chunks already finished.

    With `resume`, what the interrupted run left is checked before it is trusted: its state
    file (`verify.read_run_state`), its shards (a shard that does not read back is made again)
    and the images and recordings of its committed chunks (a chunk with a missing or torn file
    is made again). Without `resume`, a folder whose run state is damaged (an interrupted run
    that cannot be resumed) is started over.

    Raises:
        UserError: `out` holds a complete dataset, holds something else, or (with resume) an
            interrupted run made with different settings or whose state file is damaged.
    """
    partial = out / PARTIAL
    state_file = partial / "run.json"
    if (out / MANIFEST).exists():
        raise UserError(f"{out}: already holds a complete dataset; choose another --out "
                        "(--resume checks it and does nothing)")
    if partial.is_dir() and not finished_chunks(out):  # stopped before its first shard
        _discard_run(out)
        resume = False
    if resume:
        if not partial.is_dir():
            raise UserError(f"{out}: nothing to resume (no interrupted run found there)")
        previous = read_run_state(state_file)
        if previous != run_state:
            diff = sorted(k for k in set(previous) | set(run_state)
                          if previous.get(k) != run_state.get(k))
            raise UserError(f"{out}: the interrupted run used other settings ({', '.join(diff)}); "
                            "resume with the same options or choose another --out")
        for folder in (partial / "shards", out / IMAGES, out / MASKS, out / "recordings"):
            if folder.is_dir():
                remove_stale_temporaries(folder)
        return checked_chunks(out, bool(run_state["config"]["recording"]["write"]),
                              bool(run_state["config"]["render"].get("masks")))
    if partial.is_dir() and _state_damaged(state_file):  # cannot be resumed: start over
        _discard_run(out)
    if out.exists() and any(out.iterdir()):
        hint = " (an interrupted run: add --resume)" if state_file.exists() else ""
        raise UserError(f"{out}: folder exists and is not empty{hint}")
    (partial / "shards").mkdir(parents=True, exist_ok=True)
    (out / IMAGES).mkdir(parents=True, exist_ok=True)
    atomic_write_json(state_file, run_state)
    return set()


def _discard_run(out: Path) -> None:
    """Remove what an interrupted run made: its state, images, masks, recordings, and the
    tables (and their temporaries) of a merge it was killed in."""
    shutil.rmtree(out / PARTIAL)
    for folder in (IMAGES, MASKS, "recordings"):
        shutil.rmtree(out / folder, ignore_errors=True)
    for table in (CONFIGS, PRESSES):
        (out / table).unlink(missing_ok=True)
    remove_stale_temporaries(out)


def _state_damaged(state_file: Path) -> bool:
    try:
        read_run_state(state_file)
    except UserError:
        return True
    return False


def checked_chunks(out: Path, recordings: bool, masks: bool = False) -> set[int]:
    """The finished chunks whose images (and, if the run writes them, `recordings`) are all
    present and whole; the shards of the others are deleted, so that they are made again
    (rewriting their files)."""
    done = set()
    for chunk in sorted(finished_chunks(out)):
        cpath = shard_paths(out, chunk)[0]
        try:
            with pa.OSFile(str(cpath)) as fh:
                table = pa.ipc.open_file(fh).read_all()
            images = table["image"].to_pylist()
            ids = table["config_id"].to_pylist()
        except (OSError, KeyError, pa.ArrowException):
            images, ids = None, []
        csvs = [recording_name(int(i)) for i in ids] if recordings else []
        if images is not None and not damaged_files(out, images, csvs, masks):
            done.add(chunk)
        else:
            for p in shard_paths(out, chunk):
                p.unlink(missing_ok=True)
    return done


MERGE_ROWS = 5_000
"""Configurations per row group of the final tables: the merge holds one such group at a time."""
MAX_BUCKETS = 256
"""At most this many buckets (two open spill files each) however large the run: past
MERGE_ROWS * MAX_BUCKETS configurations (1.28 M) the buckets grow instead, so that a huge run
cannot exhaust the open-file limit (often 1024) at its very end."""

_BOOKKEEPING = ["config_id", "object_id", "object_family", "redraw_reasons", "failed_objects"]
"""The configs columns the manifest's counts and per-object summary are made from."""


def _numpy_copy(column: pa.ChunkedArray) -> np.ndarray:
    """A column as a NumPy array that holds no Arrow buffer (nested cells as Python lists)."""
    if pa.types.is_nested(column.type):
        cells = np.empty(len(column), dtype=object)
        cells[:] = column.to_pylist()
        return cells
    return np.array(column.to_numpy(zero_copy_only=False))


def _read_shard(path: Path, schema: pa.Schema) -> pa.Table:
    """One shard's table, in `schema` (a column missing from the shard is null)."""
    with pa.OSFile(str(path)) as fh:
        table = pa.ipc.open_file(fh).read_all()
    if table.schema == schema:
        return table
    return pa.Table.from_arrays(
        [table[f.name].cast(f.type) if f.name in table.column_names
         else pa.nulls(len(table), f.type) for f in schema], schema=schema)


def _common_schema(paths: list[Path]) -> pa.Schema:
    """One schema for all shards (a column that is null in one shard takes the others' type)."""
    schemas = []
    for p in paths:
        with pa.OSFile(str(p)) as fh:
            schemas.append(pa.ipc.open_file(fh).schema)
    return pa.unify_schemas(schemas, promote_options="default")


class _Buckets:
    """Spill files that sort rows by configuration id range, `ids` ids per bucket."""

    def __init__(self, folder: Path, name: str, schema: pa.Schema, ids: int):
        self.folder, self.name, self.schema, self.ids = folder, name, schema, ids
        self.writers: dict[int, pa.ipc.RecordBatchStreamWriter] = {}

    def path(self, bucket: int) -> Path:
        return self.folder / f"{self.name}_{bucket:05d}.arrows"

    def add(self, table: pa.Table) -> None:
        bucket = table["config_id"].to_numpy() // self.ids
        for b in np.unique(bucket).tolist():
            if b not in self.writers:
                self.writers[b] = pa.ipc.new_stream(self.path(b), self.schema)
            self.writers[b].write_table(table.filter(pa.array(bucket == b)))

    def close(self) -> None:
        for w in self.writers.values():
            w.close()

    def sorted(self, keys: list[str]) -> Iterator[pa.Table]:
        """Each bucket in id order, its rows sorted by `keys`, the spill file removed after."""
        for b in sorted(self.writers):
            with pa.OSFile(str(self.path(b))) as src:
                table = pa.ipc.open_stream(src).read_all()
            yield table.sort_by([(k, "ascending") for k in keys])
            self.path(b).unlink()


def finalize(out: Path, n_chunks: int, n: int, manifest: dict, split_by: str, fractions,
             seed: int) -> dict:
    """Merge the shards of `n_chunks` chunks (`n` configurations) into the final tables, write
    the manifest last, remove `.partial/`.

    Memory stays flat in the run's size: shards are read one at a time and spilled into buckets
    of `MERGE_ROWS` configuration ids (Arrow stream files in `.partial/merge/`), then each bucket
    is sorted and written as one row group. Only the few columns the counts and the per-object
    summary need are held for the whole run.
    """
    paths = [shard_paths(out, c) for c in range(n_chunks)]
    schemas = [_common_schema([p[k] for p in paths]) for k in (0, 1)]
    spill = out / PARTIAL / "merge"
    shutil.rmtree(spill, ignore_errors=True)
    spill.mkdir(parents=True)
    ids = max(MERGE_ROWS, -(-n // MAX_BUCKETS))
    buckets = [_Buckets(spill, name, schema, ids) for name, schema in
               zip(("configs", "presses"), schemas, strict=True)]
    # Kept as NumPy copies: an Arrow column read from a shard holds the shard's whole buffer.
    kept: dict[str, list[np.ndarray]] = {c: [] for c in _BOOKKEEPING}
    pressed: list[np.ndarray] = []  # the presses' config ids
    try:
        for cpath, ppath in paths:
            configs = _read_shard(cpath, schemas[0])
            buckets[0].add(configs)
            for c in _BOOKKEEPING:
                kept[c].append(_numpy_copy(configs[c]))
            presses = _read_shard(ppath, schemas[1])
            buckets[1].add(presses)
            pressed.append(np.array(presses["config_id"].to_numpy()))
    finally:
        for b in buckets:
            b.close()
    press_config_ids = np.concatenate(pressed)
    cols = {k: np.concatenate(v) for k, v in kept.items()}
    order = np.argsort(cols["config_id"], kind="stable")
    cols = {k: v[order] for k, v in cols.items()}
    n_presses = len(press_config_ids)
    split_of = assign_splits(cols, split_by, fractions, seed)

    def labelled(tables: Iterator[pa.Table]) -> Iterator[pa.Table]:
        start = 0
        for table in tables:
            yield table.add_column(4, "split", pa.array(split_of[start:start + len(table)],
                                                        pa.string()))
            start += len(table)

    write_row_groups(out / CONFIGS, schemas[0].insert(4, pa.field("split", pa.string())),
                     labelled(buckets[0].sorted(["config_id"])))
    write_row_groups(out / PRESSES, schemas[1], buckets[1].sorted(["config_id", "repeat"]))
    bad = bad_label(pq.read_table(out / PRESSES, columns=LABEL_COLUMNS))
    if bad is not None:  # never declared written: no manifest
        raise UserError(f"{out / PRESSES}: row {bad[0]}: {bad[1]}; these settings give no "
                        "usable labels (e.g. a --noise far above the force): generate again "
                        "with other settings into another --out")
    counts = {**table_counts(split_of, cols["object_id"], n_presses),
              "families": dict(Counter(cols["object_family"].tolist()))}
    from vistac_sim.generate.objects_report import object_summary

    reasons: Counter = Counter()
    for cell in cols["redraw_reasons"]:
        reasons.update(redraw_counts(cell))

    per_object = object_summary(cols, press_config_ids,
                                manifest.get("objects", []),
                                manifest.get("skipped_meshes", [])
                                + manifest.get("skipped_objects", []),
                                manifest.get("mesh_repairs"))
    manifest = {**manifest, "format_version": FORMAT_VERSION, "complete": True, "counts": counts,
                "redraws": {"total": sum(reasons.values()),
                            "by_reason": dict(sorted(reasons.items()))},
                "per_object": per_object}
    write_card(out, manifest)
    write_manifest(out, manifest)
    shutil.rmtree(out / PARTIAL, ignore_errors=True)
    return manifest
