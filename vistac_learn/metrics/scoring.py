"""Predicting over a pair dataset and scoring predictions with the cone metrics, per finger.

The metric itself is `vistac_learn.metrics.cone_metrics` (docs/study.md section 6 plus angular
metrics); this module only lines predictions up with the cones of their configurations.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from vistac_learn.data.loading import loader
from vistac_learn.metrics.cone import cone_metrics
from vistac_learn.models.tipnet import apply_model

# The study's results columns (docs/study.md section 9), as (header, summary key).
STUDY_COLUMNS = (
    ("% correct y", "correct_y_pct"),
    ("% in cone", "in_cone_pct"),
    ("median err overall", "error_median_pct"),
    ("median err not in cone", "error_out_median_pct"),
    ("median inacc. edge", "inacc_edge_median_pct"),
    ("median inacc. mean", "inacc_mean_median_pct"),
    ("mean MSE", "mse_mean"),
)
# Angular columns added by this project.
ANGLE_COLUMNS = (
    ("median angle to mean (deg)", "angle_to_mean_median_deg"),
    ("median angle to cone (deg)", "angle_to_cone_median_deg"),
)


@torch.no_grad()
def predict(model: torch.nn.Module, ds, device: torch.device | str, batch_size: int = 64,
            workers: int = 0) -> np.ndarray:
    """Model outputs for every sample of a `SampleSet`, in sample order, as float64 (M, 2F)
    (`workers`: loader processes, `vistac_learn.data.loading.loader`).

    A finger that was not located in its image gets (0, -1), straight against the approach.
    """
    model.eval()
    out = []
    for batch in loader(ds, batch_size, workers=workers):
        p = apply_model(model, batch, device).float().cpu().numpy().astype(np.float64)
        lost = ~batch["found"].numpy()
        for k in range(lost.shape[1]):
            p[lost[:, k], 2 * k:2 * k + 2] = (0.0, -1.0)
        out.append(p)
    if not out:
        return np.zeros((0, 2 * len(ds.fingers)))
    return np.concatenate(out)


def predict_mirror_averaged(model: torch.nn.Module, samples, device: torch.device | str,
                            batch_size: int = 64) -> np.ndarray:
    """The recipe's test-time augmentation: `predict` on ``samples(False)`` averaged with
    `predict` on the mirrored view ``samples(True)`` (whose r_y is negated back first)."""
    pred = predict(model, samples(False), device, batch_size)
    mirrored = predict(model, samples(True), device, batch_size)
    mirrored[:, 0::2] *= -1
    return 0.5 * (pred + mirrored)


def score(
    pred: np.ndarray,
    tables,
    rows: np.ndarray,
    item_row: np.ndarray,
    fingers: Sequence[str],
    full: bool = False,
) -> dict[str, dict]:
    """Cone metrics of each finger.

    Args:
        pred: (M, 2F) predictions, columns (r_y, r_z) per finger in `fingers` order.
        tables: The `DatasetTables` holding the cones.
        rows: Configuration rows scored (each a cone).
        item_row: (M,) configuration row of each prediction (a member of `rows`).
        fingers: Fingers of the prediction columns.
        full: Keep the per-sample and per-cone arrays (else scalars only).

    Returns:
        Finger -> `cone_metrics` result (scalars only unless `full`).
    """
    rows = np.asarray(rows, dtype=np.int64)
    order = np.argsort(rows)
    pos = order[np.searchsorted(rows[order], np.asarray(item_row, dtype=np.int64))]
    out = {}
    for i, f in enumerate(fingers):
        cones = [tables.cones[f][r] for r in rows]
        res = cone_metrics(pred[:, 2 * i:2 * i + 2], pos, cones)
        out[f] = res if full else {k: v for k, v in res.items() if np.isscalar(v)}
    return out


def score_predictions(pred: np.ndarray, ds, full: bool = False) -> dict[str, dict]:
    """`score` for the samples of a `SampleSet`."""
    return score(pred, ds.tables, ds.rows, ds.item_row, ds.fingers, full)


def average_over_rotations(pred: np.ndarray, item_row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Test-time averaging: the mean raw prediction per configuration row.

    Returns:
        (pred (R, out), rows (R,)), rows in ascending order.
    """
    rows, inv = np.unique(item_row, return_inverse=True)
    sums = np.zeros((len(rows), pred.shape[1]))
    np.add.at(sums, inv, pred)
    counts = np.bincount(inv, minlength=len(rows))[:, None]
    return sums / counts, rows


def format_table(entries: Sequence[tuple[str, dict]], angles: bool = True) -> str:
    """A markdown table in the study's layout (docs/study.md section 9), one row per entry.

    Args:
        entries: (label, summary) pairs; a summary is one finger's scalar metrics.
        angles: Add the angular columns after the study's.

    Returns:
        The table as markdown text.
    """
    cols = STUDY_COLUMNS + (ANGLE_COLUMNS if angles else ())
    lines = ["| model / setting | " + " | ".join(h for h, _ in cols) + " |",
             "|---" * (len(cols) + 1) + "|"]
    for label, s in entries:
        cells = []
        for _, key in cols:
            v = s.get(key, float("nan"))
            if key == "mse_mean":
                cells.append(f"{v:.2e}")
            else:
                cells.append(f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
