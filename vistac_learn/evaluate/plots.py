"""PNG figures of an evaluation: predictions against cones, error histogram, rotation spread.

Angles are those of `vistac_learn.metrics`: the direction (r_y, r_z) as atan2(r_y, -r_z) in
degrees, 0 straight into the sensor pad.
"""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from vistac.dataset.files import atomic_write_bytes  # noqa: E402


def save_png(fig, path: Path) -> None:
    """Save `fig` as a PNG at `path` whole or not at all (a temporary file and a rename), and
    close it."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.hypot(v[..., 0], v[..., 1])[..., None]
    return np.where(n > 0, v / np.where(n > 0, n, 1), np.array([0.0, -1.0]))


def plot_cones(
    pred: np.ndarray,
    cone_of: np.ndarray,
    in_cone: np.ndarray,
    label_sets: list[np.ndarray],
    cones: dict[str, np.ndarray],
    titles: list[str],
    path: Path,
    n_show: int = 8,
    seed: int = 0,
) -> Path:
    """Sample configurations: their labels, cone and the predictions (like the study's figures).

    Each panel is the (r_y, r_z) plane (r_z down = into the pad): grey lines are the repeats'
    unit labels, the shaded wedge the cone between its edge slopes, the dashed line the cone
    mean, dots the unit directions of the predictions (one per rotation), green inside the cone,
    red outside.

    Args:
        pred: (M, 2) predictions.
        cone_of: (M,) index of each prediction's cone.
        in_cone: (M,) whether each prediction lies in its cone (`metrics` per-sample value).
        label_sets: (K_i, 2) labels per cone.
        cones: `metrics.cone_stats` output.
        titles: Title per cone (e.g. its config id).
        path: PNG to write.
        n_show: Number of panels.
        seed: Seed of the choice of configurations.

    Returns:
        The PNG path.
    """
    n_cones = len(label_sets)
    rng = np.random.default_rng(seed)
    pick = np.sort(rng.choice(n_cones, size=min(n_show, n_cones), replace=False))
    cols = min(4, len(pick)) or 1
    rows = int(np.ceil(len(pick) / cols)) or 1
    fig, axes = plt.subplots(rows, cols, figsize=(3 * cols, 3 * rows), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, c in zip(axes.ravel(), pick, strict=False):
        ax.axis("on")
        labels = _unit(np.asarray(label_sets[c], float))
        lo, hi = np.radians(cones["angle_lo_deg"][c]), np.radians(cones["angle_hi_deg"][c])
        t = np.linspace(lo, hi, 30)
        wedge = np.concatenate([[[0, 0]], np.stack([np.sin(t), -np.cos(t)], 1), [[0, 0]]])
        ax.fill(wedge[:, 0], wedge[:, 1], color="tab:blue", alpha=0.2, lw=0)
        for y, z in labels:
            ax.plot([0, y], [0, z], color="0.4", lw=0.8)
        am = np.radians(cones["angle_mean_deg"][c])
        ax.plot([0, np.sin(am)], [0, -np.cos(am)], "k--", lw=1)
        mine = _unit(pred[cone_of == c])
        inside = np.asarray(in_cone)[cone_of == c].astype(bool)
        ax.scatter(mine[inside, 0], mine[inside, 1], s=12, color="tab:green", zorder=3)
        ax.scatter(mine[~inside, 0], mine[~inside, 1], s=12, color="tab:red", zorder=3)
        ax.set_xlim(-1.1, 1.1)
        ax.set_ylim(-1.1, 0.3)
        ax.set_aspect("equal")
        ax.axhline(0, color="0.8", lw=0.5)
        ax.axvline(0, color="0.8", lw=0.5)
        ax.set_title(f"{titles[c]}: {inside.mean() * 100:.0f}% in cone", fontsize=9)
        ax.set_xlabel("r_y", fontsize=8)
        ax.set_ylabel("r_z", fontsize=8)
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    save_png(fig, path)
    return path


def plot_error_hist(error_pct: np.ndarray, path: Path, label: str = "") -> Path:
    """Histogram of the slope error (%) on logarithmic bins; in-cone (zero) errors counted apart.

    Args:
        error_pct: (M,) errors in %, 0 inside the cone.
        path: PNG to write.
        label: Title prefix.

    Returns:
        The PNG path.
    """
    err = np.asarray(error_pct, float)
    pos = err[err > 0]
    fig, ax = plt.subplots(figsize=(6, 3.5))
    if pos.size:
        lo, hi = max(pos.min(), 1e-3), max(pos.max(), 1e-2)
        bins = np.logspace(np.log10(lo), np.log10(hi) + 1e-9, 40)
        ax.hist(np.clip(pos, lo, hi), bins=bins, color="tab:blue")
        ax.axvline(np.median(err), color="k", ls="--", lw=1,
                   label=f"median (all) {np.median(err):.3g}%")
        ax.axvline(np.median(pos), color="tab:red", ls="--", lw=1,
                   label=f"median (not in cone) {np.median(pos):.3g}%")
        ax.legend(fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel("error |m_edge - m| / |m| (%)")
    ax.set_ylabel("predictions")
    ax.set_title(f"{label} {len(err) - pos.size} of {len(err)} predictions in the cone (error 0)",
                 fontsize=9)
    fig.tight_layout()
    save_png(fig, path)
    return path


def plot_rotation_spread(
    angle_deg: np.ndarray,
    cone_of: np.ndarray,
    cones: dict[str, np.ndarray],
    path: Path,
    label: str = "",
) -> Path:
    """Predicted direction of every rotation per configuration, against the cone.

    Configurations are sorted by their cone-mean angle; the grey bar is the cone (edge to
    edge), the black tick its mean, the dots the predictions of the configuration's rotated
    images. The title gives the median over configurations of the circular standard deviation
    of the predictions across rotations.

    Args:
        angle_deg: (M,) predicted angles atan2(r_y, -r_z) in degrees.
        cone_of: (M,) cone index of each prediction.
        cones: `metrics.cone_stats` output.
        path: PNG to write.
        label: Title prefix.

    Returns:
        The PNG path.
    """
    n = len(cones["angle_mean_deg"])
    order = np.argsort(cones["angle_mean_deg"])
    x_of = np.empty(n, int)
    x_of[order] = np.arange(n)
    fig, ax = plt.subplots(figsize=(max(6, 0.12 * n + 2), 4))
    ax.vlines(x_of, cones["angle_lo_deg"], cones["angle_hi_deg"], color="0.7", lw=4)
    ax.scatter(x_of, cones["angle_mean_deg"], marker="_", color="k", s=40, zorder=3)
    ax.scatter(x_of[cone_of], angle_deg, s=4, color="tab:orange", alpha=0.7, zorder=4)
    a = np.radians(angle_deg)
    spreads = []
    for c in range(n):
        sel = cone_of == c
        if sel.sum() > 1:
            r = np.hypot(np.cos(a[sel]).mean(), np.sin(a[sel]).mean())
            spreads.append(np.degrees(np.sqrt(-2 * np.log(max(r, 1e-12)))))
    spread = float(np.median(spreads)) if spreads else 0.0
    ax.set_xlabel("configuration (sorted by cone mean)")
    ax.set_ylabel("direction atan2(r_y, -r_z) (deg)")
    ax.set_title(f"{label} spread across rotations: median circular std {spread:.2f} deg",
                 fontsize=9)
    fig.tight_layout()
    save_png(fig, path)
    return path
