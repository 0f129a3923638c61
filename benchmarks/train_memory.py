"""The memory estimate that refuses an oversized `vistac train --size`, against measured memory.

For each (model, view, --size, --batch-size), a fresh Python process builds the run's model
(`vistac_learn.train.build.build_model`), takes its resident memory, then runs what a run
does with the most memory: one training step (AdamW, forward, backward, step) on a random batch
and one scoring pass (no gradients) over ``eval_batch_size`` samples, and reports the growth of
its peak resident memory (``ru_maxrss``) over the model's. That growth is compared with
`vistac_learn.train.memory.estimate_bytes` (the larger of its training and scoring parts).

Usage:
    python benchmarks/train_memory.py            # writes benchmarks/results/train_memory.md|json
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
from pathlib import Path

from vistac.provenance import provenance

CASES = [  # model, variant, finger, size, batch size, eval batch size
    ("tipnet", "tip", "both", 48, 32, 256),
    ("tipnet", "tip", "both", 96, 32, 256),
    ("tipnet", "tip", "both", 192, 32, 64),
    ("tipnet", "tip", "both", 256, 16, 32),
    ("smallconv", "edge-index", "index", 227, 32, 64),
    ("schoeconv100-v3-fc160", "edge-index", "index", 100, 5, 256),
]

CHILD = r"""
import json, resource, sys, torch
from vistac_learn.train.build import build_model, build_view
from vistac_learn.train.config import protocol_cfg
from vistac_learn.train.memory import estimate_bytes
model_name, variant, finger, size, batch, eval_batch = sys.argv[1:]
size, batch, eval_batch = int(size), int(batch), int(eval_batch)
torch.set_num_threads(1)
cfg = protocol_cfg("default", "d", "o", model=model_name, variant=variant, finger=finger,
                   size=size, batch_size=batch, eval_batch_size=eval_batch,
                   **({"rotations": "none"} if variant == "tip" else {}))
model = build_model(cfg)
view = build_view(cfg)
est = estimate_bytes(model, view.channels, size, batch, eval_batch)
def peak():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
crops = (model.n_fingers,) if hasattr(model, "n_fingers") else ()
def run(b):
    x = torch.rand(b, *crops, view.channels, size, size)
    s = torch.zeros(b, *crops, 5) if getattr(model, "side_features", 0) else None
    return model(x, s) if s is not None else model(x)
base = peak()
opt = torch.optim.AdamW(model.parameters(), lr=1e-3)
model.train()
out = run(batch)
out.square().mean().backward()
opt.step()
del out
train_peak = peak() - base
model.eval()
with torch.no_grad():
    run(eval_batch)
score_peak = peak() - base
print(json.dumps({"estimate_train": est[0], "estimate_score": est[1],
                  "measured_train": train_peak, "measured_peak": score_peak}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = ap.parse_args()
    rows = []
    for model, variant, finger, size, batch, eval_batch in CASES:
        res = subprocess.run([sys.executable, "-c", CHILD, model, variant, finger, str(size),
                              str(batch), str(eval_batch)], capture_output=True, text=True,
                             check=True)
        r = json.loads(res.stdout.strip().splitlines()[-1])
        est = max(r["estimate_train"], r["estimate_score"])
        rows.append({"model": model, "variant": variant, "size": size, "batch_size": batch,
                     "eval_batch_size": eval_batch, **r, "estimate": est,
                     "ratio": est / max(r["measured_peak"], 1)})
        print(f"{model:10s} {variant:10s} size {size:4d} batch {batch:3d}/{eval_batch:3d}: "
              f"estimate {est / 2**20:8.1f} MiB, measured {r['measured_peak'] / 2**20:8.1f} MiB "
              f"(ratio {rows[-1]['ratio']:.2f})", flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    meta = {"python": platform.python_version(), "machine": platform.machine(),
            "note": "shared 2-core machine; peak resident memory over the built model's"}
    (out / "train_memory.json").write_text(json.dumps(
        {"meta": meta, "rows": rows, "provenance": provenance()}, indent=2) + "\n")
    lines = ["# `vistac train` memory: estimate against measured peak", "",
             "One training step and one scoring pass per row, each in a fresh process "
             "(benchmarks/train_memory.py); MiB of peak resident memory above the built model's.",
             "", "| model | view | size | batch / eval batch | estimate | measured | ratio |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['model']} | {r['variant']} | {r['size']} | {r['batch_size']} / "
                     f"{r['eval_batch_size']} | {r['estimate'] / 2**20:.0f} | "
                     f"{r['measured_peak'] / 2**20:.0f} | {r['ratio']:.2f} |")
    (out / "train_memory.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
