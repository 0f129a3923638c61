"""`vistac ingest`: RH8D/FTS-3 recordings (or the study's label spreadsheets) + images -> dataset.

The study's tactile preprocessing (thesis.md, section 3), made automatic:

1. Read each recording CSV (one header line; force columns from a `ColumnMap`, contracts.md's
   layout by default; integer mN by default).
2. Split the series into grasps: a grasp starts where |index F_z| rises above `threshold` and
   ends where it falls back to or below it; empty segments cannot occur (each segment has at
   least one sample above the threshold).
3. Representative sample of a grasp: the first local extremum of index F_z that lies beyond the
   segment's mean index F_z (a trough when the mean is negative, a peak when it is positive).
   A run of equal samples counts as one value (quantised readings are often flat at the top); the
   sample is the run's first. The segment's first and last runs have no neighbour on one side
   and are never extrema.
4. The study's by-eye rejection is replaced by these criteria, checked in this order; the first
   that applies is the grasp's reason (`REASONS`):

   - ``too_short``: fewer than `min_samples` samples above the threshold (a knock or a glitch);
   - ``truncated``: the segment touches the first or last sample of the recording (the press
     began before or ended after the recording, so its peak may be missing);
   - ``saturated``: some force component of either finger reaches `saturation` in magnitude
     anywhere in the segment (the FTS-3 range ends at 10 N; the reading is clipped);
   - ``no_extremum``: no local extremum beyond the mean (e.g. a monotonic ramp);
   - ``below_resolution``: at the representative sample a finger's |(F_y, F_z)| is below
     `min_force` (its direction is not resolved: at 20 mN the 1 mN grid alone moves it up to
     ~3 degrees; the thumb may also simply not touch);
   - ``pulling``: at the representative sample a finger's F_z >= 0 (the surface can only push,
     F_z < 0 in contact; contracts.md). Off with `allow_pulling`.

5. Each kept grasp becomes a press: forces in N (sensor frame) and the unit labels
   r = (F_y, F_z)/|(F_y, F_z)| per finger. |(F_y, F_z)| = 0 cannot pass ``below_resolution``;
   the reduction itself maps it to (0, -1) (straight against the approach), as `generate` does.

Repeats are numbered by segment, rejected ones included (the k-th grasp of a recording is
``repeat`` k), so that ingested presses join generated ones on (`config_id`, `repeat`). A
configuration keeps the id its file names (``000123.csv`` <-> ``000123.png``: 123); when some
name is not a number, ids are 0..N-1 in name order and the name stays in the `recording` column.
Configurations without a kept grasp are left out (a dataset's configuration needs presses) and
listed in the manifest. Every rejected grasp is listed in ``rejected.csv`` (and counted by reason
in the manifest).

With ``--labels FILE.xlsx`` (the study's spreadsheets: one row per grasp, image name, r_y index,
r_z index, r_y thumb, r_z thumb): without recordings the spreadsheet's rows are the presses (no
forces); with recordings they are checked against the ingested labels per configuration (angle
between the mean directions, grasp counts) in the configuration table and the manifest.

Columns only simulation knows (``bbox_*``, ``force_clean_*``, ``normal_*``, ``camera_*``,
``px_per_m``) are NaN. The dataset is built in a hidden temporary folder next to ``--out`` and
renamed into place at the end, its manifest written last: an error or an interruption leaves no
half-written dataset behind.
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import json
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from vistac_sim import dataset
from vistac_sim.errors import UserError

FINGERS = ("index", "thumb")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
UNITS = {"mN": 1e-3, "N": 1.0}
REASONS = ("too_short", "truncated", "saturated", "no_extremum", "below_resolution", "pulling")
MAX_LISTED_ERRORS = 20


# ------------------------------------------------------------------------------ configuration
@dataclass(frozen=True)
class ColumnMap:
    """0-based CSV columns of each finger's F_x, F_y, F_z (contracts.md by default)."""

    thumb: tuple[int, int, int] = (14, 15, 16)
    index: tuple[int, int, int] = (17, 18, 19)

    def of(self, finger: str) -> tuple[int, int, int]:
        return getattr(self, finger)

    @property
    def needed(self) -> int:
        """Fields a row must have."""
        return max(*self.thumb, *self.index) + 1


@dataclass(frozen=True)
class IngestCfg:
    """The preprocessing and rejection knobs (forces in newtons, lengths in samples)."""

    columns: ColumnMap = field(default_factory=ColumnMap)
    unit: str = "mN"  # unit of the CSV's force cells (mN or N)
    threshold: float = 0.1  # N on |index F_z|: above it a grasp is in progress
    min_samples: int = 5  # a grasp needs at least this many samples above the threshold
    saturation: float = 9.9  # N; a component this large in magnitude counts as clipped
    min_force: float = 0.02  # N; smallest |(F_y, F_z)| of a finger whose direction is kept
    allow_pulling: bool = False  # keep grasps with F_z >= 0 at the representative sample


# ----------------------------------------------------------------------------- preprocessing
def split_grasps(fz_index: np.ndarray, threshold: float) -> np.ndarray:
    """(S, 2) [start, end) sample ranges where |index F_z| > threshold, in time order."""
    above = np.abs(np.asarray(fz_index, float)) > threshold
    edges = np.diff(np.r_[0, above.astype(np.int8), 0])
    return np.stack([np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)], axis=1)


def representative_sample(fz: np.ndarray) -> int | None:
    """Index into `fz` of its first local extremum beyond its mean, or None.

    A trough (value below the mean) when the mean is negative, a peak when it is positive; a run
    of equal values counts as one value and yields its first index; the first and last runs
    are never extrema.
    """
    fz = np.asarray(fz, float)
    mean = fz.mean()
    x = fz if mean >= 0 else -fz  # look for peaks of x above |mean|
    starts = np.r_[0, np.flatnonzero(np.diff(x) != 0) + 1]
    v = x[starts]
    inner = v[1:-1]
    hits = np.flatnonzero((inner > v[:-2]) & (inner > v[2:]) & (inner > abs(mean)))
    return int(starts[hits[0] + 1]) if len(hits) else None


def unit_vectors(forces: np.ndarray) -> np.ndarray:
    """(..., 2) unit (r_y, r_z) of forces (..., 3); |(F_y, F_z)| = 0 gives (0, -1).

    The same convention as `sample.unit_labels` (a test holds them equal); kept here so that
    ingesting does not import the simulator (MuJoCo, meshes).
    """
    yz = np.asarray(forces, float)[..., 1:]
    n = np.linalg.norm(yz, axis=-1, keepdims=True)
    return np.where(n > 0, yz / np.where(n > 0, n, 1.0), np.array([0.0, -1.0]))


@dataclass
class Grasp:
    """One segment of a recording and what became of it."""

    repeat: int
    start: int  # first sample (0-based data row)
    end: int  # one past the last sample
    sample: int | None = None  # representative sample (data row), if found
    reason: str | None = None  # None: kept
    detail: str = ""


def preprocess(forces: np.ndarray, cfg: IngestCfg) -> list[Grasp]:
    """Split one recording into grasps, pick each one's sample and apply the criteria.

    Args:
        forces: (T, 2, 3) series in N: sample, finger (index, thumb), sensor-frame xyz.
        cfg: thresholds and criteria.

    Returns:
        Every segment as a `Grasp`, `reason` None for the kept ones.
    """
    n = len(forces)
    out = []
    for k, (a, b) in enumerate(split_grasps(forces[:, 0, 2], cfg.threshold)):
        g = Grasp(k, int(a), int(b))
        out.append(g)
        if b - a < cfg.min_samples:
            g.reason, g.detail = "too_short", f"{b - a} samples < {cfg.min_samples}"
            continue
        if a == 0 or b == n:
            g.reason = "truncated"
            g.detail = "starts with the recording" if a == 0 else "ends with the recording"
            continue
        seg = forces[a:b]
        peak = np.abs(seg).max(axis=0)
        if (peak >= cfg.saturation).any():
            f, c = np.argwhere(peak >= cfg.saturation)[0]
            g.reason = "saturated"
            g.detail = f"{FINGERS[f]} F_{'xyz'[c]} reached {peak[f, c]:.3f} N"
            continue
        i = representative_sample(seg[:, 0, 2])
        if i is None:
            g.reason, g.detail = "no_extremum", "index F_z has no extremum beyond its mean"
            continue
        g.sample = a + i
        yz = np.linalg.norm(forces[g.sample, :, 1:], axis=-1)
        if (yz < cfg.min_force).any():
            f = int(np.argmax(yz < cfg.min_force))
            g.reason = "below_resolution"
            g.detail = f"{FINGERS[f]} |F_yz| = {yz[f]:.4f} N < {cfg.min_force} N"
            continue
        fz = forces[g.sample, :, 2]
        if not cfg.allow_pulling and (fz >= 0).any():
            f = int(np.argmax(fz >= 0))
            g.reason, g.detail = "pulling", f"{FINGERS[f]} F_z = {fz[f]:.4f} N >= 0"
    return out


# -------------------------------------------------------------------------------- reading
def data_line(row: int) -> int:
    """1-based file line of 0-based data row `row` (the header is line 1)."""
    return row + 2


def read_recording(path: Path, cfg: IngestCfg) -> np.ndarray:
    """(T, 2, 3) force series in N of one recording CSV.

    Raises:
        UserError: unreadable file, no header, too few fields, unparsable rows or non-numeric
            cells; the message names the file and line.
    """
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: unreadable ({exc})") from exc
    text = text.rstrip()
    if not text:
        raise UserError(f"{path}: line 1: empty file (expected a header line)")
    header = text.split("\n", 1)[0].rstrip("\r")
    need = cfg.columns.needed
    n_head = len(header.split(","))
    if n_head < need:
        raise UserError(f"{path}: line 1: missing columns: the header has {n_head} fields, the "
                        f"column map needs {need} (force columns {cfg.columns})")
    try:
        df = pd.read_csv(io.StringIO(text), header=0, dtype=str, keep_default_na=False,
                         skip_blank_lines=False)
    except pd.errors.ParserError as exc:
        raise UserError(f"{path}: unreadable row: {_parser_message(exc)}") from exc
    if len(df) == 0:
        raise UserError(f"{path}: line 2: no data rows after the header")
    lines = text.split("\n")[1:]
    fields = np.fromiter((line.count(",") + 1 for line in lines), int, len(lines))
    short = np.flatnonzero(fields < need)
    if len(short):
        r = int(short[0])
        what = "empty line" if not lines[r].strip() else f"only {fields[r]} fields"
        raise UserError(f"{path}: line {data_line(r)}: {what}, the column map needs {need} "
                        f"(missing field; {len(short)} short row(s) in all)")
    cols = [c for f in FINGERS for c in cfg.columns.of(f)]
    raw = df.iloc[:, cols]
    values = raw.apply(pd.to_numeric, errors="coerce").to_numpy(float)
    bad = ~np.isfinite(values)
    if bad.any():
        order = np.argsort(cols)  # report the leftmost bad cell of the first bad row
        r = int(np.flatnonzero(bad.any(axis=1))[0])
        c = int(order[np.flatnonzero(bad[r, order])[0]])
        raise UserError(f"{path}: line {data_line(r)}: non-numeric cell {raw.iat[r, c]!r} in "
                        f"column {cols[c]} ({bad.sum()} bad cell(s) in all)")
    return values.reshape(-1, 2, 3) * UNITS[cfg.unit]


def _parser_message(exc: Exception) -> str:
    """pandas' tokenizer message ("Expected 20 fields in line 7, saw 21") without its prefix."""
    text = str(exc).strip()
    return text.split(". C error: ")[-1] if "C error" in text else text


def read_label_sheet(path: Path, sheet: str | None = None) -> pd.DataFrame:
    """The study's label spreadsheet: columns image, row, r_y_index, r_z_index, r_y_thumb,
    r_z_thumb (`row` is the sheet's 1-based row). A first row whose label cells are not all
    numbers is a header.

    Raises:
        UserError: unreadable file, unknown sheet, rows with missing or non-numeric cells.
    """
    import openpyxl

    try:
        wb = openpyxl.load_workbook(path, read_only=True, data_only=True)
    except Exception as exc:  # openpyxl raises many types for a bad file
        raise UserError(f"{path}: not a readable xlsx file ({exc})") from exc
    try:
        if sheet is not None and sheet not in wb.sheetnames:
            raise UserError(f"{path}: no sheet {sheet!r} (sheets: {', '.join(wb.sheetnames)})")
        ws = wb[sheet] if sheet is not None else wb.worksheets[0]
        rows, errors, first = [], [], True
        for r, cells in enumerate(ws.iter_rows(values_only=True), start=1):
            cells = list(cells) + [None] * max(0, 5 - len(cells))
            if all(c is None or str(c).strip() == "" for c in cells):
                continue
            nums = [_number(c) for c in cells[1:5]]
            if first and any(v is None for v in nums):
                first = False  # a header row
                continue
            first = False
            name = "" if cells[0] is None else str(cells[0]).strip()
            if not name:
                errors.append(f"{path}: sheet {ws.title!r}, row {r}: no image name")
            elif any(v is None for v in nums):
                k = next(i for i, v in enumerate(nums) if v is None)
                errors.append(f"{path}: sheet {ws.title!r}, row {r}: non-numeric cell "
                              f"{cells[k + 1]!r} in column {'BCDE'[k]}")
            else:
                rows.append((name, r, *nums))
    finally:
        wb.close()
    _raise_all(errors)
    if not rows:
        raise UserError(f"{path}: no label rows")
    return pd.DataFrame(rows, columns=["image", "row", "r_y_index", "r_z_index", "r_y_thumb",
                                       "r_z_thumb"])


def _number(cell) -> float | None:
    if isinstance(cell, bool):
        return None
    if isinstance(cell, int | float):
        return float(cell) if np.isfinite(cell) else None
    try:
        v = float(str(cell).strip().replace(",", "."))
    except (TypeError, ValueError):
        return None
    return v if np.isfinite(v) else None


def _raise_all(errors: list[str]) -> None:
    if errors:
        more = len(errors) - MAX_LISTED_ERRORS
        listed = errors[:MAX_LISTED_ERRORS] + ([f"... and {more} more"] if more > 0 else [])
        raise UserError("\n  ".join([f"{len(errors)} problem(s):", *listed]))


# ------------------------------------------------------------------------------- matching
def _files(folder: Path, suffixes: tuple[str, ...], what: str) -> dict[str, Path]:
    """Files of `folder` with one of `suffixes`, by stem (two files of one stem: error)."""
    if not folder.is_dir():
        raise UserError(f"{folder}: no such {what} folder")
    out: dict[str, Path] = {}
    for p in sorted(folder.iterdir()):
        if p.is_file() and p.suffix.lower() in suffixes:
            if p.stem in out:
                raise UserError(f"{folder}: two {what} files for {p.stem!r}: {out[p.stem].name}, "
                                f"{p.name}")
            out[p.stem] = p
    if not out:
        raise UserError(f"{folder}: no {what} files ({', '.join(suffixes)})")
    return out


def config_ids(names: list[str]) -> dict[str, int]:
    """Configuration id of each name: the number it is, or 0..N-1 in name order."""
    if all(n.isdigit() for n in names):
        ids = {n: int(n) for n in names}
        seen: dict[int, str] = {}
        for n, i in ids.items():
            if i in seen:
                raise UserError(f"names {seen[i]!r} and {n!r} give the same configuration id {i}")
            seen[i] = n
        return ids
    return {n: i for i, n in enumerate(sorted(names))}


def _match(recordings: dict[str, Path], images: dict[str, Path], rec_dir: Path,
           img_dir: Path) -> list[str]:
    no_image = sorted(set(recordings) - set(images))
    no_rec = sorted(set(images) - set(recordings))
    errors = [f"{recordings[n]}: recording without an image in {img_dir}" for n in no_image]
    errors += [f"{images[n]}: image without a recording in {rec_dir}" for n in no_rec]
    _raise_all(errors)
    return sorted(recordings)


def read_objects_csv(path: Path, ids: dict[str, int]) -> dict[int, str]:
    """config_id -> object_id from a CSV with columns object_id and config_id or name.

    Raises:
        UserError: unreadable file, missing columns, unknown or missing configurations.
    """
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (OSError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: unreadable ({exc})") from exc
    key = "config_id" if "config_id" in df else "name" if "name" in df else None
    if key is None or "object_id" not in df:
        raise UserError(f"{path}: line 1: needs columns object_id and config_id (or name)")
    by_id = {str(i): i for i in ids.values()} if key == "config_id" else ids
    out, errors = {}, []
    for r, (k, obj) in enumerate(zip(df[key], df["object_id"], strict=True)):
        k = k.strip()
        if key == "config_id" and k.isdigit():
            k = str(int(k))
        if k not in by_id:
            errors.append(f"{path}: line {data_line(r)}: unknown {key} {k!r}")
        elif not obj.strip():
            errors.append(f"{path}: line {data_line(r)}: empty object_id")
        else:
            out[by_id[k]] = obj.strip()
    missing = sorted(set(ids.values()) - set(out))
    if missing:
        errors.append(f"{path}: no object_id for configuration(s) {missing[:10]}")
    _raise_all(errors)
    return out


# ------------------------------------------------------------------------------- the run
@dataclass
class IngestSources:
    """What to ingest and how to split it."""

    images: Path
    recordings: Path | None = None
    labels: Path | None = None
    labels_sheet: str | None = None
    objects_csv: Path | None = None
    split_by: str = "config"
    fractions: tuple[float, float, float] = (0.7, 0.15, 0.15)
    seed: int = 0
    image_size: int | None = None  # square crop + resize, as the study; None keeps images


def ingest(src: IngestSources, out: str | Path, cfg: IngestCfg = IngestCfg()) -> dict:
    """Build a dataset in `out` from recordings and/or a label spreadsheet plus images.

    Returns:
        The manifest.

    Raises:
        UserError: unusable inputs (every message names the file and line) or `out` in use.
    """
    t0 = time.perf_counter()
    out = Path(out)
    if cfg.unit not in UNITS:
        raise UserError(f"unit must be one of {', '.join(UNITS)}, not {cfg.unit!r}")
    if src.recordings is None and src.labels is None:
        raise UserError("give --recordings, --labels or both")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise UserError(f"{out}: exists and is not an empty folder; choose another --out")
    if src.split_by == "object" and src.objects_csv is None:
        raise UserError("--split-by object needs --objects-csv (object of each configuration)")
    images = _files(src.images, IMAGE_SUFFIXES, "image")
    sheet = read_label_sheet(src.labels, src.labels_sheet) if src.labels else None
    if src.recordings is not None:
        recordings = _files(src.recordings, (".csv",), "recording")
        names = _match(recordings, images, src.recordings, src.images)
    else:
        recordings = {}
        names = _sheet_names(sheet, images, src)
    ids = config_ids(names)
    objects = read_objects_csv(src.objects_csv, ids) if src.objects_csv else {}

    configs, presses, rejected, dropped = [], [], [], []
    errors: list[str] = []
    for name in names:
        cid = ids[name]
        row = {"config_id": cid, "object_id": objects.get(cid, "unknown"),
               "image": f"{name}.png", "recording": recordings[name].name if recordings else ""}
        if recordings:
            try:
                forces = read_recording(recordings[name], cfg)
            except UserError as exc:
                errors.append(str(exc))
                continue
            grasps = preprocess(forces, cfg)
            kept = [g for g in grasps if g.reason is None]
            for g in grasps:
                if g.reason is not None:
                    rejected.append({"source": recordings[name].name, "line": data_line(g.start),
                                     "end_line": data_line(g.end - 1), "config_id": cid,
                                     "repeat": g.repeat, "reason": g.reason,
                                     "detail": g.detail})
            presses += _presses_of(cid, kept, forces)
            row |= {"n_grasps": len(grasps), "n_kept": len(kept)}
        else:
            kept = sheet[sheet["stem"] == name]
            part, bad = _sheet_presses(cid, kept, src.labels)
            rejected += bad
            presses += part
            row |= {"n_grasps": len(kept), "n_kept": len(part)}
        if row["n_kept"] == 0:
            dropped.append({"config_id": cid, "name": name,
                            "reason": "no_grasp" if row["n_grasps"] == 0 else "no_usable_grasp"})
            continue
        configs.append(row)
    _raise_all(errors)
    if not configs:
        raise UserError("no configuration has a usable grasp (see the rejection criteria)")

    cfg_df = _with_sim_columns(pd.DataFrame(configs))
    prs_df = pd.DataFrame(presses).sort_values(["config_id", "repeat"]).reset_index(drop=True)
    check = _check_against_sheet(cfg_df, prs_df, sheet) if (sheet is not None and recordings) \
        else None
    cfg_df.insert(3, "split", dataset.assign_splits(cfg_df, src.split_by, src.fractions,
                                                    src.seed))
    tmp = out.parent / f".{out.name}.ingest-{os.getpid()}.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        (tmp / "images").mkdir(parents=True)
        sizes = [_copy_image(images[Path(n).stem], tmp / "images" / n, src.image_size)
                 for n in cfg_df["image"]]
        cfg_df["image_width"], cfg_df["image_height"] = zip(*sizes, strict=True)
        dataset.write_table(tmp / "configs.parquet", cfg_df)
        dataset.write_table(tmp / "presses.parquet", prs_df)
        rej_df = pd.DataFrame(rejected, columns=["source", "line", "end_line", "config_id",
                                                 "repeat", "reason", "detail"])
        dataset.atomic_write_bytes(tmp / "rejected.csv", rej_df.to_csv(index=False).encode())
        manifest = _manifest(src, cfg, cfg_df, prs_df, rej_df, dropped, check, t0)
        dataset.atomic_write_json(tmp / dataset.MANIFEST, manifest)  # last
        if out.exists():
            out.rmdir()  # checked empty above
        os.rename(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return manifest


def _presses_of(cid: int, kept: list[Grasp], forces: np.ndarray) -> list[dict]:
    rows = []
    for g in kept:
        f = forces[g.sample]
        r = unit_vectors(f)
        row = {"config_id": cid, "repeat": g.repeat}
        for k, fin in enumerate(FINGERS):
            row |= {f"force_{fin}_{c}": float(f[k, j]) for j, c in enumerate("xyz")}
        for k, fin in enumerate(FINGERS):
            row |= {f"r_y_{fin}": float(r[k, 0]), f"r_z_{fin}": float(r[k, 1])}
        row |= {"sample_line": data_line(g.sample), "start_line": data_line(g.start),
                "end_line": data_line(g.end - 1)}
        rows.append(row)
    return rows


def _sheet_names(sheet: pd.DataFrame, images: dict[str, Path], src: IngestSources) -> list[str]:
    sheet["stem"] = [Path(n).stem for n in sheet["image"]]
    errors = [f"{src.labels}: row {r}: image {n!r} not in {src.images}"
              for n, s, r in zip(sheet["image"], sheet["stem"], sheet["row"], strict=True)
              if s not in images]
    errors += [f"{p}: image without label rows in {src.labels}" for s, p in images.items()
               if s not in set(sheet["stem"])]
    _raise_all(errors)
    return sorted(images)


def _sheet_presses(cid: int, rows: pd.DataFrame, path: Path) -> tuple[list[dict], list[dict]]:
    """Presses from spreadsheet rows (renormalised); rows with a zero vector are rejected."""
    out, rejected = [], []
    for k, r in enumerate(rows.itertuples(index=False)):
        vec = np.array([[r.r_y_index, r.r_z_index], [r.r_y_thumb, r.r_z_thumb]], float)
        norm = np.linalg.norm(vec, axis=1)
        if (norm < 1e-9).any():
            f = FINGERS[int(np.argmax(norm < 1e-9))]
            rejected.append({"source": path.name, "line": int(r.row), "end_line": int(r.row),
                             "config_id": cid, "repeat": k, "reason": "zero_label",
                             "detail": f"{f} label is (0, 0) (the study's |F| = 0 guard)"})
            continue
        vec = vec / norm[:, None]
        row = {"config_id": cid, "repeat": k}
        row |= {f"force_{f}_{c}": float("nan") for f in FINGERS for c in "xyz"}
        row |= {f"r_{a}_{f}": float(vec[i, j]) for i, f in enumerate(FINGERS)
                for j, a in enumerate("yz")}
        row |= {"sample_line": int(r.row), "start_line": int(r.row), "end_line": int(r.row)}
        out.append(row)
    return out, rejected


def _check_against_sheet(cfg_df: pd.DataFrame, prs_df: pd.DataFrame,
                         sheet: pd.DataFrame) -> dict:
    """Per configuration: grasp counts and angle between mean label directions, recordings vs
    spreadsheet; adds columns `sheet_grasps`, `sheet_angle_index_deg`, `sheet_angle_thumb_deg`."""
    sheet = sheet.assign(stem=[Path(n).stem for n in sheet["image"]])
    stems = [Path(n).stem for n in cfg_df["image"]]
    counts = sheet.groupby("stem").size()
    cfg_df["sheet_grasps"] = [int(counts.get(s, 0)) for s in stems]
    summary = {"configs_compared": int((cfg_df["sheet_grasps"] > 0).sum()),
               "grasp_count_mismatch": int((cfg_df["sheet_grasps"] != cfg_df["n_kept"]).sum())}
    for f in FINGERS:
        cols = [f"r_y_{f}", f"r_z_{f}"]
        ours = prs_df.groupby("config_id")[cols].mean()
        theirs = sheet.groupby("stem")[cols].mean()
        ang = []
        for cid, s in zip(cfg_df["config_id"], stems, strict=True):
            if s not in theirs.index:
                ang.append(float("nan"))
                continue
            a, b = ours.loc[cid].to_numpy(), theirs.loc[s].to_numpy()
            ang.append(float(np.degrees(abs(np.arctan2(a[0] * b[1] - a[1] * b[0], a @ b)))))
        cfg_df[f"sheet_angle_{f}_deg"] = ang
        finite = np.array(ang)[np.isfinite(ang)]
        summary[f"median_angle_{f}_deg"] = float(np.median(finite)) if len(finite) else None
    return summary


def _with_sim_columns(df: pd.DataFrame) -> pd.DataFrame:
    """Add the columns only simulation knows, as NaN."""
    nan = float("nan")
    extra = {"camera_x": nan, "camera_y": nan, "px_per_m": nan}
    for f in FINGERS:
        extra |= {f"bbox_{f}_{c}": nan for c in "xywh"}
        extra |= {f"force_clean_{f}_{c}": nan for c in "xyz"}
        extra |= {f"normal_{f}_{c}": nan for c in "xyz"}
    return df.assign(**extra)


def _copy_image(src: Path, dst: Path, size: int | None) -> tuple[int, int]:
    """Copy an image as PNG (bytes unchanged for a PNG kept at its size); returns (w, h)."""
    import cv2

    bgr = cv2.imread(str(src), cv2.IMREAD_COLOR)
    if bgr is None:
        raise UserError(f"{src}: unreadable image")
    if size is None and src.suffix.lower() == ".png":
        shutil.copyfile(src, dst)
        return bgr.shape[1], bgr.shape[0]
    if size is not None:  # the study: crop square (centre), resize
        h, w = bgr.shape[:2]
        s = min(h, w)
        y0, x0 = (h - s) // 2, (w - s) // 2
        bgr = cv2.resize(bgr[y0:y0 + s, x0:x0 + s], (size, size), interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not ok:
        raise UserError(f"{src}: PNG encoding failed")
    dataset.atomic_write_bytes(dst, buf.tobytes())
    return bgr.shape[1], bgr.shape[0]


def _manifest(src: IngestSources, cfg: IngestCfg, cfg_df, prs_df, rej_df, dropped, check,
              t0: float) -> dict:
    import platform

    import vistac_sim

    by_reason = {k: int(v) for k, v in rej_df["reason"].value_counts().sort_index().items()}
    return {
        "generator": "vistac ingest",
        "format_version": dataset.FORMAT_VERSION,
        "complete": True,
        "config": {"ingest": _jsonable(dataclasses.asdict(cfg)),
                   "split": {"by": src.split_by, "fractions": list(src.fractions)}},
        "seed": src.seed,
        "sources": {k: (str(v) if isinstance(v, Path) else v)
                    for k, v in dataclasses.asdict(src).items()},
        "versions": {"vistac": vistac_sim.__version__, "numpy": np.__version__,
                     "pandas": pd.__version__, "python": platform.python_version()},
        "effects": [],
        "counts": {"configs": len(cfg_df), "presses": len(prs_df),
                   "split": {s: int((cfg_df["split"] == s).sum()) for s in dataset.SPLITS},
                   "objects": int(cfg_df["object_id"].nunique()),
                   "grasps": int(len(prs_df) + len(rej_df)),
                   "rejected": int(len(rej_df)), "dropped_configs": len(dropped)},
        "rejected": {"by_reason": by_reason, "file": "rejected.csv",
                     "criteria": list(REASONS)},
        "dropped_configs": dropped,
        "labels_check": check,
        "wall_time_s": round(time.perf_counter() - t0, 3),
    }


def _jsonable(value):
    return json.loads(json.dumps(value, default=list))


# ------------------------------------------------------------------------------------ CLI
def add_ingest_command(sub: argparse._SubParsersAction) -> None:
    """Add `vistac ingest` to the `vistac` parser."""
    d, c = IngestCfg(), ColumnMap()
    p = sub.add_parser(
        "ingest",
        help="turn RH8D/FTS-3 recordings (or label spreadsheets) + images into a dataset",
        description="Split each recording into grasps at a threshold on |index F_z|, take each "
        "grasp's first extremum beyond its mean, reject unusable grasps by documented criteria "
        "(rejected.csv), and write the standard dataset layout. Recording NNN.csv belongs to "
        "image NNN.png (any image type) and keeps configuration id NNN.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    p.add_argument("--recordings", type=Path, help="folder of recording CSVs")
    p.add_argument("--images", type=Path, required=True, help="folder of the images")
    p.add_argument("--out", type=Path, required=True, help="dataset folder to create")
    p.add_argument("--labels", type=Path, help="the study's label spreadsheet (xlsx): the "
                   "presses without --recordings, a check of them with it")
    p.add_argument("--labels-sheet", help="sheet of --labels (None: the first)")
    p.add_argument("--threshold", type=float, default=d.threshold,
                   help="N on |index F_z| that starts and ends a grasp")
    p.add_argument("--unit", choices=tuple(UNITS), default=d.unit,
                   help="unit of the CSV force cells")
    p.add_argument("--columns", type=int, nargs=6, default=[*c.thumb, *c.index],
                   metavar=("THUMB_X", "THUMB_Y", "THUMB_Z", "INDEX_X", "INDEX_Y", "INDEX_Z"),
                   help="0-based CSV columns of the forces")
    p.add_argument("--min-samples", type=int, default=d.min_samples,
                   help="shortest grasp kept, samples above the threshold")
    p.add_argument("--saturation", type=float, default=d.saturation,
                   help="N; a grasp with a force component this large is rejected as clipped")
    p.add_argument("--min-force", type=float, default=d.min_force,
                   help="N; smallest |(F_y, F_z)| of a finger whose direction is kept")
    p.add_argument("--allow-pulling", action="store_true",
                   help="keep grasps with F_z >= 0 at the representative sample")
    p.add_argument("--objects-csv", type=Path,
                   help="CSV with object_id and config_id (or name) per configuration")
    p.add_argument("--split-by", choices=("config", "object"), default="config")
    p.add_argument("--split", type=float, nargs=3, default=[0.7, 0.15, 0.15],
                   metavar=("TRAIN", "VAL", "TEST"), help="split fractions")
    p.add_argument("--seed", type=int, default=0, help="seed of the split")
    p.add_argument("--image-size", type=int, default=None,
                   help="crop images square (centre) and resize to this size (default: keep)")
    p.set_defaults(func=_run_ingest)


def _run_ingest(args: argparse.Namespace) -> int:
    if args.min_samples < 1 or args.threshold < 0 or args.min_force < 0:
        raise UserError("--min-samples must be >= 1; --threshold and --min-force >= 0")
    cfg = IngestCfg(columns=ColumnMap(tuple(args.columns[:3]), tuple(args.columns[3:])),
                    unit=args.unit, threshold=args.threshold, min_samples=args.min_samples,
                    saturation=args.saturation, min_force=args.min_force,
                    allow_pulling=args.allow_pulling)
    src = IngestSources(images=args.images, recordings=args.recordings, labels=args.labels,
                        labels_sheet=args.labels_sheet, objects_csv=args.objects_csv,
                        split_by=args.split_by, fractions=tuple(args.split), seed=args.seed,
                        image_size=args.image_size)
    manifest = ingest(src, args.out, cfg)
    print(f"wrote {args.out}: " + json.dumps({"counts": manifest["counts"],
                                              "rejected": manifest["rejected"]["by_reason"]}))
    return 0
