"""Learning curve on the headline dataset: accuracy against training configurations, with time.

Dataset: `vistac generate --n 20000 --noise 0.05 --split-by object` (or ``--data``). For each
training-set size (nested seeded subsets of the train split, `--train-fraction`) it trains

- the default recipe (tipnet on the tip view, both fingers),
- one of the study's nets (default SmallConv, 227 px tip view) under the same recipe, and
- that net under the study's protocol (edge-index, index finger, batches of 5;
  ``--study-rotations`` random angles per configuration and epoch) up to
  ``--study-protocol-max-n`` configurations: on 2 CPU cores its batches of 5 make a larger run
  take hours, and it stays at the mean predictor at these budgets,

and scores each on the whole test split (held-out objects), beside two references that need no
training: the training split's mean label and the geometric baseline. Memory stays flat as the
training set grows: images are decoded per batch and nothing per rotation is stored; the
process's peak resident memory after each run is recorded.

Writes ``learning_curve.md`` / ``.json`` / ``.png`` into ``--out``; reruns resume.

Usage:
    python benchmarks/learning_curve.py --out bench/curve
    python benchmarks/learning_curve.py --out bench/curve --sizes 300 1000 3000 --data D
"""

from __future__ import annotations

import argparse
import resource
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from learnbench import (  # noqa: E402
    baseline_entry,
    ensure_dataset,
    fmt,
    headline_data,
    machine,
    mean_entry,
    run_entry,
    save,
)
from matplotlib.ticker import ScalarFormatter  # noqa: E402

from vistac.dataset import open_dataset  # noqa: E402
from vistac_learn.train.config import protocol_cfg  # noqa: E402


def plot(rows: list[dict], refs: list[dict], path: Path) -> None:
    """Accuracy and training time against training configurations (log x), with the reference
    predictors (no training) as horizontal lines."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for colour, name in zip(colours, dict.fromkeys(r["recipe"] for r in rows), strict=False):
        rs = sorted((r for r in rows if r["recipe"] == name), key=lambda r: r["n_train"])
        x = [r["n_train"] for r in rs]
        a.plot(x, [r["index_deg"] for r in rs], "o-", color=colour, label=f"{name}: index")
        if rs[0]["thumb_deg"] is not None:
            a.plot(x, [r["thumb_deg"] for r in rs], "s--", color=colour, label=f"{name}: thumb")
        b.plot(x, [r["train_s"] / 60 for r in rs], "o-", color=colour, label=name)
    for ref, style in zip(refs, (":", "-."), strict=False):
        deg = ref["metrics"]["index"]["angle_to_mean_median_deg"]
        a.axhline(deg, color="grey", ls=style, lw=1, label=f"{ref['label']}: index {deg:.1f}")
    for ax in (a, b):
        ax.set_xscale("log")
        ax.set_xlabel("training configurations")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    a.set_yscale("log")
    a.yaxis.set_major_formatter(ScalarFormatter())
    a.yaxis.set_minor_formatter(ScalarFormatter())
    a.set_ylabel("median angle to cone mean, test (deg)")
    b.set_ylabel("training time (min, 2 CPU cores)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def report(rows: list[dict], refs: list[dict], out: Path, data: Path) -> None:
    """Table, JSON and plot of the runs so far."""
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    head = ["recipe", "train configs", "index °", "thumb °", "index % in cone",
            "index % correct y", "train min", "best epoch"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for r in rows:
        lines.append("| " + " | ".join([
            r["recipe"], str(r["n_train"]), fmt(r["index_deg"]), fmt(r["thumb_deg"]),
            fmt(r["index_in_cone"]), fmt(r["index_correct_y"]), fmt(r["train_s"] / 60),
            f"{r['best_epoch']}/{r['epochs']}"]) + " |")
    md = "\n".join(lines) + (
        f"\n\nPeak resident memory of this benchmark process: {peak_mib:.0f} MiB (each run's "
        "`peak_rss_mib` in the JSON is this process's peak after it; runs a resumed report did "
        "not train itself add nothing).")
    for ref in refs:
        m = ref["metrics"]
        md += (f"\n\n{ref['label']} on the same test split: index "
               f"{fmt(m['index']['angle_to_mean_median_deg'])} deg, thumb "
               f"{fmt(m['thumb']['angle_to_mean_median_deg'])} deg.")
    plot(rows, refs, out / "learning_curve.png")
    save(out, "learning_curve", {"dataset": str(data), "machine": machine(), "rows": rows,
                                 "references": refs, "peak_rss_mib": peak_mib}, md)


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--data", type=Path, help="dataset (default: generated into <out>/data)")
    p.add_argument("--n", type=int, default=20000, help="configurations to generate")
    p.add_argument("--sizes", type=int, nargs="+", default=[300, 1000, 3000, 10000, 0],
                   help="training configurations per point (0: the whole train split)")
    p.add_argument("--study-model", default="smallconv")
    p.add_argument("--study-rotations", type=int, default=1)
    p.add_argument("--sample-budget", type=int, default=90000,
                   help="training samples seen per run at most: a run on n configurations "
                   "trains min(protocol epochs, max(3, budget / n)) epochs, so the large "
                   "sizes cost about what the default run on 3000 configurations costs "
                   "(0: the protocol's epochs everywhere)")
    p.add_argument("--study-protocol-max-n", type=int, default=1000,
                   help="largest training set trained under the study's protocol")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    data = args.data or ensure_dataset(args.out / "data", headline_data(args.n))
    n_train = len(open_dataset(data).rows("train"))
    sizes = [n_train if size <= 0 or size >= n_train else size for size in args.sizes]
    plan = [(n, name, protocol, kw) for name, protocol, kw in (
        ("default (tipnet, tip)", "default", {"finger": "both"}),
        (f"{args.study_model} (default recipe, tip)", "default",
         {"finger": "both", "model": args.study_model})) for n in sizes]
    plan.sort(key=lambda p: p[0])  # size by size: both recipes of a size, then the next size
    plan += [(n, f"{args.study_model} (study protocol)", "study",
              {"model": args.study_model, "rotations": "random",
               "n_rotations": args.study_rotations})
             for n in sizes if n <= args.study_protocol_max_n]
    refs = [mean_entry(data), baseline_entry(data, args.out)]
    rows = []
    for n, name, protocol, kw in plan:
        frac = n / n_train
        epochs = protocol_cfg(protocol, "", "").epochs
        if args.sample_budget:
            epochs = min(epochs, max(3, round(args.sample_budget / n)))
        e = run_entry(data, args.out, f"{name} n{n}", protocol, not args.quiet,
                      train_fraction=frac, epochs=epochs, **kw)
        m = e["metrics"]
        rows.append({
            "recipe": name, "n_train": e["n_train"] if frac == 1 else n,
            "index_deg": m["index"]["angle_to_mean_median_deg"],
            "thumb_deg": m["thumb"]["angle_to_mean_median_deg"] if "thumb" in m else None,
            "index_in_cone": m["index"]["in_cone_pct"],
            "index_correct_y": m["index"]["correct_y_pct"],
            "train_s": e["train_s"], "epochs": e["epochs"], "best_epoch": e["best_epoch"],
            "macs": e["macs"],
            "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024})
        report(rows, refs, args.out, data)  # after every run: a stopped benchmark keeps its points
    return 0


if __name__ == "__main__":
    sys.exit(main())
