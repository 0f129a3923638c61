"""`vistac ingest` itself: recordings and/or a label spreadsheet plus images -> a dataset."""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import numpy as np
import pandas as pd

from vistac.config import to_dict
from vistac.dataset import (
    FINGERS,
    FORMAT_VERSION,
    assign_splits,
    files,
    press_row,
    unit_labels,
)
from vistac.dataset.card import write_card
from vistac.dataset.ingest.config import IngestCfg, IngestSources
from vistac.dataset.ingest.preprocess import REASONS, RecordedGrasp, preprocess
from vistac.dataset.ingest.readers import (
    IMAGE_SUFFIXES,
    config_ids,
    data_line,
    files_by_stem,
    match_names,
    raise_all,
    read_label_sheet,
    read_objects_csv,
    read_recording,
)
from vistac.dataset.schema import (
    CONFIGS,
    IMAGES,
    PRESSES,
    box_columns,
    clean_force_columns,
    label_columns,
    normal_columns,
)
from vistac.errors import UserError
from vistac.folder_lock import hold


def ingest(src: IngestSources, out: str | Path, cfg: IngestCfg | None = None) -> dict:
    """Build a dataset in `out` from recordings and/or a label spreadsheet plus images.

    Returns:
        The manifest.

    Raises:
        UserError: unusable inputs (every message names the file and line) or `out` in use
            (not empty, or held by another process).
    """
    with hold(out, "ingest"):
        return _ingest(src, out, cfg)


def _ingest(src: IngestSources, out: str | Path, cfg: IngestCfg | None) -> dict:
    t0 = time.perf_counter()
    out, cfg = Path(out), cfg or IngestCfg()
    if src.recordings is None and src.labels is None:
        raise UserError("give --recordings, --labels or both")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise UserError(f"{out}: exists and is not an empty folder; choose another --out")
    if src.split.by == "object" and src.objects_csv is None:
        raise UserError("--split-by object needs --objects-csv (object of each configuration)")
    images = files_by_stem(src.images, IMAGE_SUFFIXES, "image")
    sheet = read_label_sheet(src.labels, src.labels_sheet) if src.labels else None
    if src.recordings is not None:
        recordings = files_by_stem(src.recordings, (".csv",), "recording")
        names = match_names(recordings, images, src.recordings, src.images)
    else:
        recordings = {}
        names = _sheet_names(sheet, images, src)
    if src.image_size is None:
        check_image_sizes([images[n] for n in names])
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
    raise_all(errors)
    if not configs:
        raise UserError("no configuration has a usable grasp (see the rejection criteria)")

    cfg_df = _with_sim_columns(pd.DataFrame(configs))
    prs_df = pd.DataFrame(presses).sort_values(["config_id", "repeat"]).reset_index(drop=True)
    check = _check_against_sheet(cfg_df, prs_df, sheet) if (sheet is not None and recordings) \
        else None
    cfg_df.insert(3, "split", assign_splits(cfg_df, src.split.by, src.split.fractions,
                                            src.seed))
    tmp = out.parent / f".{out.name}.ingest-{os.getpid()}.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        (tmp / IMAGES).mkdir(parents=True)
        sizes = [_copy_image(images[Path(n).stem], tmp / IMAGES / n, src.image_size)
                 for n in cfg_df["image"]]
        cfg_df["image_width"], cfg_df["image_height"] = zip(*sizes, strict=True)
        files.write_table(tmp / CONFIGS, cfg_df)
        files.write_table(tmp / PRESSES, prs_df)
        rej_df = pd.DataFrame(rejected, columns=["source", "line", "end_line", "config_id",
                                                 "repeat", "reason", "detail"])
        files.atomic_write_bytes(tmp / "rejected.csv", rej_df.to_csv(index=False).encode())
        manifest = _manifest(src, cfg, cfg_df, prs_df, rej_df, dropped, check, t0)
        write_card(tmp, manifest)
        files.write_manifest(tmp, manifest)  # last
        if out.exists():
            out.rmdir()  # checked empty above
        os.rename(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return manifest


def check_image_sizes(paths: list[Path]) -> None:
    """Refuse images of different sizes (without --image-size), naming the first odd one.

    Raises:
        UserError: an unreadable image, or one whose size differs from the first's.
    """
    from PIL import Image, UnidentifiedImageError

    first = None
    for path in paths:
        try:
            with Image.open(path) as im:
                size = im.size
        except (OSError, UnidentifiedImageError):
            raise UserError(f"{path}: unreadable image") from None
        if first is None:
            first = (path, size)
        elif size != first[1]:
            raise UserError(f"{path}: {size[0]} x {size[1]} pixels, but {first[0].name} is "
                            f"{first[1][0]} x {first[1][1]}; images must share one size (or "
                            "pass --image-size N to crop and resize them all)")


def _presses_of(cid: int, kept: list[RecordedGrasp], forces: np.ndarray) -> list[dict]:
    rows = []
    for g in kept:
        f = forces[g.sample]
        row = press_row(cid, g.repeat, f, unit_labels(f))
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
    raise_all(errors)
    return sorted(images)


def _sheet_presses(cid: int, rows: pd.DataFrame, path: Path) -> tuple[list[dict], list[dict]]:
    """Presses from spreadsheet rows (renormalised); rows with a zero vector are rejected."""
    out, rejected = [], []
    for k, r in enumerate(rows.itertuples(index=False)):
        vec = np.array([[getattr(r, c) for c in label_columns(f)] for f in FINGERS], float)
        norm = np.linalg.norm(vec, axis=1)
        if (norm < 1e-9).any():
            f = FINGERS[int(np.argmax(norm < 1e-9))]
            rejected.append({"source": path.name, "line": int(r.row), "end_line": int(r.row),
                             "config_id": cid, "repeat": k, "reason": "zero_label",
                             "detail": f"{f} label is (0, 0) (the study's |F| = 0 guard)"})
            continue
        row = press_row(cid, k, np.full((2, 3), np.nan), vec / norm[:, None])
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
        cols = label_columns(f)
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
        for cols in (box_columns(f), clean_force_columns(f), normal_columns(f)):
            extra |= dict.fromkeys(cols, nan)
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
    files.atomic_write_bytes(dst, buf.tobytes())
    return bgr.shape[1], bgr.shape[0]


def _manifest(src: IngestSources, cfg: IngestCfg, cfg_df, prs_df, rej_df, dropped, check,
              t0: float) -> dict:
    by_reason = {k: int(v) for k, v in rej_df["reason"].value_counts().sort_index().items()}
    sources = {"images": src.images, "recordings": src.recordings, "labels": src.labels,
               "labels_sheet": src.labels_sheet, "objects_csv": src.objects_csv,
               "split_by": src.split.by, "fractions": list(src.split.fractions),
               "seed": src.seed, "image_size": src.image_size}
    return {
        "generator": "vistac ingest",
        "format_version": FORMAT_VERSION,
        "complete": True,
        "config": {"ingest": to_dict(cfg), "split": to_dict(src.split)},
        "seed": src.seed,
        "sources": {k: (str(v.absolute()) if isinstance(v, Path) else v)
                    for k, v in sources.items()},
        "versions": files.versions("numpy", "pandas"),
        "effects": [],
        "counts": {**files.table_counts(cfg_df["split"], cfg_df["object_id"], len(prs_df)),
                   "grasps": int(len(prs_df) + len(rej_df)),
                   "rejected": int(len(rej_df)), "dropped_configs": len(dropped)},
        "rejected": {"by_reason": by_reason, "file": "rejected.csv",
                     "criteria": list(REASONS)},
        "dropped_configs": dropped,
        "labels_check": check,
        "wall_time_s": round(time.perf_counter() - t0, 3),
    }
