"""The reference study's protocol on a simulated dataset of the study's size (issue 4).

162 training, 34 validation and 34 test configurations (the study had 162 / 34 and no validation
split), 6 presses each with 5 % force noise, every image at the study's 20 rotations of 18
degrees; index finger, edge-index variant, CPU. For each model: train with the study's defaults
(Adam, MSE, lr 1e-4, weight decay 1e-5, batch 5) for ``--epochs`` epochs, pick the best epoch on
the validation split, score the test split (34 x 20 = 680 predictions); then the same for the
geometric baseline. Writes ``table.md`` (docs/study.md section 9 columns, angular columns, training
seconds per epoch, inference images/s) and ``results.json`` into ``--out``.

Re-running with the same ``--out`` reuses the dataset and finished runs, and resumes unfinished
ones.

Usage:
    .venv/bin/python benchmarks/learn_protocol.py --out bench/learn            # 20 epochs
    .venv/bin/python benchmarks/learn_protocol.py --out bench/learn --epochs 2  # quick
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch

import vistac
from vistac.dataset import SplitCfg, open_tables
from vistac.provenance import provenance
from vistac_learn.evaluate.config import EvaluateCfg
from vistac_learn.evaluate.run import evaluate_baseline, evaluate_run
from vistac_learn.metrics.scoring import ANGLE_COLUMNS, STUDY_COLUMNS
from vistac_learn.models import model_info
from vistac_learn.train.config import protocol_cfg
from vistac_learn.train.loop import train_run_folder
from vistac_sim.generate.config import GenerateCfg

DEFAULT_MODELS = ("schoeconv100-v3-fc160", "alexnet-1x1", "smallconv", "resnet-tiny")


def _dataset(args: argparse.Namespace) -> Path:
    """The dataset: --data, or generated (once) into <out>/data."""
    if args.data:
        return Path(args.data)
    path = Path(args.out) / "data"
    n = args.n_train + args.n_val + args.n_test
    man = path / "manifest.json"
    if man.exists() and json.loads(man.read_text()).get("complete"):
        return path
    cfg = GenerateCfg.from_preset(
        "clean", noise=args.noise, n=n, repeats=args.repeats, seed=args.seed,
        split=SplitCfg(fractions=(args.n_train / n, args.n_val / n, args.n_test / n)))
    t0 = time.perf_counter()
    vistac.generate(cfg, path, workers=args.gen_workers, resume=man.exists() or
                    (path / ".partial").exists())
    print(f"generated {path} in {time.perf_counter() - t0:.0f} s", flush=True)
    return path


def _epoch_rows(run: Path) -> list[dict]:
    path = run / "metrics.csv"
    if not path.exists():
        return []
    with path.open() as fh:
        return list(csv.DictReader(fh))


def _fmt(key: str, v: float) -> str:
    if key == "mse_mean":
        return f"{v:.2e}"
    return f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}"


def run_protocol(args: argparse.Namespace) -> dict:
    """Train and score every model and the baseline; return the results dict."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    data = _dataset(args)
    tables = open_tables(data)
    counts = {s: int((tables.configs["split"] == s).sum()) for s in ("train", "val", "test")}
    print(f"dataset {data}: {counts} configurations, {len(tables.presses)} presses", flush=True)
    entries = []
    for name in args.models:
        run = out / "runs" / name
        cfg = protocol_cfg("study", str(data), str(run), model=name, variant=args.variant,
                           epochs=args.epochs, batch_size=args.batch_size, lr=args.lr,
                           weight_decay=args.weight_decay, seed=args.seed,
                           n_rotations=args.n_rotations, device="cpu",
                           cache_dir=str(out / "cache"))
        done = len(_epoch_rows(run))
        if done < args.epochs:
            print(f"== {name}: training {args.epochs} epochs", flush=True)
            train_run_folder(cfg, resume=(run / "checkpoints" / "last.pt").exists(),
                             progress=not args.quiet)
        rows = _epoch_rows(run)
        res = evaluate_run(EvaluateCfg(run=str(run), device="cpu"))
        info = model_info(name, 1, 2)
        entries.append({
            "label": info.get("display", name), "model": name, "kind": "model",
            "metrics": res["metrics"]["index"],
            "train_s_per_epoch": float(np.mean([float(r["train_s"]) for r in rows])),
            "train_s_epochs": [float(r["train_s"]) for r in rows],
            "epoch_s_with_val": float(np.mean([float(r["epoch_s"]) for r in rows])),
            "images_per_s": res["images_per_s"], "best_epoch": res["epoch"],
            "epochs": len(rows), "params": info["params"], "macs": info["macs"],
            "input_size": info["input_size"],
        })
    print("== geometric baseline", flush=True)
    bl = evaluate_baseline(EvaluateCfg(baseline="geometric", data=str(data), rotations="fixed",
                                       n_rotations=args.n_rotations), out / "baseline")
    entries.append({"label": "geometric baseline (non-learned)", "model": "geometric",
                    "kind": "baseline", "metrics": bl["metrics"]["index"],
                    "train_s_per_epoch": None, "images_per_s": bl["images_per_s"],
                    "failures": bl["failures"]})
    machine = {"platform": platform.platform(), "processor": platform.processor(),
               "cpu_count": os.cpu_count(), "torch_threads": torch.get_num_threads(),
               "torch": torch.__version__, "python": platform.python_version()}
    settings = {k: v for k, v in vars(args).items()}
    settings["models"] = list(args.models)
    result = {"dataset": str(data), "split_counts": counts,
              "n_presses": len(tables.presses), "settings": settings, "machine": machine,
              "entries": entries}
    cols = STUDY_COLUMNS + ANGLE_COLUMNS
    head = ["model / setting", *(h for h, _ in cols), "train s/epoch", "inference img/s",
            "best epoch (val)"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for e in entries:
        cells = [e["label"], *(_fmt(k, e["metrics"][k]) for _, k in cols),
                 "-" if e["train_s_per_epoch"] is None else f"{e['train_s_per_epoch']:.0f}",
                 f"{e['images_per_s']:.0f}",
                 str(e.get("best_epoch", "-")) + (f"/{e['epochs']}" if "epochs" in e else "")]
        lines.append("| " + " | ".join(cells) + " |")
    table = "\n".join(lines)
    note = (f"Index finger, {args.variant}, {counts['train']} train / {counts['val']} val / "
            f"{counts['test']} test configurations x {args.n_rotations} rotations, "
            f"{args.repeats} presses, noise {args.noise}, {args.epochs} epochs, batch "
            f"{args.batch_size}, lr {args.lr}, weight decay {args.weight_decay}, seed "
            f"{args.seed}; CPU ({machine['cpu_count']} cores, {machine['torch_threads']} torch "
            "threads; timings depend on what else runs on the machine). Test metrics of the "
            "validation-selected epoch; errors and inaccuracies "
            "in %, angles in degrees. Train s/epoch excludes validation; inference img/s is "
            "batched (64) forward passes on the test pairs.")
    result["table"] = table
    (out / "table.md").write_text(table + "\n\n" + note + "\n")
    result["provenance"] = provenance([data])
    (out / "results.json").write_text(json.dumps(result, indent=2))
    print(table)
    print(note)
    return result


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--out", required=True, help="output folder (dataset, runs, table)")
    p.add_argument("--data", help="use this dataset instead of generating one")
    p.add_argument("--n-train", type=int, default=162)
    p.add_argument("--n-val", type=int, default=34)
    p.add_argument("--n-test", type=int, default=34)
    p.add_argument("--repeats", type=int, default=6)
    p.add_argument("--noise", type=float, default=0.05)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--gen-workers", type=int, default=1, help="processes for generation")
    p.add_argument("--models", nargs="+", default=list(DEFAULT_MODELS))
    p.add_argument("--variant", default="edge-index")
    p.add_argument("--epochs", type=int, default=20,
                   help="epochs per model (the study's 20; on 2 CPU cores the two ~1 GMAC "
                   "models take minutes per epoch, so --epochs 2 keeps all four near 30 min)")
    p.add_argument("--n-rotations", type=int, default=20)
    p.add_argument("--batch-size", type=int, default=5)
    p.add_argument("--lr", type=float, default=1e-4)
    p.add_argument("--weight-decay", type=float, default=1e-5)
    p.add_argument("--threads", type=int, help="torch CPU threads (default: torch's)")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    run_protocol(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
