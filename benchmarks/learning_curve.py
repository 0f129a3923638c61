"""Learning curve on the headline dataset: accuracy against training configurations and minutes.

Dataset: `vistac generate --n 20000 --noise 0.05 --seed 21 --split-by object` (or ``--data``).
For each training-set size (nested seeded subsets of the train split, `--train-fraction`) it
trains two recipes, both fingers:

- the default recipe (`vistac train` with no options: pinchnet on the pinch view), and
- the previous default (tipnet on the tip view, same optimiser and augmentation),

and scores each on the whole test split (held-out objects), beside the references that need no
training: the noise floor (the dataset's noise-free forces scored like a prediction), the pinch
baseline (image-only contact geometry) and the training split's mean label.

Epochs: every run on 1000 configurations or more gets at least as many optimiser steps as the
default recipe on a 3000-configuration dataset (15 epochs x 2059 training configurations of
`vistac generate --n 3000 --noise 0.05 --seed 21 --split-by object`: 975 steps of 32, about
``--sample-budget`` 31000 samples): ``epochs = max(--min-epochs, ceil(budget / n))``, at most
``--max-epochs``, since on small sets every epoch's validation pass over the whole validation
split costs more than the training pass (300 configurations: 30 epochs, 300 steps). Each run's
best epoch (chosen on the validation split) is reported beside its epochs, with the validation
angle half-way and at the best epoch, so a reader sees whether more epochs would have helped.

Memory stays flat as the training set grows: images are decoded per batch. Training wall and
CPU seconds are recorded per run (`learnbench.run_entry`); on a shared machine the CPU seconds
are the comparable figure.

Writes ``learning_curve.md`` / ``.json`` / ``.png`` into ``--out``; reruns resume.

Usage:
    python benchmarks/learning_curve.py --out bench/curve
    python benchmarks/learning_curve.py --out bench/curve --sizes 300 1000 3000 --data D
"""

from __future__ import annotations

import argparse
import csv
import math
import resource
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from learnbench import (
    ensure_dataset,
    fmt,
    headline_data,
    mean_entry,
    reference_entries,
    run_entry,
    save,
    slug,
)
from matplotlib.ticker import ScalarFormatter

from vistac.dataset import open_tables
from vistac_learn.train.config import TrainCfg
from vistac_learn.train.run_folder import finished

RECIPES = (("default (pinchnet, pinch view)", {}),
           ("previous default (tipnet, tip view)", {"model": "tipnet", "variant": "tip"}))


def epochs_for(n_train: int, sample_budget: int, min_epochs: int, max_epochs: int) -> int:
    """Epochs of a run on `n_train` configurations: enough to see `sample_budget` samples,
    within [min_epochs, max_epochs]."""
    return int(min(max_epochs, max(min_epochs, math.ceil(sample_budget / n_train))))


def val_trace(run: Path, fingers=("index", "thumb")) -> list[float]:
    """The validation median angle to the cone mean per epoch (mean of the fingers)."""
    with (run / "metrics.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    return [float(np.mean([float(r[f"val_{f}_angle_to_mean_median_deg"]) for f in fingers]))
            for r in rows]


def _ref_deg(ref: dict) -> float:
    return float(np.mean([m["angle_to_mean_median_deg"] for m in ref["metrics"].values()]))


def plot(rows: list[dict], refs: list[dict], path: Path) -> None:
    """Test accuracy against training configurations and against training CPU minutes (log
    axes), with the references (no training) as horizontal lines."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for colour, name in zip(colours, dict.fromkeys(r["recipe"] for r in rows), strict=False):
        rs = sorted((r for r in rows if r["recipe"] == name), key=lambda r: r["n_train"])
        for ax, key, scale, lines in ((axes[0], "n_train", 1, ("o-", "s--")),
                                      (axes[1], "train_cpu_s", 1 / 60, ("o", "s"))):
            x = [r[key] * scale for r in rs]  # time is not monotonic in size: points only
            ax.plot(x, [r["index_deg"] for r in rs], lines[0], color=colour,
                    label=f"{name}: index")
            ax.plot(x, [r["thumb_deg"] for r in rs], lines[1], color=colour,
                    label=f"{name}: thumb")
        for r in rs:  # each point's training configurations, on the time panel
            axes[1].annotate(f"{r['n_train']}", (r["train_cpu_s"] / 60, r["index_deg"]),
                             fontsize=6, xytext=(3, 3), textcoords="offset points")
    values = [r[k] for r in rows for k in ("index_deg", "thumb_deg")]
    top = 1.6 * max(values) if values else None  # the mean label stays far above the models
    for ref, style in zip(refs, (":", "--", "-."), strict=False):
        deg = _ref_deg(ref)
        m = ref["metrics"]
        off = " (above the plot)" if top is not None and deg > top else ""
        for ax in axes:
            ax.axhline(deg, color="grey", ls=style, lw=1,
                       label=f"{ref['label']}: {m['index']['angle_to_mean_median_deg']:.2f} / "
                       f"{m['thumb']['angle_to_mean_median_deg']:.2f}{off}")
    for ax, label in ((axes[0], "training configurations"),
                      (axes[1], "training CPU minutes (1 torch thread)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(ScalarFormatter())
        ax.yaxis.set_minor_formatter(ScalarFormatter())
        ax.tick_params(axis="y", which="minor", labelsize=6)
        ax.set_xlabel(label)
        ax.set_ylabel("median angle to cone mean, test (deg)")
        ax.grid(alpha=0.3, which="both")
        if top is not None:
            floor = min([*values, *(_ref_deg(r) for r in refs)])
            ax.set_ylim(0.85 * floor, top)
    axes[0].legend(fontsize=6, title="index / thumb (deg)", title_fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def report(rows: list[dict], refs: list[dict], out: Path, data: Path, settings: dict,
           missing: list[str] = ()) -> None:
    """Table, JSON and plot of the runs so far."""
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    head = ["recipe", "train configs", "epochs (best)", "optimiser steps", "index °",
            "thumb °", "index % in cone", "val ° half-way -> best", "train wall min",
            "train CPU min"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for r in sorted(rows, key=lambda r: (r["recipe"], r["n_train"])):
        trace = r["val_deg"]
        lines.append("| " + " | ".join([
            r["recipe"], str(r["n_train"]), f"{r['epochs']} ({r['best_epoch']})",
            str(r["steps"]), fmt(r["index_deg"]), fmt(r["thumb_deg"]), fmt(r["index_in_cone"]),
            f"{fmt(trace[len(trace) // 2 - 1] if len(trace) > 1 else trace[0])} -> "
            f"{fmt(trace[r['best_epoch'] - 1])}",
            fmt((r["train_wall_s"] or float("nan")) / 60),
            fmt((r["train_cpu_s"] or float("nan")) / 60)]) + " |")
    for ref in refs:
        m = ref["metrics"]
        lines.append("| " + " | ".join([
            ref["label"], "-", "-", "-", fmt(m["index"]["angle_to_mean_median_deg"]),
            fmt(m["thumb"]["angle_to_mean_median_deg"]), fmt(m["index"]["in_cone_pct"]),
            "-", "-", "-"]) + " |")
    md = "\n".join(lines) + (
        f"\n\nPeak resident memory of this benchmark process: {peak_mib:.0f} MiB (each run's "
        "`peak_rss_mib` in the JSON is this process's peak after it; runs a resumed report did "
        "not train itself add nothing).")
    if missing:
        md += "\n\nNot trained (no result): " + ", ".join(missing) + "."
    plot(rows, refs, out / "learning_curve.png")
    save(out, "learning_curve", {"dataset": str(data),
                                 "settings": settings, "rows": rows, "references": refs,
                                 "missing": list(missing), "peak_rss_mib": peak_mib}, md,
         datasets=(data,))


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--data", type=Path, help="dataset (default: generated into <out>/data)")
    p.add_argument("--n", type=int, default=20000, help="configurations to generate")
    p.add_argument("--seed", type=int, default=21, help="seed of the generated dataset")
    p.add_argument("--sizes", type=int, nargs="+", default=[300, 1000, 3000, 10000, 0],
                   help="training configurations per point (0: the whole train split)")
    p.add_argument("--recipes", nargs="+", default=[name for name, _ in RECIPES],
                   choices=[name for name, _ in RECIPES], metavar="RECIPE",
                   help="recipes to train, in this order (each over all sizes, small first)")
    p.add_argument("--sample-budget", type=int, default=31000,
                   help="training samples seen per run at least (the default recipe's on 3000 "
                   "configurations: 15 epochs x 2059)")
    p.add_argument("--min-epochs", type=int, default=3)
    p.add_argument("--max-epochs", type=int, default=30,
                   help="epochs at most (small sets: validation dominates the cost)")
    p.add_argument("--no-train", action="store_true",
                   help="report the finished runs only; list the others as missing")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    data = args.data or ensure_dataset(args.out / "data", headline_data(args.n, args.seed))
    n_all = len(open_tables(data).rows("train"))
    sizes = sorted({n_all if size <= 0 or size >= n_all else size for size in args.sizes})
    refs = [*reference_entries(data), mean_entry(data)]
    settings = {k: str(v) for k, v in vars(args).items()}
    kwargs = dict(RECIPES)
    rows, missing = [], []
    for name in args.recipes:
        for n in sizes:
            frac = n / n_all
            epochs = epochs_for(n, args.sample_budget, args.min_epochs, args.max_epochs)
            label = f"{name} n{n}"
            if args.no_train and not finished(args.out / "runs" / slug(label), epochs):
                missing.append(f"{label} ({epochs} epochs)")
                continue
            # scored on the plain view (tta=False), as the curve's first runs were, so that
            # every point is measured alike
            e = run_entry(data, args.out, label, "default", not args.quiet,
                          finger="both", train_fraction=frac, epochs=epochs, tta=False,
                          **kwargs[name])
            m = e["metrics"]
            n_train = e["n_train"]
            rows.append({
                "recipe": name, "n_train": n_train,
                "index_deg": m["index"]["angle_to_mean_median_deg"],
                "thumb_deg": m["thumb"]["angle_to_mean_median_deg"],
                "index_in_cone": m["index"]["in_cone_pct"],
                "thumb_in_cone": m["thumb"]["in_cone_pct"],
                "train_s": e["train_s"], "train_wall_s": e["train_wall_s"],
                "train_cpu_s": e["train_cpu_s"], "epochs": e["epochs"],
                "best_epoch": e["best_epoch"],
                "steps": e["epochs"] * math.ceil(n_train / TrainCfg().batch_size),
                "val_deg": val_trace(Path(e["run"])), "macs": e["macs"],
                "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024})
            report(rows, refs, args.out, data, settings, missing)  # after every run
    if not rows:
        report(rows, refs, args.out, data, settings, missing)
    return 0


if __name__ == "__main__":
    sys.exit(main())
