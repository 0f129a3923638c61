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
pairs). With ``--tta`` the raw predictions of a configuration's rotations are averaged first
(test-time augmentation), one prediction per configuration.
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

from vistac.dataset import open_dataset
from vistac.dataset.files import atomic_write_bytes, broken_link
from vistac.errors import UserError, brief
from vistac.folder_kinds import EVALUATION, mark
from vistac_learn.data.fingertip_table import fingertip_table
from vistac_learn.data.samples import RotationCfg, fingers_of
from vistac_learn.data.tip_coverage import MAX_MISSING_PCT, tip_coverage
from vistac_learn.evaluate import plots
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
    tables = open_dataset(data if data is not None else saved["path"])
    if tables.fingerprint() != saved["fingerprint"]:
        if data is None:
            raise UserError(f"{saved['path']}: the run's dataset has changed since training "
                            "(fingerprint differs); score it explicitly with --data and "
                            "--cross-dataset")
        if not cross_dataset:
            raise UserError(f"--data {data}: not the run's dataset ({saved['path']}); pass "
                            "--cross-dataset to score the run on another dataset")
    return tables


def evaluate_run(
    run: str | Path,
    data: str | Path | None = None,
    split: str = "test",
    tta: bool | None = None,
    checkpoint: str = "best",
    out: str | Path | None = None,
    make_plots: bool = True,
    device: str | None = None,
    progress: bool = False,
    cross_dataset: bool = False,
    max_missing_pct: float = MAX_MISSING_PCT,
    references: bool = True,
) -> dict:
    """Score a run's model on a split, beside the references (noise floor, pinch baseline).

    Args:
        run: Run folder.
        data: Dataset to score on (default: the run's training dataset).
        split: Split to score.
        tta: Test-time augmentation: average each configuration's rotations (study views) and
            its mirrored view (r_y of the mirror negated); None: as the run's recipe says
            (`TrainCfg.tta`: on for the default recipe, off for the study's protocol).
        checkpoint: ``best`` (validation-selected) or ``last``.
        out: Output folder (default ``<run>/eval/<split>[-tta]``).
        make_plots: Write the PNG figures.
        device: Override the run's device.
        progress: Show progress bars.
        cross_dataset: Allow a dataset other than the run's (see `run_dataset`).
        max_missing_pct: Refuse a split of which more than this share (%) of the
            configurations has a fingertip the locator does not find (tip view).
        references: Score the noise floor and the pinch baseline on the same configurations
            (`vistac_learn.evaluate.references`; skipped for data without clean forces).

    Returns:
        The content of ``metrics.json``.

    Raises:
        UserError: a damaged run or dataset, too many fingertips not found.
    """
    cfg, meta = load_run(run)
    tta = cfg.tta if tta is None else tta
    dev = resolve_device(device or cfg.device)
    tables = run_dataset(meta, data, cross_dataset)
    cfg = dataclasses.replace(cfg, data=str(tables.root))
    model, epoch = load_model(run, cfg, checkpoint, dev)
    size = input_size(cfg, model)
    tips = fingertip_table(tables, cache_dir=cfg.cache_dir, progress=progress) \
        if build_view(cfg).needs_tips else None
    coverage = None
    if tips is not None:
        coverage = tip_coverage(tables, tips, tables.rows(split), fingers_of(cfg.finger), split)
        coverage.check(max_missing_pct)
    ds = build_samples(cfg, tables, split, size, tips)
    t0 = time.perf_counter()
    if tta:
        pred = predict_mirror_averaged(
            model, lambda mirror: build_samples(cfg, tables, split, size, tips, mirror=mirror)
            if mirror else ds, dev, cfg.eval_batch_size)
    else:
        pred = predict(model, ds, dev, cfg.eval_batch_size)
    elapsed = time.perf_counter() - t0
    item_row, item_rot = ds.item_row, ds.item_rot
    if tta:
        pred, item_row = average_over_rotations(pred, item_row)
        item_rot = np.full(len(item_row), -1)
    lost = {f: (tips.failures(ds.rows, f) if tips is not None else 0) for f in ds.fingers}
    info = {"kind": "model", "run": str(Path(run).resolve()), "model": cfg.model,
            "variant": cfg.variant, "data": str(tables.root.resolve()),
            "fingerprint": tables.fingerprint(), "split": split, "tta": tta,
            "checkpoint": checkpoint, "epoch": epoch, "device": str(dev),
            "images_per_s": len(ds) * (2 if tta else 1) / max(elapsed, 1e-9),
            "n_rotations": ds.rotations.count, "fingers_not_found": lost,
            "fingertips": coverage.as_dict() if coverage is not None else None,
            "fingertips_line": coverage.line() if coverage is not None else None}
    out = Path(out) if out is not None else Path(run) / "eval" / (split + ("-tta" if tta else ""))
    label = f"{cfg.model}, {cfg.variant}" + (", TTA" if tta else "")
    fingers = fingers_of(cfg.finger)
    refs = reference_scores(tables, ds.rows, fingers, cache_dir=cfg.cache_dir,
                            progress=progress) if references else None
    return _write_outputs(out, label, pred, tables, ds.rows, item_row, item_rot, fingers, info,
                          make_plots, refs)


def evaluate_baseline(
    data: str | Path,
    out: str | Path,
    split: str = "test",
    finger: str = "index",
    rotations: RotationCfg | None = None,
    tta: bool = False,
    make_plots: bool = True,
    cfg: GeometricCfg | PinchCfg | None = None,
    progress: bool = False,
    max_missing_pct: float = MAX_MISSING_PCT,
    baseline: str = "geometric",
) -> dict:
    """Score a non-learned baseline on a split (same metrics and outputs as `evaluate_run`),
    beside the noise floor on simulated data.

    Args:
        data: Dataset directory.
        out: Output folder.
        split: Split to score.
        finger: ``index``, ``thumb`` or ``both``.
        rotations: Rotations of each image it is applied to, as the models see them (default
            the study's 20 fixed angles).
        tta: Average each configuration's rotations before scoring.
        make_plots: Write the PNG figures.
        cfg: Baseline settings (default `GeometricCfg()` or `PinchCfg()`).
        progress: Show a progress bar.
        max_missing_pct: Refuse a split of which more than this share (%) of the
            configurations has a fingertip the locator does not find.
        baseline: ``geometric`` (surface normal, `evaluate.geometric`) or ``pinch`` (closing
            axis and friction cone, `evaluate.pinch`).

    Returns:
        The content of ``metrics.json``.
    """
    rotations = rotations or RotationCfg()
    if baseline not in BASELINES:
        raise UserError(f"--baseline must be {' or '.join(BASELINES)}, not {baseline!r}")
    cfg = cfg or BASELINES[baseline][0]()
    tables = open_dataset(data)
    fingers = fingers_of(finger)
    rows = tables.rows(split)
    coverage = tip_coverage(tables, fingertip_table(tables, cfg.locator, progress=progress),
                            rows, fingers, split)
    coverage.check(max_missing_pct)
    t0 = time.perf_counter()
    pred, item_row, item_rot, failures = BASELINES[baseline][1](
        tables, rows, fingers, rotations, cfg, progress)
    elapsed = time.perf_counter() - t0
    if tta:
        pred, item_row = average_over_rotations(pred, item_row)
        item_rot = np.full(len(item_row), -1)
    info = {"kind": "baseline", "baseline": baseline, "settings": dataclasses.asdict(cfg),
            "data": str(data), "split": split, "tta": tta, "failures": failures,
            "fingertips": coverage.as_dict(), "fingertips_line": coverage.line(),
            "images_per_s": len(rows) * rotations.count / max(elapsed, 1e-9),
            "n_rotations": rotations.count}
    refs = ({"noise_floor": {"metrics": noise_floor(tables, rows, fingers)}}
            if has_clean_forces(tables, fingers) else None)
    label = f"{baseline} baseline" + (", TTA" if tta else "")
    return _write_outputs(Path(out), label, pred, tables, rows, item_row, item_rot, fingers,
                          info, make_plots, refs)
