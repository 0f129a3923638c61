"""Accuracy against cost for the model zoo, on one split: MACs, train time, inference, accuracy.

Every model is trained with the default recipe (pinch view: the model is the backbone reading
each fingertip crop's contact point and normal, the label composed from them; crops rendered at
the model's own input size: 48 px for pinchnet and tipnet, 100 or 227 px for the study's nets)
on the same dataset and scored on its test split; ``--tip-models`` are also trained on the tip
view (crops, label regressed: tipnet there is the previous default). Before training, a few
training steps are timed; a model whose estimated training time exceeds ``--budget-min`` is not
trained (its MACs and speed are still reported, its accuracy is "-"). The estimate counts the
optimiser steps only (no rendering, no validation), so real runs take longer. Inference is
timed on batches of 64 samples (both fingers' crops) with torch's threads. The references that
need no training (noise floor, pinch baseline, mean label) are scored on the same test split.

Writes ``model_zoo.md`` / ``.json`` and ``model_zoo.png`` (Pareto fronts: accuracy against MACs
and against training time, the references as horizontal lines) into ``--out``; reruns resume.

Usage:
    python benchmarks/model_zoo.py --data bench/default/data --out bench/zoo
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import torch
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

from vistac.dataset import open_tables
from vistac_learn.models import count_macs
from vistac_learn.train.build import build_model, input_size
from vistac_learn.train.config import protocol_cfg

MODELS = ("pinchnet", "tipnet", "smallconv", "randomconv", "mobilenetv2-tiny", "resnet-tiny",
          "schoeconv100-v1", "schoeconv100-v3-fc160", "alexnet-1x1", "schoeconv227-v1")


def _timings(name: str, view: str, epochs: int, batch: int, n_train: int) -> dict:
    """MACs per sample, inference ms per sample, and an estimate of the training time (the
    optimiser steps alone)."""
    cfg = protocol_cfg("default", "", "", model=name, variant=view)
    model = build_model(cfg)
    s = input_size(cfg, model)
    macs = model.n_fingers * count_macs(model.net, (3, s, s))
    x = torch.rand(batch, 2, 3, s, s)
    side = torch.rand(batch, 2, model.side_features)
    y = torch.rand(batch, 4)
    opt = torch.optim.AdamW(model.parameters(), 1e-3)
    steps = []
    for _ in range(3):
        t0 = time.perf_counter()
        opt.zero_grad()
        ((model(x, side) - y) ** 2).mean().backward()
        opt.step()
        steps.append(time.perf_counter() - t0)
    model.eval()
    with torch.no_grad():
        xs = torch.rand(64, 2, 3, s, s)
        sides = torch.rand(64, 2, model.side_features)
        model(xs, sides)
        t0 = time.perf_counter()
        for _ in range(3):
            model(xs, sides)
        infer = (time.perf_counter() - t0) / (3 * 64)
    est = float(np.median(steps[1:])) * np.ceil(n_train / batch) * epochs
    return {"macs": int(macs), "input_size": s, "infer_ms": 1000 * infer,
            "est_train_min": est / 60, "params": sum(p.numel() for p in model.parameters())}


def pareto(xs: list[float], ys: list[float]) -> list[int]:
    """Indices of the points not beaten on both x and y (lower is better for both)."""
    idx = sorted(range(len(xs)), key=lambda i: (xs[i], ys[i]))
    front, best = [], np.inf
    for i in idx:
        if ys[i] < best:
            front.append(i)
            best = ys[i]
    return front


def _mean_deg(metrics: dict) -> float:
    """Median angle to the cone mean, averaged over the fingers."""
    return float(np.mean([m["angle_to_mean_median_deg"] for m in metrics.values()]))


def plot(rows: list[dict], refs: list[dict], path: Path) -> None:
    """Accuracy against MACs and against training time, Pareto fronts and references drawn."""
    done = [r for r in rows if r.get("deg") is not None]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, key, label in ((axes[0], "macs", "MACs per sample (both fingers)"),
                           (axes[1], "train_min", "training time (wall min, shared machine)")):
        xs, ys = [r[key] for r in done], [r["deg"] for r in done]
        ax.scatter(xs, ys)
        for r in done:
            ax.annotate(f"{r['model']} ({r['view']})", (r[key], r["deg"]), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")
        for ref, style in zip(refs, (":", "--", "-."), strict=False):
            deg = _mean_deg(ref["metrics"])
            ax.axhline(deg, color="grey", ls=style, lw=1, label=f"{ref['label']}: {deg:.2f}")
        front = pareto(xs, ys)
        ax.plot([xs[i] for i in front], [ys[i] for i in front], "r--", lw=1, label="Pareto front")
        ax.set_yscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("test: median angle to cone mean (deg, mean of fingers)", fontsize=8)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--data", type=Path, help="dataset (default: generated into <out>/data)")
    p.add_argument("--n", type=int, default=3000)
    p.add_argument("--models", nargs="+", default=list(MODELS),
                   help="backbones trained on the pinch view (the default recipe)")
    p.add_argument("--tip-models", nargs="*", default=["tipnet"],
                   help="models also trained on the tip view (tipnet: the previous default)")
    p.add_argument("--epochs", type=int, help="epochs per model (default: the recipe's)")
    p.add_argument("--budget-min", type=float, default=30.0,
                   help="train only models whose estimated training time is below this")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    data = args.data or ensure_dataset(args.out / "data", headline_data(args.n))
    base = protocol_cfg("default", str(data), "")
    epochs = args.epochs or base.epochs
    n_train = len(open_tables(data).rows("train"))
    refs = [*reference_entries(data), mean_entry(data)]
    plan = [(name, base.variant) for name in args.models] + [(n, "tip") for n in args.tip_models]
    rows = []
    for name, view in plan:
        r = {"model": name, "view": view,
             **_timings(name, view, epochs, base.batch_size, n_train)}
        label = f"{name} {view} view e{epochs}"
        trained = (args.out / "runs" / slug(label) / "metrics.csv").exists()
        if r["est_train_min"] <= args.budget_min or trained:
            e = run_entry(data, args.out, label, "default", not args.quiet, model=name,
                          variant=view, epochs=epochs)
            m = e["metrics"]
            r |= {"deg": _mean_deg(m),
                  "index_deg": m["index"]["angle_to_mean_median_deg"],
                  "thumb_deg": m["thumb"]["angle_to_mean_median_deg"],
                  "in_cone": float(np.mean([m[f]["in_cone_pct"] for f in m])),
                  "correct_y": float(np.mean([m[f]["correct_y_pct"] for f in m])),
                  "train_s_per_epoch": e["train_s_per_epoch"], "train_min": e["train_s"] / 60,
                  "train_cpu_s": e["train_cpu_s"], "epochs": e["epochs"],
                  "best_epoch": e["best_epoch"]}
        else:
            print(f"== {name} ({view}): estimated {r['est_train_min']:.0f} min > budget, "
                  "not trained", flush=True)
        rows.append(r)
        report(rows, refs, args.out, data, epochs)  # after every model: a stopped run keeps it
    return 0


def report(rows: list[dict], refs: list[dict], out: Path, data: Path, epochs: int) -> None:
    """Table, JSON and plot of the models so far."""
    head = ["model", "view", "input px", "params", "MACs/sample", "infer ms/sample",
            "train s/epoch", "train min", "train CPU s", "best epoch", "° index", "° thumb",
            "% in cone (mean of fingers)", "% correct y (mean of fingers)"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for r in rows:
        lines.append("| " + " | ".join([
            r["model"], r["view"], str(r["input_size"]), fmt(r["params"]),
            f"{r['macs'] / 1e6:.1f} M", fmt(r["infer_ms"]), fmt(r.get("train_s_per_epoch")),
            fmt(r.get("train_min", r["est_train_min"])) + ("" if "deg" in r else " (est.)"),
            fmt(r.get("train_cpu_s")),
            f"{r['best_epoch']}/{r['epochs']}" if "deg" in r else "-",
            fmt(r.get("index_deg")), fmt(r.get("thumb_deg")), fmt(r.get("in_cone")),
            fmt(r.get("correct_y"))]) + " |")
    for ref in refs:
        m = ref["metrics"]
        lines.append("| " + " | ".join([
            ref["label"], "-", "-", "-", "-", "-", "-", "-", "-", "-",
            fmt(m["index"]["angle_to_mean_median_deg"]),
            fmt(m["thumb"]["angle_to_mean_median_deg"]),
            fmt(float(np.mean([m[f]["in_cone_pct"] for f in m]))),
            fmt(float(np.mean([m[f]["correct_y_pct"] for f in m])))]) + " |")
    plot(rows, refs, out / "model_zoo.png")
    save(out, "model_zoo", {"dataset": str(data), "epochs": epochs,
                            "rows": rows, "references": refs}, "\n".join(lines),
         datasets=(data,))


if __name__ == "__main__":
    sys.exit(main())
