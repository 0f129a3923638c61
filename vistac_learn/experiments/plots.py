"""The experiments' figures: mean +- std (over seeds) error bars."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def _series(summary: list[dict], x: str, metric: str, **match) -> tuple[list, list, list]:
    pts = [(s[x], s[f"{metric}_mean"], s[f"{metric}_std"]) for s in summary
           if all(s[k] == v for k, v in match.items()) and math.isfinite(s[f"{metric}_mean"])]
    pts.sort()
    return [p[0] for p in pts], [p[1] for p in pts], [p[2] for p in pts]


def _save(fig, path: Path) -> None:
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    tmp.replace(path)


def plot_sim2real(summary: list[dict], path: Path) -> None:
    """Real test angle against the fraction of real training data: from scratch and fine-tuned
    (error bars), the sim-only model as a horizontal band.

    Args:
        summary: Rows of results.csv (``arm``, ``fraction``, ``test_angle_deg_mean|std``).
        path: PNG to write.
    """
    fig, ax = plt.subplots(figsize=(5.5, 3.8), dpi=120)
    styles = {"scratch": ("from scratch", "tab:blue", "o"),
              "finetune": ("sim-pretrained, fine-tuned", "tab:orange", "s")}
    for arm, (label, colour, marker) in styles.items():
        xs, ys, es = _series(summary, "fraction", "test_angle_deg", arm=arm)
        if xs:
            ax.errorbar(xs, ys, yerr=es, marker=marker, color=colour, capsize=4, label=label)
    _, ys, es = _series(summary, "fraction", "test_angle_deg", arm="sim-only")
    if ys:
        ax.axhline(ys[0], color="tab:red", ls="--", label="sim only (zero-shot)")
        ax.axhspan(ys[0] - es[0], ys[0] + es[0], color="tab:red", alpha=0.12)
    ax.set_xscale("log")
    ticks = sorted({s["fraction"] for s in summary if s["arm"] != "sim-only"})
    if ticks:
        ax.minorticks_off()
        ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
    ax.set_xlabel("fraction of the real training split")
    ax.set_ylabel("real test: median angle to cone mean (deg)")
    ax.set_title("sim-to-real: mean ± std over seeds", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    _save(fig, path)


def plot_label_noise(summary: list[dict], path: Path) -> None:
    """Test angle against the label-noise level, to the clean labels and to the noisy cones
    (error bars), and how far the noisy labels themselves are from the clean ones.

    Args:
        summary: Rows of results.csv (``level`` and the ``*_mean|std`` columns).
        path: PNG to write.
    """
    fig, ax = plt.subplots(figsize=(5.5, 3.8), dpi=120)
    for metric, label, colour, marker in (
            ("clean_angle_deg", "model vs clean labels", "tab:blue", "o"),
            ("noisy_angle_deg", "model vs noisy cone mean", "tab:orange", "s"),
            ("label_angle_deg", "noisy labels vs clean labels", "0.5", "")):
        xs, ys, es = _series(summary, "level", metric)
        if xs:
            ax.errorbar(xs, ys, yerr=es, marker=marker or None, color=colour, capsize=4,
                        label=label, ls="--" if not marker else "-")
    ax.set_xlabel("label noise level (relative force std)")
    ax.set_ylabel("test: median angle (deg)")
    ax.set_title("label noise: mean ± std over seeds", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    _save(fig, path)
