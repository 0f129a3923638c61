"""Scoring a trained run (or the geometric baseline) on a split (`vistac evaluate`).

For each finger: every metric of docs/study.md section 6 plus angular metrics
(`vistac_learn.metrics.cone_metrics`), as a table in the study's layout (docs/study.md section 9,
which `vistac evaluate` prints; these functions print nothing) and saved, with the
per-prediction values and the figures, into an output folder:

- ``metrics.json``: settings, counts, inference speed, the scalar metrics per finger, the table.
- ``predictions.parquet``: one row per prediction (config_id, rotation, prediction and per-sample
  metrics of each finger).
- ``cones_<finger>.png``, ``error_hist_<finger>.png``, ``rotation_spread_<finger>.png``.

Every (configuration, rotation) pair is one prediction, as in the study (34 x 20 = 680 test
pairs). With test-time augmentation (``--tta``; a run's recipe may turn it on) the raw
predictions of a configuration's rotations (and, for a run, of its mirrored view) are averaged
first, one prediction per configuration.
"""

from __future__ import annotations

import dataclasses
import io
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from vistac.dataset import open_tables
from vistac.dataset.files import atomic_write_bytes, broken_link
from vistac.errors import UserError, brief
from vistac.folder_kinds import EVALUATION, mark
from vistac_learn.data.fingertip_table import fingertip_table
from vistac_learn.data.samples import RotationCfg, fingers_of
from vistac_learn.data.tip_coverage import tip_coverage
from vistac_learn.evaluate import plots
from vistac_learn.evaluate.config import EvaluateCfg
from vistac_learn.evaluate.geometric import GeometricCfg, baseline_predictions
from vistac_learn.evaluate.pinch import PinchCfg, pinch_predictions
from vistac_learn.evaluate.references import has_clean_forces, noise_floor, reference_entries
from vistac_learn.evaluate.references import references as reference_scores
from vistac_learn.metrics.scoring import (
    average_over_rotations,
    format_table,
    predict,
    predict_mirror_averaged,
    score,
)
from vistac_learn.train.build import (
    build_boxes,
    build_model,
    build_samples,
    build_view,
    input_size,
    resolve_device,
)
from vistac_learn.train.checkpoints import load_checkpoint, load_weights
from vistac_learn.train.config import TrainCfg
from vistac_learn.train.run_files import read_run_config, run_settings

RETRAIN = "train the run again (`vistac train` into this folder without --resume)"

# Baselines by name: (settings class, predictions over (configuration, rotation) pairs).
BASELINES = {"geometric": (GeometricCfg, baseline_predictions),
             "pinch": (PinchCfg, pinch_predictions)}


def load_run(run: str | Path) -> tuple[TrainCfg, dict]:
    """The `TrainCfg` and the whole ``config.json`` of a run folder.

    Raises:
        UserError: no run there, or a damaged ``config.json`` (what to do in the message).
    """
    meta = read_run_config(Path(run), RETRAIN)
    return run_settings(Path(run), meta, RETRAIN), meta


def load_model(
    run: str | Path, cfg: TrainCfg, checkpoint: str, device
) -> tuple[torch.nn.Module, int]:
    """The run's model with weights from ``checkpoints/<checkpoint>.pt``; (model, epoch)."""
    path = Path(run) / "checkpoints" / f"{checkpoint}.pt"
    why = broken_link(path.parent)
    if why is not None:
        raise UserError(f"{path.parent}: {why}; remove it (or point it at the run's "
                        "checkpoints) and train the run again")
    if not path.exists():
        raise UserError(f"{path}: missing (has the run finished an epoch?)")
    ck = load_checkpoint(path, ("model", "epoch"), RETRAIN, map_location=device)
    epoch = ck["epoch"]
    if not isinstance(epoch, int) or isinstance(epoch, bool) or epoch < 0:
        raise UserError(f"{path}: its epoch is {brief(epoch)}, not a whole number; {RETRAIN}")
    model = build_model(cfg)
    load_weights(model, ck["model"], path, RETRAIN)
    return model.to(device), epoch


def _write_outputs(
    out: Path,
    label: str,
    pred: np.ndarray,
    tables,
    rows: np.ndarray,
    item_row: np.ndarray,
    item_rot: np.ndarray,
    fingers: tuple[str, ...],
    info: dict,
    make_plots: bool,
    refs: dict | None = None,
) -> dict:
    """Score and save (JSON, per-prediction parquet, PNGs); return the JSON dict (its
    ``table`` is what `vistac evaluate` prints).

    `refs` (`references.references`) adds the noise floor and the pinch baseline below the
    scored rows of the table and under ``"references"`` in the JSON.
    """
    mark(out, EVALUATION)  # the folder's kind, before its first file
    res = score(pred, tables, rows, item_row, fingers, full=True)
    cids = tables.configs["config_id"].to_numpy()
    frame = {"config_id": cids[item_row], "rotation": item_rot}
    for i, f in enumerate(fingers):
        frame[f"pred_{f}_y"], frame[f"pred_{f}_z"] = pred[:, 2 * i], pred[:, 2 * i + 1]
        for k, v in res[f]["per_sample"].items():
            frame[f"{f}_{k}"] = v
    table_bytes = io.BytesIO()  # written whole or not at all, like every file here
    pd.DataFrame(frame).to_parquet(table_bytes, index=False)
    atomic_write_bytes(out / "predictions.parquet", table_bytes.getvalue())
    summary = {f: {k: v for k, v in r.items() if np.isscalar(v)} for f, r in res.items()}
    table = format_table([(f"{label} ({f})", summary[f]) for f in fingers]
                         + reference_entries(refs, fingers))
    result = {**info, "label": label, "fingers": list(fingers), "n_configs": int(len(rows)),
              "n_predictions": int(len(pred)), "metrics": summary, "table": table}
    if refs is not None:
        result["references"] = refs
    atomic_write_bytes(out / "metrics.json", json.dumps(result, indent=2).encode())
    if make_plots:
        order = np.argsort(rows)
        pos = order[np.searchsorted(rows[order], item_row)]
        titles = [f"config {c}" for c in cids[rows]]
        for i, f in enumerate(fingers):
            ps, cones = res[f]["per_sample"], res[f]["cones"]
            label_sets = [tables.cones[f][r] for r in rows]
            plots.plot_cones(pred[:, 2 * i:2 * i + 2], pos, ps["in_cone"], label_sets, cones,
                             titles, out / f"cones_{f}.png")
            plots.plot_error_hist(ps["error_pct"], out / f"error_hist_{f}.png", f"{label} {f}:")
            plots.plot_rotation_spread(ps["angle_deg"], pos, cones,
                                       out / f"rotation_spread_{f}.png", f"{label} {f}:")
    return result


def run_dataset(meta: dict, data: str | Path | None, cross_dataset: bool):
    """The dataset to score a run on, checked against the run's.

    Without `data`, the run's own dataset (its absolute path in ``config.json``), which must
    still have the fingerprint the run recorded. Another dataset is scored only with
    `cross_dataset` (e.g. a sim-trained model on real recordings).
    """
    saved = meta["dataset"]
    tables = open_tables(data if data is not None else saved["path"])
    if tables.fingerprint() != saved["fingerprint"]:
        if data is None:
            raise UserError(f"{saved['path']}: the run's dataset has changed since training "
                            "(fingerprint differs); score it explicitly with --data and "
                            "--cross-dataset")
        if not cross_dataset:
            raise UserError(f"--data {data}: not the run's dataset ({saved['path']}); pass "
                            "--cross-dataset to score the run on another dataset")
    return tables


def evaluate_run(cfg: EvaluateCfg, out: str | Path | None = None, *,
                 progress: bool = False) -> dict:
    """Score a run's model on a split, beside the references (noise floor, pinch baseline).

    Args:
        cfg: What to score (`EvaluateCfg` with `run`): ``run``, ``data`` (default: the run's
            training dataset), ``split``, ``tta`` (``recipe``: as the run's `TrainCfg.tta` says,
            on for the default recipe, off for the study's protocol; ``on``: average each
            configuration's rotations and its mirrored view, r_y of the mirror negated;
            ``off``: neither), ``checkpoint`` (``best``, validation-selected, or ``last``),
            ``no_plots``, ``device`` (override the run's), ``cross_dataset`` (allow a dataset
            other than the run's, see `run_dataset`), ``max_missing_pct`` (refuse a split of
            which more than this share (%) of the configurations has a fingertip the locator
            does not find; tip view), ``no_references`` (skip the noise floor and the pinch
            baseline, `vistac_learn.evaluate.references`; skipped anyway for data without
            clean forces).
        out: Output folder (default `cfg.out_dir`: ``cfg.out``, else
            `vistac_learn.evaluate.config.default_out_dir`: ``<run>/eval/<split>``, with
            ``-tta`` after it for ``tta="on"`` and ``-no-tta`` for ``tta="off"``).
        progress: Show progress bars.

    Returns:
        The content of ``metrics.json``.

    Raises:
        UserError: a damaged run or dataset, too many fingertips not found.
    """
    if cfg.run is None:
        raise UserError("evaluate_run: the config names no run (a baseline's goes to "
                        "evaluate_baseline)")
    run, split, checkpoint = Path(cfg.run), cfg.split, cfg.checkpoint
    train_cfg, meta = load_run(run)
    tta = cfg.averaged(train_cfg.tta)
    dev = resolve_device(cfg.device or train_cfg.device)
    tables = run_dataset(meta, cfg.data, cfg.cross_dataset)
    train_cfg = dataclasses.replace(train_cfg, data=str(tables.root))
    model, epoch = load_model(run, train_cfg, checkpoint, dev)
    size = input_size(train_cfg, model)
    tips = fingertip_table(tables, cache_dir=train_cfg.cache_dir, progress=progress) \
        if build_view(train_cfg).needs_tips else None
    boxes = build_boxes(train_cfg, tables, progress)  # where the dataset has none (ingested)
    coverage = None
    if tips is not None:
        coverage = tip_coverage(tables, tips, tables.rows(split), fingers_of(train_cfg.finger),
                                split)
        coverage.check(cfg.max_missing_pct)
    if boxes is not None:
        box_cov = tip_coverage(tables, boxes, tables.rows(split),
                               build_view(train_cfg).needs_boxes, split)
        box_cov.check(cfg.max_missing_pct)
        coverage = coverage or box_cov
    ds = build_samples(train_cfg, tables, split, size, tips, boxes=boxes)
    t0 = time.perf_counter()
    if tta:
        pred = predict_mirror_averaged(
            model, lambda mirror: build_samples(train_cfg, tables, split, size, tips,
                                                mirror=mirror, boxes=boxes) if mirror else ds,
            dev, train_cfg.eval_batch_size)
    else:
        pred = predict(model, ds, dev, train_cfg.eval_batch_size)
    elapsed = time.perf_counter() - t0
    item_row, item_rot = ds.item_row, ds.item_rot
    if tta:
        pred, item_row = average_over_rotations(pred, item_row)
        item_rot = np.full(len(item_row), -1)
    lost = {f: (tips.failures(ds.rows, f) if tips is not None else 0) for f in ds.fingers}
    info = {"kind": "model", "run": str(run.resolve()), "model": train_cfg.model,
            "variant": train_cfg.variant, "data": str(tables.root.resolve()),
            "fingerprint": tables.fingerprint(), "split": split, "tta": tta,
            "checkpoint": checkpoint, "epoch": epoch, "device": str(dev),
            "images_per_s": len(ds) * (2 if tta else 1) / max(elapsed, 1e-9),
            "n_rotations": ds.rotations.count, "fingers_not_found": lost,
            "fingertips": coverage.as_dict() if coverage is not None else None,
            "fingertips_line": coverage.line() if coverage is not None else None}
    out = Path(out) if out is not None else cfg.out_dir
    label = f"{train_cfg.model}, {train_cfg.variant}" + (", TTA" if tta else "")
    fingers = fingers_of(train_cfg.finger)
    refs = reference_scores(tables, ds.rows, fingers, cache_dir=train_cfg.cache_dir,
                            progress=progress) if not cfg.no_references else None
    return _write_outputs(out, label, pred, tables, ds.rows, item_row, item_rot, fingers, info,
                          not cfg.no_plots, refs)


def evaluate_baseline(cfg: EvaluateCfg, out: str | Path | None = None, *,
                      progress: bool = False,
                      settings: GeometricCfg | PinchCfg | None = None) -> dict:
    """Score a non-learned baseline on a split (same metrics and outputs as `evaluate_run`),
    beside the noise floor on simulated data.

    Args:
        cfg: What to score (`EvaluateCfg` with `baseline` and `data`): ``baseline``
            (``geometric``: surface normal, `evaluate.geometric`; ``pinch``: closing axis and
            friction cone, `evaluate.pinch`), ``data``, ``split``, ``finger`` (``index``,
            ``thumb`` or ``both``), ``rotations`` and ``n_rotations`` (the rotations of each
            image it is applied to, as the models see them), ``tta`` (``on``: average each
            configuration's rotations before scoring; ``recipe``, there being none, and
            ``off``: not), ``no_plots``, ``max_missing_pct`` (refuse a split of which more
            than this share (%) of the configurations has a fingertip the locator does not
            find).
        out: Output folder (default `cfg.out_dir`: ``cfg.out``, else
            `vistac_learn.evaluate.config.default_out_dir`: ``<data>/eval/<baseline>-<split>``,
            with ``-tta`` after it for ``tta="on"`` and ``-no-tta`` for ``tta="off"``).
        progress: Show a progress bar.
        settings: Baseline settings (default `GeometricCfg()` or `PinchCfg()`).

    Returns:
        The content of ``metrics.json``.
    """
    baseline, data, split = cfg.baseline, cfg.data, cfg.split
    if baseline is None:
        raise UserError("evaluate_baseline: the config names no baseline (a run's goes to "
                        "evaluate_run)")
    rotations = RotationCfg(cfg.rotations, cfg.n_rotations)
    tta = cfg.averaged()
    out = Path(out) if out is not None else cfg.out_dir
    bcfg = settings or BASELINES[baseline][0]()
    tables = open_tables(data)
    fingers = fingers_of(cfg.finger)
    rows = tables.rows(split)
    coverage = tip_coverage(tables, fingertip_table(tables, bcfg.locator, progress=progress),
                            rows, fingers, split)
    coverage.check(cfg.max_missing_pct)
    t0 = time.perf_counter()
    pred, item_row, item_rot, failures = BASELINES[baseline][1](
        tables, rows, fingers, rotations, bcfg, progress)
    elapsed = time.perf_counter() - t0
    if tta:
        pred, item_row = average_over_rotations(pred, item_row)
        item_rot = np.full(len(item_row), -1)
    info = {"kind": "baseline", "baseline": baseline, "settings": dataclasses.asdict(bcfg),
            "data": str(data), "split": split, "tta": tta, "failures": failures,
            "fingertips": coverage.as_dict(), "fingertips_line": coverage.line(),
            "images_per_s": len(rows) * rotations.count / max(elapsed, 1e-9),
            "n_rotations": rotations.count}
    refs = ({"noise_floor": {"metrics": noise_floor(tables, rows, fingers)}}
            if has_clean_forces(tables, fingers) else None)
    label = f"{baseline} baseline" + (", TTA" if tta else "")
    return _write_outputs(out, label, pred, tables, rows, item_row, item_rot, fingers,
                          info, not cfg.no_plots, refs)
