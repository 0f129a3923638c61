"""Cone metrics of the reference study (thesis.md section 6) plus angular metrics, numerically safe.

A configuration (object + finger placement) is pressed several times; its unit labels (r_y, r_z)
span a "cone" of force directions. Directions are compared as slopes m = y / z with z = -1 (the
force pushes into the pad, so labels have z < 0). Per configuration: m_min, m_max over the
repeats, cone mean m_mean = mean slope, width w = m_max - m_min. A prediction's slope is m.

Metrics per prediction (`per_sample_metrics`), summarised by `summarize`; `cone_metrics` does
both:
- correct y direction: sign(y_pred) lies between the smallest and the largest sign of the
  configuration's label y (signs -1, 0, +1). A cone holding both signs accepts any prediction;
  y_pred = 0 is correct only for a cone that holds y <= 0 and y >= 0 labels.
- in cone: m_min <= m <= m_max, each edge widened by a relative tolerance `IN_CONE_RTOL` * max(1,
  |edge|) so that a prediction equal to a label (up to rounding, or scaled) counts as inside.
- error = |m_edge - m| / max(|m|, EPS_M), m_edge the violated edge; 0 inside. Reported in %,
  median and mean over all predictions and over those outside the cone.
- inaccuracy to the cone edge = |m_edge - m| / w_eff (0 inside); inaccuracy to the cone mean =
  |m_mean - m| / w_eff, with w_eff = max(w, EPS_W). Reported in %, median and mean.
- MSE: the mean, over the configuration's labels and the two components, of (pred - label)^2 on
  the raw (not normalised) prediction; the torch `MSELoss` convention. Reported as the mean.
- angle to the cone mean (degrees, 0..180): between the raw prediction direction and the
  direction of slope m_mean, (y, z) ~ (-m_mean, -1).
- angular distance to the cone (degrees, 0..180): 0 inside the cone, else the angle to the nearer
  edge direction.

Conventions that keep every value finite for every finite input:
- Each vector is first reduced to its direction: divided by max(|y|, |z|), then by its length
  (no overflow for 1e308, no loss for 1e-320). Slopes and angles are therefore exactly invariant
  to a power-of-two scale and invariant up to rounding to any positive scale.
- A zero vector has no direction; it is read as (0, -1), straight into the pad: slope 0,
  angle 0.
- Slopes saturate: m = u_y / u_z on the unit vector u while u_z <= -EPS_Z (EPS_Z = 1e-6), so
  |m| <= 1 / EPS_Z = 1e6. A direction with u_z > -EPS_Z (tangential, or pointing away from the
  object, which no contact force does) gets the saturated slope -sign(u_y) / EPS_Z, y = 0
  counting as positive: it lies outside every cone whose labels press into the pad and scores
  the largest slope error. Labels are treated the same way. Angles of predictions are honest
  (unsaturated), so an away-pointing prediction lies more than 90 degrees from every cone; the
  cone edges' angles are those of their (saturated) slopes.
- |m| in the error's denominator is at least EPS_M = 1e-6: the error of y_pred -> 0 grows to
  |m_edge| * 1e6 instead of infinity (the study observed up to 35960 %).
- A cone of one label or of identical labels has w = 0; w_eff = EPS_W = 1e-3 (a cone narrower
  than 0.06 degrees at the normal counts as that wide).
- MSE clips raw components to +-MSE_CLIP = 1e100 first, so it saturates near 1e200 instead of
  overflowing.
- Medians are proper medians (`numpy.median`), never taken by a fixed index. The median or mean
  of an empty selection (e.g. no prediction outside any cone) is 0.0; the counts (`n`, `n_out`)
  tell that it was empty.
- Non-finite inputs (NaN, inf) are rejected with ValueError rather than silently propagated.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = [
    "EPS_Z",
    "EPS_M",
    "EPS_W",
    "IN_CONE_RTOL",
    "MSE_CLIP",
    "cone_metrics",
    "cone_stats",
    "per_sample_metrics",
    "summarize",
    "directions",
    "slopes",
]

EPS_Z = 1e-6
EPS_M = 1e-6
EPS_W = 1e-3
IN_CONE_RTOL = 1e-9
MSE_CLIP = 1e100


def _as_array(x: object, name: str) -> np.ndarray:
    """Convert an array-like (numpy, list, torch tensor) to float64, rejecting non-finite values.

    Args:
        x: the values.
        name: argument name for error messages.

    Returns:
        A float64 array.

    Raises:
        ValueError: if any value is NaN or infinite.
    """
    if hasattr(x, "detach"):  # torch tensor, without importing torch
        x = x.detach().cpu().numpy()
    arr = np.asarray(x, dtype=np.float64)
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} holds {int((~np.isfinite(arr)).sum())} non-finite values")
    return arr


def _as_vectors(x: object, name: str) -> np.ndarray:
    """Convert to an (N, 2) float64 array of finite (y, z) vectors.

    Args:
        x: array-like of shape (N, 2).
        name: argument name for error messages.

    Returns:
        The (N, 2) array.

    Raises:
        ValueError: for a wrong shape or non-finite values.
    """
    arr = _as_array(x, name)
    if arr.size == 0:
        return arr.reshape(0, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name} must have shape (N, 2), got {arr.shape}")
    return arr


def directions(vectors: np.ndarray) -> np.ndarray:
    """Unit direction of each (y, z) vector; the zero vector becomes (0, -1).

    Args:
        vectors: (N, 2) finite vectors.

    Returns:
        (N, 2) unit vectors (exactly scale-invariant for power-of-two scales).
    """
    vectors = np.asarray(vectors, dtype=np.float64)
    scale = np.abs(vectors).max(axis=1, keepdims=True)
    zero = scale[:, 0] == 0
    scaled = vectors / np.where(scale == 0, 1.0, scale)
    unit = scaled / np.hypot(scaled[:, :1], scaled[:, 1:]).clip(min=1.0)
    unit[zero] = (0.0, -1.0)
    return unit


def slopes(unit: np.ndarray) -> np.ndarray:
    """Slope m = y / z of unit vectors, saturated at -sign(y) / EPS_Z where z > -EPS_Z.

    Args:
        unit: (N, 2) unit vectors from `directions`.

    Returns:
        (N,) slopes, |m| <= 1 / EPS_Z; y = 0 with z > -EPS_Z gives -1 / EPS_Z.
    """
    y, z = unit[:, 0], unit[:, 1]
    pressing = z <= -EPS_Z
    saturated = np.where(y < 0, 1.0, -1.0) / EPS_Z
    return np.where(pressing, y / np.where(pressing, z, -1.0), saturated)


def _angles_deg(y: np.ndarray, minus_z: np.ndarray) -> np.ndarray:
    """Angle of a direction from the into-the-pad axis (0, -1), degrees in (-180, 180].

    Args:
        y: y components.
        minus_z: -z components.

    Returns:
        atan2(y, -z) in degrees.
    """
    return np.degrees(np.arctan2(y, minus_z))


def _wrap_abs_deg(delta: np.ndarray) -> np.ndarray:
    """Absolute angular difference folded into [0, 180] degrees.

    Args:
        delta: differences in degrees.

    Returns:
        |delta| modulo 360, folded to at most 180.
    """
    folded = np.abs(np.mod(delta, 360.0))
    return np.minimum(folded, 360.0 - folded)


def _segment_reduce(values: np.ndarray, lengths: np.ndarray, ufunc: np.ufunc) -> np.ndarray:
    """Reduce consecutive segments of `values` with `ufunc`; empty segments give 0.

    Args:
        values: (sum(lengths), ...) concatenated segments.
        lengths: (S,) segment lengths.
        ufunc: np.minimum, np.maximum or np.add.

    Returns:
        (S, ...) reductions.
    """
    out = np.zeros((len(lengths), *values.shape[1:]))
    nonempty = lengths > 0
    if nonempty.any():
        starts = (np.cumsum(lengths) - lengths)[nonempty]
        out[nonempty] = ufunc.reduceat(values, starts, axis=0)
    return out


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
    sets = [_as_vectors(labels, f"label_sets[{i}]") for i, labels in enumerate(label_sets)]
    lengths = np.array([len(s) for s in sets], dtype=np.int64)
    labels = np.concatenate(sets) if sets else np.zeros((0, 2))
    unit = directions(labels)
    m = slopes(unit)
    angle = _angles_deg(-m, np.ones_like(m))
    sign = np.sign(unit[:, 0])
    count = np.maximum(lengths, 1)
    raw = np.clip(labels, -MSE_CLIP, MSE_CLIP)
    label_mean = _segment_reduce(raw, lengths, np.add) / count[:, None]
    sq_dev = ((raw - np.repeat(label_mean, lengths, axis=0)) ** 2).sum(axis=1)
    slope_min = _segment_reduce(m, lengths, np.minimum)
    slope_max = _segment_reduce(m, lengths, np.maximum)
    slope_mean = _segment_reduce(m, lengths, np.add) / count
    return {
        "count": lengths,
        "slope_min": slope_min,
        "slope_max": slope_max,
        "slope_mean": slope_mean,
        "width": slope_max - slope_min,
        "sign_lo": _segment_reduce(sign, lengths, np.minimum),
        "sign_hi": _segment_reduce(sign, lengths, np.maximum),
        "angle_lo_deg": _segment_reduce(angle, lengths, np.minimum),
        "angle_hi_deg": _segment_reduce(angle, lengths, np.maximum),
        "angle_mean_deg": _angles_deg(-slope_mean, np.ones_like(slope_mean)),
        "label_mean": label_mean,
        "label_var": _segment_reduce(sq_dev, lengths, np.add) / count,
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
    return _per_sample(_as_vectors(pred, "pred"), cone_of, cone_stats(label_sets))


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
    angle = _angles_deg(unit[:, 0], -unit[:, 1])
    to_cone = np.minimum(
        _wrap_abs_deg(angle - cones["angle_lo_deg"][idx]),
        _wrap_abs_deg(angle - cones["angle_hi_deg"][idx]),
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
        "angle_to_mean_deg": _wrap_abs_deg(angle - cones["angle_mean_deg"][idx]),
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
    """Every metric of thesis.md section 6 plus angular metrics, summarised and per prediction.

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
    per_sample = _per_sample(_as_vectors(pred, "pred"), cone_of, cones)
    result: dict = summarize(per_sample)
    result["per_sample"] = per_sample
    result["cones"] = cones
    return result
