"""Distributions of a dataset's labels and bookkeeping, as figures (matplotlib, Agg).

Per finger and configuration: the label angle (the mean label's angle from straight into the
pad, `vistac_learn.metrics.directions.angles_deg`, the metrics' convention), the cone width (the
spread of the presses' angles) and the force magnitude |F| of the presses, each by object family
and by split; the rejected draws and grasps by reason; the image effects' draws (camera,
lighting, appearance) where the dataset has any.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from vistac.dataset import FINGERS  # noqa: E402
from vistac.dataset.reader import DatasetTables  # noqa: E402
from vistac.dataset.schema import force_columns  # noqa: E402
from vistac_learn.metrics.directions import angles_deg, wrap_abs_deg  # noqa: E402

CORE_PREFIXES = ("config_id", "object_", "image", "split", "camera_x", "camera_y", "px_per_m",
                 "target_", "approach_", "push_", "tip_", "penetration_", "bbox_",
                 "force_clean_", "normal_", "grasp_effect_fallbacks", "redraws", "n_grasps",
                 "n_kept", "sheet_", "recording")
"""Configs columns that are not draws of an image effect."""
MAX_EFFECT_PANELS = 16


def label_stats(tables: DatasetTables) -> pd.DataFrame:
    """Per configuration and finger: split, family, label angle (deg), cone width (deg) and the
    presses' median |F| (N; NaN without forces). One row per (configuration, finger)."""
    c = tables.configs
    n = len(c)
    force = _press_magnitudes(tables)
    cid = c["config_id"].to_numpy() if "config_id" in c else np.arange(n)
    split = c["split"].astype(str).to_numpy() if "split" in c else np.full(n, "-")
    family = c["object_family"].astype(str).to_numpy() if "object_family" in c else \
        c["object_id"].astype(str).to_numpy() if "object_id" in c else np.full(n, "-")
    parts = []
    for f in FINGERS:
        angle, width = cone_angles(tables.cones.get(f, []), n)
        mag = force.get(f, {})
        parts.append(pd.DataFrame({
            "finger": f, "row": np.arange(n), "config_id": cid, "split": split,
            "family": family, "angle_deg": angle, "cone_width_deg": width,
            "force_n": [mag.get(k, np.nan) for k in cid.tolist()]}))
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()


def cone_angles(cones: list[np.ndarray], n: int) -> tuple[np.ndarray, np.ndarray]:
    """(n,) angle of each configuration's mean label (`mean_label`) and (n,) its cone width
    (range of the presses' angles around it), degrees; NaN for a configuration without labels."""
    angle, width = np.full(n, np.nan), np.full(n, np.nan)
    sizes = np.array([len(cones[r]) if r < len(cones) else 0 for r in range(n)], int)
    have = np.flatnonzero(sizes > 0)
    if not len(have):
        return angle, width
    labels = np.concatenate([cones[r] for r in have])
    starts = np.r_[0, np.cumsum(sizes[have])[:-1]]
    mean = np.add.reduceat(labels, starts, axis=0) / sizes[have, None]
    norm = np.hypot(mean[:, 0], mean[:, 1])
    mean = np.where(norm[:, None] > 1e-12, mean / np.maximum(norm, 1e-300)[:, None],
                    np.array([0.0, -1.0]))
    angle[have] = angles_deg(mean[:, 0], -mean[:, 1])
    rel = angles_deg(labels[:, 0], -labels[:, 1]) - np.repeat(angle[have], sizes[have])
    rel = (rel + 180.0) % 360.0 - 180.0
    width[have] = np.maximum.reduceat(rel, starts) - np.minimum.reduceat(rel, starts)
    return angle, width


def _press_magnitudes(tables: DatasetTables) -> dict[str, dict]:
    p = tables.presses
    out: dict[str, dict] = {}
    for f in FINGERS:
        cols = force_columns(f)
        if "config_id" not in p or not set(cols) <= set(p.columns):
            continue
        mag = np.linalg.norm(p[cols].apply(pd.to_numeric, errors="coerce").to_numpy(float),
                             axis=1)
        out[f] = pd.Series(mag).groupby(p["config_id"].to_numpy()).median().to_dict()
    return out


def _hist(ax, stats: pd.DataFrame, column: str, by: str, bins: np.ndarray) -> None:
    for key, g in stats.groupby(by):
        v = g[column].to_numpy(float)
        v = v[np.isfinite(v)]
        if len(v):
            ax.hist(v, bins=bins, histtype="step", weights=np.full(len(v), 1 / len(v)),
                    label=f"{key} ({len(v)})")


METRICS = (("angle_deg", "label angle (deg from straight into the pad)"),
           ("cone_width_deg", "cone width (deg, presses' angle range)"),
           ("force_n", "|F| of the presses (N, median per configuration)"))


def plot_labels(stats: pd.DataFrame, by: str, out: Path) -> bool:
    """One figure: rows fingers, columns the label metrics, a histogram per `by` group.
    Returns False (nothing written) without any finite value."""
    if stats.empty or not np.isfinite(stats["angle_deg"].to_numpy(float)).any():
        return False
    fig, axes = plt.subplots(len(FINGERS), len(METRICS), figsize=(13, 6.2), squeeze=False)
    for i, f in enumerate(FINGERS):
        s = stats[stats["finger"] == f]
        for j, (col, title) in enumerate(METRICS):
            ax = axes[i, j]
            v = stats[col].to_numpy(float)
            v = v[np.isfinite(v)]
            if not len(v):
                ax.set_axis_off()
                ax.set_title(f"{f}: no {col.split('_')[0]} values", fontsize=9)
                continue
            lo, hi = np.percentile(v, [0.5, 99.5]) if len(v) > 20 else (v.min(), v.max())
            bins = np.linspace(lo, hi + 1e-9, 41)
            _hist(ax, s, col, by, bins)
            ax.set_title(f"{f}: {title}", fontsize=9)
            ax.tick_params(labelsize=8)
        axes[i, 0].legend(fontsize=7, title=by, title_fontsize=7)
        axes[i, 0].set_ylabel("share of the group's configurations", fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=80)
    plt.close(fig)
    return True


def plot_reasons(reasons: dict[str, dict[str, int]], out: Path) -> bool:
    """Horizontal bars of counts by reason, one panel per title (e.g. rejected draws, rejected
    grasps); False (nothing written) when every panel is empty."""
    panels = {k: v for k, v in reasons.items() if v}
    if not panels:
        return False
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 0.4 * max(
        len(v) for v in panels.values()) + 1.2), squeeze=False)
    for ax, (title, counts) in zip(axes[0], panels.items(), strict=True):
        keys = sorted(counts, key=counts.get)
        ax.barh(keys, [counts[k] for k in keys], color="0.4")
        for y, k in enumerate(keys):
            ax.text(counts[k], y, f" {counts[k]}", va="center", fontsize=8)
        ax.set_title(title, fontsize=9)
        ax.tick_params(labelsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=80)
    plt.close(fig)
    return True


def effect_columns(configs: pd.DataFrame) -> list[str]:
    """Numeric configs columns drawn by image effects (camera, lighting, appearance) that
    vary across the dataset."""
    out = []
    for col in configs.columns:
        if col.startswith(CORE_PREFIXES) or not pd.api.types.is_numeric_dtype(configs[col]):
            continue
        v = configs[col].to_numpy(float)
        v = v[np.isfinite(v)]
        if len(v) > 1 and v.std() > 0:
            out.append(col)
    return out[:MAX_EFFECT_PANELS]


def plot_effects(configs: pd.DataFrame, out: Path) -> list[str]:
    """Histograms of the image effects' draws; returns the columns shown (none: no file)."""
    cols = effect_columns(configs)
    if not cols:
        return []
    n = len(cols)
    ncol = min(4, n)
    fig, axes = plt.subplots(-(-n // ncol), ncol, figsize=(3.3 * ncol, 2.3 * -(-n // ncol)),
                             squeeze=False)
    for ax, col in zip(axes.flat, cols, strict=False):
        v = configs[col].to_numpy(float)
        ax.hist(v[np.isfinite(v)], bins=30, color="0.4")
        ax.set_title(col, fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[n:]:
        ax.set_axis_off()
    fig.tight_layout()
    fig.savefig(out, dpi=80)
    plt.close(fig)
    return cols


def angle_summary(stats: pd.DataFrame) -> dict[str, dict[str, float]]:
    """Per finger: median label angle, median |angle|, median cone width, median |F|."""
    out = {}
    for f, s in stats.groupby("finger"):
        def med(v):
            v = np.asarray(v, float)
            v = v[np.isfinite(v)]
            return float(np.median(v)) if len(v) else float("nan")
        out[str(f)] = {"angle_deg": med(s["angle_deg"]),
                       "abs_angle_deg": med(wrap_abs_deg(s["angle_deg"].to_numpy(float))),
                       "cone_width_deg": med(s["cone_width_deg"]), "force_n": med(s["force_n"])}
    return out
