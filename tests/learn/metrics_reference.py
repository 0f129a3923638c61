"""A slow, obvious reference of the cone metrics (a test helper) and small label builders."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest

from vistac_learn.metrics import EPS_M, EPS_W, EPS_Z, cone_metrics, per_sample_metrics

SUMMARY_KEYS = (
    "correct_y_pct", "in_cone_pct", "error_median_pct", "error_mean_pct", "error_out_median_pct",
    "error_out_mean_pct", "inacc_edge_median_pct", "inacc_edge_mean_pct", "inacc_mean_median_pct",
    "inacc_mean_mean_pct", "mse_mean", "angle_to_mean_median_deg", "angle_to_mean_mean_deg",
    "angle_to_cone_median_deg", "angle_to_cone_mean_deg",
)  # fmt: skip
CONE_KEYS = (  # per-sample metrics that depend only on the prediction's direction
    "slope", "angle_deg", "correct_y", "in_cone", "error_pct", "inacc_edge_pct",
    "inacc_mean_pct", "angle_to_mean_deg", "angle_to_cone_deg",
)  # fmt: skip


def label(m: float) -> tuple[float, float]:
    """Unit label (y, z) with z < 0 and slope y / z = m."""
    z = -1.0 / math.sqrt(1.0 + m * m)
    return (m * z, z)


def pred_with_slope(m: float, scale: float = 1.0) -> tuple[float, float]:
    """A prediction pressing into the pad (z = -scale) with slope m."""
    return (-m * scale, -scale)


# --------------------------------------------------------------------------------------------
# Slow, obvious reference: loops over plain floats, following the module's stated conventions.
# --------------------------------------------------------------------------------------------


def ref_slope(y: float, z: float) -> float:
    """m = y / z; zero vector -> 0; z / |v| > -EPS_Z -> -sign(y) / EPS_Z with sign(0) = +1."""
    if y == 0.0 and z == 0.0:
        return 0.0
    if z / math.hypot(y, z) <= -EPS_Z:
        return y / z
    return (1.0 if y < 0 else -1.0) / EPS_Z


def ref_angle(y: float, z: float) -> float:
    """Degrees of (y, z) from the into-the-pad axis; zero vector -> 0."""
    if y == 0.0 and z == 0.0:
        return 0.0
    return math.degrees(math.atan2(y, -z))


def ref_angle_between(a: float, b: float) -> float:
    d = abs(a - b) % 360.0
    return min(d, 360.0 - d)


def ref_sign(v: float) -> int:
    return (v > 0) - (v < 0)


def ref_metrics(preds, cone_of, label_sets):
    """Per-sample dicts and a summary dict, computed one prediction at a time."""
    rows = []
    for (py, pz), c in zip(preds, cone_of, strict=True):
        labels = label_sets[c]
        ms = [ref_slope(y, z) for y, z in labels]
        lo, hi, mean = min(ms), max(ms), sum(ms) / len(ms)
        width = hi - lo
        m = ref_slope(py, pz)
        tol_lo = 1e-9 * max(1.0, abs(lo))
        tol_hi = 1e-9 * max(1.0, abs(hi))
        if m < lo - tol_lo:
            inside, dist = False, lo - m
        elif m > hi + tol_hi:
            inside, dist = False, m - hi
        else:
            inside, dist = True, 0.0
        signs = [ref_sign(y) for y, _ in labels]
        w_eff = width if width > EPS_W else EPS_W
        angle = ref_angle(py, pz)
        edge_angles = [math.degrees(math.atan(-lo)), math.degrees(math.atan(-hi))]
        mean_angle = math.degrees(math.atan2(-mean, 1.0))
        sq = 0.0
        cy, cz = (max(-1e100, min(1e100, v)) for v in (py, pz))  # MSE_CLIP
        for ly, lz in labels:
            sq += ((cy - ly) ** 2 + (cz - lz) ** 2) / 2.0
        rows.append({
            "slope": m,
            "angle_deg": angle,
            "correct_y": min(signs) <= ref_sign(py) <= max(signs),
            "in_cone": inside,
            "error_pct": 100.0 * dist / max(abs(m), EPS_M),
            "inacc_edge_pct": 100.0 * dist / w_eff,
            "inacc_mean_pct": 100.0 * abs(m - mean) / w_eff,
            "mse": sq / len(labels),
            "angle_to_mean_deg": ref_angle_between(angle, mean_angle),
            "angle_to_cone_deg": 0.0 if inside else min(
                ref_angle_between(angle, a) for a in edge_angles),
        })  # fmt: skip

    def med(values):
        return statistics.median(values) if values else 0.0

    def avg(values):
        return statistics.fmean(values) if values else 0.0

    def col(key, only_out=False):
        return [r[key] for r in rows if not (only_out and r["in_cone"])]

    summary = {
        "correct_y_pct": 100.0 * avg([float(v) for v in col("correct_y")]),
        "in_cone_pct": 100.0 * avg([float(v) for v in col("in_cone")]),
        "error_median_pct": med(col("error_pct")),
        "error_mean_pct": avg(col("error_pct")),
        "error_out_median_pct": med(col("error_pct", only_out=True)),
        "error_out_mean_pct": avg(col("error_pct", only_out=True)),
        "inacc_edge_median_pct": med(col("inacc_edge_pct")),
        "inacc_edge_mean_pct": avg(col("inacc_edge_pct")),
        "inacc_mean_median_pct": med(col("inacc_mean_pct")),
        "inacc_mean_mean_pct": avg(col("inacc_mean_pct")),
        "mse_mean": avg(col("mse")),
        "angle_to_mean_median_deg": med(col("angle_to_mean_deg")),
        "angle_to_mean_mean_deg": avg(col("angle_to_mean_deg")),
        "angle_to_cone_median_deg": med(col("angle_to_cone_deg")),
        "angle_to_cone_mean_deg": avg(col("angle_to_cone_deg")),
    }
    return rows, summary


def random_case(seed: int, n_configs: int = 25, n_preds: int = 300):
    """Configurations of 1-8 noisy labels (some identical), predictions incl. special values."""
    rng = np.random.default_rng(seed)
    label_sets = []
    for i in range(n_configs):
        k = int(rng.integers(1, 9))
        centre = rng.uniform(-1.3, 1.3)  # radians from the normal
        angles = centre + rng.normal(0.0, 0.15, k)
        if i % 5 == 0:
            angles[:] = centre  # identical repeats: zero width
        label_sets.append(np.stack([np.sin(angles), -np.cos(angles)], axis=1))
    preds = rng.normal(0.0, 1.0, (n_preds, 2)) * rng.choice([1e-3, 1.0, 10.0], (n_preds, 1))
    preds[:, 1] -= 0.8 * np.abs(preds[:, 1])  # mostly pressing, some pointing away
    special = [(0.0, 0.0), (0.0, -1.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (1e-300, -1e-300),
               (0.3, 1e-300), (5e-324, -1.0), (1e300, -2e300), (-1e-8, -1.0)]  # fmt: skip
    preds[: len(special)] = special
    cone_of = rng.integers(0, n_configs, n_preds)
    return preds, cone_of, label_sets


def assert_close_to_reference(preds, cone_of, label_sets, rtol=1e-9, atol=1e-9):
    ref_rows, ref_summary = ref_metrics(
        [tuple(map(float, p)) for p in preds], [int(c) for c in cone_of],
        [[tuple(map(float, lab)) for lab in labels] for labels in label_sets],
    )  # fmt: skip
    result = cone_metrics(preds, cone_of, label_sets)
    for key in ref_rows[0]:
        expected = np.array([r[key] for r in ref_rows])
        actual = result["per_sample"][key]
        if expected.dtype == bool:
            np.testing.assert_array_equal(actual, expected, err_msg=key)
        else:
            np.testing.assert_allclose(actual, expected, rtol=rtol, atol=atol, err_msg=key)
    for key in SUMMARY_KEYS:
        assert result[key] == pytest.approx(ref_summary[key], rel=rtol, abs=atol), key


CONE = [label(0.1), label(0.2), label(0.3)]  # slopes 0.1..0.3, mean 0.2, width 0.2


def one(pred, labels=CONE):
    """Per-sample metrics of a single prediction against one cone, as Python scalars."""
    ps = per_sample_metrics(np.array([pred]), np.array([0]), [np.array(labels)])
    return {k: v[0].item() for k, v in ps.items()}
