"""Cones of repeated labels and the study's metrics of predictions against them.

See `vistac_learn.metrics` for the definitions and the conventions.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from vistac_learn.metrics.directions import (
    EPS_M,
    EPS_W,
    IN_CONE_RTOL,
    MSE_CLIP,
    angles_deg,
    as_vectors,
    directions,
    segment_reduce,
    slopes,
    wrap_abs_deg,
)


def cone_stats(label_sets: Sequence[object]) -> dict[str, np.ndarray]:
    """Cone of each configuration from its repeated unit labels.

    Args:
        label_sets: one (K_i, 2) array-like of (r_y, r_z) labels per configuration (K_i may be 0
            for a configuration no prediction refers to).

    Returns:
        Per-configuration (S,) arrays: "count" (K_i), "slope_min", "slope_max", "slope_mean",
        "width", "sign_lo", "sign_hi" (smallest/largest sign of label y), "angle_lo_deg",
        "angle_hi_deg" (edge directions, atan2(y, -z)), "angle_mean_deg" (direction of
        slope_mean), "label_mean" (S, 2) and "label_var" (mean squared distance of the labels
        to label_mean), both on the raw labels clipped to +-MSE_CLIP. Empty sets hold zeros.

    Raises:
        ValueError: for a label set of wrong shape or with non-finite values.
    """
    sets = [as_vectors(labels, f"label_sets[{i}]") for i, labels in enumerate(label_sets)]
    lengths = np.array([len(s) for s in sets], dtype=np.int64)
    labels = np.concatenate(sets) if sets else np.zeros((0, 2))
    unit = directions(labels)
    m = slopes(unit)
    angle = angles_deg(-m, np.ones_like(m))
    sign = np.sign(unit[:, 0])
    count = np.maximum(lengths, 1)
    raw = np.clip(labels, -MSE_CLIP, MSE_CLIP)
    label_mean = segment_reduce(raw, lengths, np.add) / count[:, None]
    sq_dev = ((raw - np.repeat(label_mean, lengths, axis=0)) ** 2).sum(axis=1)
    slope_min = segment_reduce(m, lengths, np.minimum)
    slope_max = segment_reduce(m, lengths, np.maximum)
    slope_mean = segment_reduce(m, lengths, np.add) / count
    return {
        "count": lengths,
        "slope_min": slope_min,
        "slope_max": slope_max,
        "slope_mean": slope_mean,
        "width": slope_max - slope_min,
        "sign_lo": segment_reduce(sign, lengths, np.minimum),
        "sign_hi": segment_reduce(sign, lengths, np.maximum),
        "angle_lo_deg": segment_reduce(angle, lengths, np.minimum),
        "angle_hi_deg": segment_reduce(angle, lengths, np.maximum),
        "angle_mean_deg": angles_deg(-slope_mean, np.ones_like(slope_mean)),
        "label_mean": label_mean,
        "label_var": segment_reduce(sq_dev, lengths, np.add) / count,
    }


def _check_cone_of(cone_of: object, n: int, cones: dict[str, np.ndarray]) -> np.ndarray:
    """Validate the prediction-to-configuration map.

    Args:
        cone_of: (N,) integer indices into the label sets.
        n: number of predictions.
        cones: output of `cone_stats`.

    Returns:
        (N,) int64 indices.

    Raises:
        ValueError: for a wrong shape, non-integers, out-of-range indices or indices of empty
            label sets.
    """
    idx = np.asarray(cone_of)
    if idx.size == 0:
        idx = idx.astype(np.int64)
    if idx.shape != (n,):
        raise ValueError(f"cone_of must have shape ({n},), got {idx.shape}")
    if not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"cone_of must hold integers, got dtype {idx.dtype}")
    n_sets = len(cones["count"])
    if n and (idx.min() < 0 or idx.max() >= n_sets):
        raise ValueError(f"cone_of must lie in [0, {n_sets}), got [{idx.min()}, {idx.max()}]")
    empty = cones["count"][idx] == 0
    if empty.any():
        raise ValueError(f"label sets {sorted(set(idx[empty].tolist()))} are empty")
    return idx.astype(np.int64)


def per_sample_metrics(
    pred: object, cone_of: object, label_sets: Sequence[object]
) -> dict[str, np.ndarray]:
    """Every metric for every prediction, against its configuration's cone.

    Args:
        pred: (N, 2) predicted (r_y, r_z), any positive scale.
        cone_of: (N,) index of each prediction's configuration in `label_sets`.
        label_sets: one (K_i, 2) array-like of unit labels per configuration.

    Returns:
        (N,) arrays: "slope" (clamped m), "angle_deg" (atan2(y, -z) of the prediction),
        "correct_y", "in_cone" (bool), "error_pct", "inacc_edge_pct", "inacc_mean_pct", "mse",
        "angle_to_mean_deg", "angle_to_cone_deg", and the cone of each prediction:
        "cone_min", "cone_max", "cone_mean", "cone_width" (slopes).

    Raises:
        ValueError: for wrong shapes, non-finite values or bad indices.
    """
    return _per_sample(as_vectors(pred, "pred"), cone_of, cone_stats(label_sets))


def _per_sample(
    vectors: np.ndarray, cone_of: object, cones: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """`per_sample_metrics` on validated (N, 2) predictions and precomputed cones.

    Args:
        vectors: (N, 2) finite predictions.
        cone_of: (N,) configuration indices (validated here).
        cones: output of `cone_stats`.

    Returns:
        The per-prediction arrays of `per_sample_metrics`.
    """
    idx = _check_cone_of(cone_of, len(vectors), cones)
    lo, hi = cones["slope_min"][idx], cones["slope_max"][idx]
    mean, width = cones["slope_mean"][idx], cones["width"][idx]

    unit = directions(vectors)
    m = slopes(unit)
    below = m < lo - IN_CONE_RTOL * np.maximum(1.0, np.abs(lo))
    above = m > hi + IN_CONE_RTOL * np.maximum(1.0, np.abs(hi))
    in_cone = ~(below | above)
    to_edge = np.where(below, lo - m, np.where(above, m - hi, 0.0))
    w_eff = np.maximum(width, EPS_W)

    sign = np.sign(unit[:, 0])
    angle = angles_deg(unit[:, 0], -unit[:, 1])
    to_cone = np.minimum(
        wrap_abs_deg(angle - cones["angle_lo_deg"][idx]),
        wrap_abs_deg(angle - cones["angle_hi_deg"][idx]),
    )
    raw = np.clip(vectors, -MSE_CLIP, MSE_CLIP)
    mse = 0.5 * (((raw - cones["label_mean"][idx]) ** 2).sum(axis=1) + cones["label_var"][idx])
    return {
        "slope": m,
        "angle_deg": angle,
        "correct_y": (sign >= cones["sign_lo"][idx]) & (sign <= cones["sign_hi"][idx]),
        "in_cone": in_cone,
        "error_pct": 100.0 * to_edge / np.maximum(np.abs(m), EPS_M),
        "inacc_edge_pct": 100.0 * to_edge / w_eff,
        "inacc_mean_pct": 100.0 * np.abs(m - mean) / w_eff,
        "mse": mse,
        "angle_to_mean_deg": wrap_abs_deg(angle - cones["angle_mean_deg"][idx]),
        "angle_to_cone_deg": np.where(in_cone, 0.0, to_cone),
        "cone_min": lo,
        "cone_max": hi,
        "cone_mean": mean,
        "cone_width": width,
    }


def _median(values: np.ndarray) -> float:
    """Median, 0.0 for an empty array."""
    return float(np.median(values)) if values.size else 0.0


def _mean(values: np.ndarray) -> float:
    """Mean, 0.0 for an empty array."""
    return float(np.mean(values)) if values.size else 0.0


def summarize(per_sample: dict[str, np.ndarray], mask: object = None) -> dict[str, float]:
    """Summarise per-prediction metrics the way the study reports them.

    Args:
        per_sample: output of `per_sample_metrics`.
        mask: optional (N,) bool selection, e.g. `cone_of == c` for one configuration.

    Returns:
        {"n", "n_in_cone", "n_out" (counts), "correct_y_pct", "in_cone_pct",
        "error_median_pct", "error_mean_pct" (in-cone counted as 0), "error_out_median_pct",
        "error_out_mean_pct" (outside the cone only), "inacc_edge_median_pct",
        "inacc_edge_mean_pct", "inacc_mean_median_pct", "inacc_mean_mean_pct", "mse_mean",
        "angle_to_mean_median_deg", "angle_to_mean_mean_deg", "angle_to_cone_median_deg",
        "angle_to_cone_mean_deg"}; every value a finite float (0.0 over an empty selection).
    """
    sel = per_sample if mask is None else {k: v[np.asarray(mask)] for k, v in per_sample.items()}
    n = int(sel["in_cone"].size)
    out = ~sel["in_cone"]
    summary: dict[str, float] = {
        "n": n,
        "n_in_cone": int(sel["in_cone"].sum()),
        "n_out": int(out.sum()),
        "correct_y_pct": 100.0 * _mean(sel["correct_y"].astype(float)),
        "in_cone_pct": 100.0 * _mean(sel["in_cone"].astype(float)),
        "error_median_pct": _median(sel["error_pct"]),
        "error_mean_pct": _mean(sel["error_pct"]),
        "error_out_median_pct": _median(sel["error_pct"][out]),
        "error_out_mean_pct": _mean(sel["error_pct"][out]),
    }
    for key in ("inacc_edge_pct", "inacc_mean_pct"):
        stem = key.removesuffix("_pct")
        summary[f"{stem}_median_pct"] = _median(sel[key])
        summary[f"{stem}_mean_pct"] = _mean(sel[key])
    summary["mse_mean"] = _mean(sel["mse"])
    for key in ("angle_to_mean_deg", "angle_to_cone_deg"):
        stem = key.removesuffix("_deg")
        summary[f"{stem}_median_deg"] = _median(sel[key])
        summary[f"{stem}_mean_deg"] = _mean(sel[key])
    return summary


def cone_metrics(pred: object, cone_of: object, label_sets: Sequence[object]) -> dict:
    """Every metric of docs/study.md section 6 plus angular metrics, summarised and per prediction.

    Several predictions may share a configuration (e.g. its 20 rotated images). See the module
    docstring for definitions and the conventions that keep every value finite.

    Args:
        pred: (N, 2) predicted (r_y, r_z), not necessarily unit length.
        cone_of: (N,) integer index of each prediction's configuration in `label_sets`.
        label_sets: one (K_i, 2) array-like of unit labels (the repeats) per configuration.

    Returns:
        The summary of `summarize` (finite floats and counts), plus "per_sample" (the arrays of
        `per_sample_metrics`) and "cones" (the per-configuration arrays of `cone_stats`).

    Raises:
        ValueError: for wrong shapes, non-finite values, indices out of range or referring to
            an empty label set.
    """
    cones = cone_stats(label_sets)
    per_sample = _per_sample(as_vectors(pred, "pred"), cone_of, cones)
    result: dict = summarize(per_sample)
    result["per_sample"] = per_sample
    result["cones"] = cones
    return result
