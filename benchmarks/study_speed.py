"""Training speed of the study's protocol with and without rendered samples kept in memory.

`--protocol study` trains on the same (configuration, rotation) samples every epoch, so
`SampleSet` renders each once (decode, edge image, rotation, crop) and keeps it
(`vistac_learn.data.samples.RENDER_CACHE_BYTES`). This script trains the same run twice in one
process, once with the cache switched off (budget 0) and once with it, and reports training
samples per second per epoch (the first epoch renders in both; later epochs show the gain), the
CPU seconds of each whole run (user + system of this process: on a shared, busy machine the
figure to compare) and whether the two runs' losses agree bit for bit.

Usage:
    .venv/bin/python benchmarks/study_speed.py            # 40 configurations x 20 rotations
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

from learnbench import cpu_s, ensure_dataset
from study_replay import train_fraction

import vistac_learn.data.samples as samples
from vistac.dataset import SplitCfg, open_tables
from vistac.provenance import provenance
from vistac_learn.train.config import protocol_cfg
from vistac_learn.train.loop import train_run_folder
from vistac_sim.generate.config import GenerateCfg

REPO = Path(__file__).resolve().parent.parent


def epochs_of(run: Path) -> list[dict]:
    with (run / "metrics.csv").open() as fh:
        return list(csv.DictReader(fh))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--work", default=str(REPO / "runs" / "study_speed"))
    p.add_argument("--results", default=str(REPO / "benchmarks" / "results"))
    p.add_argument("--n", type=int, default=200, help="configurations generated")
    p.add_argument("--n-train", type=int, default=40, help="training configurations used")
    p.add_argument("--epochs", type=int, default=3)
    args = p.parse_args(argv)
    work = Path(args.work)
    data = ensure_dataset(work / "data", GenerateCfg.from_preset(
        "lab", noise=0.05, n=args.n, seed=0, split=SplitCfg(fractions=(0.5, 0.25, 0.25))))
    frac = train_fraction(open_tables(data), args.n_train)
    budget = samples.RENDER_CACHE_BYTES
    arms = {}
    for name, cache in (("rendered every epoch", 0), ("rendered once", budget)):
        samples.RENDER_CACHE_BYTES = cache
        run = work / name.replace(" ", "_")
        cfg = protocol_cfg("study", str(data), str(run), epochs=args.epochs, device="cpu",
                           train_fraction=frac,
                           cache_dir=str(work / "cache"))
        c0 = cpu_s()
        train_run_folder(cfg, progress=False)
        cpu = cpu_s() - c0
        rows = epochs_of(run)
        n = args.n_train * cfg.n_rotations
        arms[name] = {"samples_per_s": [n / float(r["train_s"]) for r in rows],
                      "train_loss": [float(r["train_loss"]) for r in rows],
                      "cpu_s": cpu, "samples_per_cpu_s": n * args.epochs / cpu}
    samples.RENDER_CACHE_BYTES = budget
    a, b = arms.values()
    same = a["train_loss"] == b["train_loss"]
    later = slice(1, None)
    ratio = (sum(b["samples_per_s"][later]) / sum(a["samples_per_s"][later]))
    cpu_ratio = b["samples_per_cpu_s"] / a["samples_per_cpu_s"]
    lines = ["| epoch | " + " | ".join(f"{k} (samples/s)" for k in arms) + " |",
             "|---|---|---|"]
    for i in range(args.epochs):
        lines.append(f"| {i + 1} | " + " | ".join(f"{v['samples_per_s'][i]:.1f}"
                                                   for v in arms.values()) + " |")
    md = ("# Study protocol: training speed with rendered samples kept\n\n" + "\n".join(lines)
          + f"\n\nSchoeConv100-V3(FC160), edge-index, {args.n_train} configurations x 20 "
          f"rotations, batch 5, CPU. Epochs 2+: {ratio:.2f}x the samples per second; whole "
          f"runs ({args.epochs} epochs with validation): {a['cpu_s']:.0f} and {b['cpu_s']:.0f} "
          f"CPU s, {cpu_ratio:.2f}x the samples per CPU second; losses "
          f"{'identical' if same else 'DIFFER'} in every epoch.\n")
    result = {"provenance": provenance([data]), "arms": arms, "ratio_later_epochs": ratio,
              "ratio_samples_per_cpu_s": cpu_ratio,
              "losses_identical": same}
    out = Path(args.results)
    (out / "study_speed.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / "study_speed.md").write_text(md)
    print(md)
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
