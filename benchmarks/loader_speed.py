"""Training speed and results of two checkouts of the learner on the same data, interleaved.

Each round trains one short run (``--epochs`` epochs of the default protocol on a seeded
``--fraction`` of the training configurations) with each checkout, in a fresh Python process
whose imports come from that checkout (``PYTHONPATH``), the order of the two alternating from
round to round so that a slow spell of the shared machine hits both. Reported per run: process
CPU seconds (user + system, all threads), wall seconds, the seconds of the training steps alone
(``train_s`` of ``metrics.csv``) and steps per second, and the run's validation numbers, which
must agree between the checkouts (same seed, same samples) and between rounds (determinism).

Usage (after: this checkout; before: e.g. ``git archive 400713e | tar -x -C /tmp/before``):
    OMP_NUM_THREADS=1 python benchmarks/loader_speed.py --data D --before /tmp/before
        # writes benchmarks/results/loader_speed.json|md
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from vistac.provenance import provenance

HERE = Path(__file__).resolve().parents[1]
RESULTS = HERE / "benchmarks" / "results"

CHILD = r"""
import csv, json, resource, sys, time
import torch
import vistac_learn
from vistac_learn.train.config import protocol_cfg
from vistac_learn.train.loop import train_run_folder
data, out, epochs, fraction, cache, workers = sys.argv[1:]
torch.set_num_threads(1)
extra = {"loader_workers": int(workers)} if int(workers) else {}
cfg = protocol_cfg("default", data, out, epochs=int(epochs), train_fraction=float(fraction),
                   cache_dir=cache, **extra)
t0 = time.perf_counter()
train_run_folder(cfg, progress=False)
wall = time.perf_counter() - t0
ru = resource.getrusage(resource.RUSAGE_SELF)
kids = resource.getrusage(resource.RUSAGE_CHILDREN)  # loader workers
with open(out + "/metrics.csv", newline="") as fh:
    rows = list(csv.DictReader(fh))
meta = json.load(open(out + "/config.json"))
n = meta["dataset"]["n_train_samples"]
steps = -(-n // cfg.batch_size) * cfg.epochs
keep = [k for k in rows[0] if k not in ("train_s", "epoch_s")]
cpu = ru.ru_utime + ru.ru_stime + kids.ru_utime + kids.ru_stime
print(json.dumps({"code": vistac_learn.__file__, "cpu_s": cpu,
                  "wall_s": wall, "train_s": sum(float(r["train_s"]) for r in rows),
                  "steps": steps, "n_train_samples": n,
                  "results": [{k: float(r[k]) for k in keep} for r in rows]}))
"""


def run_one(code: Path, data: str, epochs: int, fraction: float, cache: str,
            workers: int = 0) -> dict:
    """One training run in a fresh process importing the learner from `code` (`workers`:
    loader processes, ``--loader-workers``; 0 is the default and the only choice before)."""
    with tempfile.TemporaryDirectory(prefix="loader_speed_") as tmp:
        env = os.environ | {"PYTHONPATH": str(code), "OMP_NUM_THREADS": "1"}
        res = subprocess.run([sys.executable, "-c", CHILD, data, f"{tmp}/run", str(epochs),
                              str(fraction), cache, str(workers)], env=env, cwd=code,
                             capture_output=True, text=True, check=False)
    if res.returncode != 0:
        raise SystemExit(f"training with {code} failed:\n{res.stderr[-2000:]}")
    out = json.loads(res.stdout.strip().splitlines()[-1])
    if not out["code"].startswith(str(code)):
        raise SystemExit(f"{code}: the child imported {out['code']} instead")
    out["steps_per_s"] = out["steps"] / out["train_s"]
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", required=True, help="dataset (its cache/ holds the fingertips)")
    p.add_argument("--before", required=True, help="checkout of the code to compare with")
    p.add_argument("--after", default=str(HERE), help="checkout measured (default: this one)")
    p.add_argument("--epochs", type=int, default=2)
    p.add_argument("--fraction", type=float, default=0.15,
                   help="share of the training configurations")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--workers", type=int, default=2,
                   help="also time this checkout with this many loader workers (0: skip)")
    p.add_argument("--out", default=str(RESULTS / "loader_speed"), help="results stem")
    a = p.parse_args(argv)
    cache = str(Path(a.data) / "cache")
    sides = [("before", Path(a.before).resolve(), 0), ("after", Path(a.after).resolve(), 0)]
    if a.workers:
        sides.append((f"after, {a.workers} workers", Path(a.after).resolve(), a.workers))
    runs: dict[str, list[dict]] = {name: [] for name, _, _ in sides}
    for r in range(a.rounds):
        for name, code, workers in sides[r % len(sides):] + sides[:r % len(sides)]:
            runs[name].append(run_one(code, a.data, a.epochs, a.fraction, cache, workers))
            m = runs[name][-1]
            print(f"round {r + 1} {name}: {m['steps_per_s']:.2f} steps/s, cpu "
                  f"{m['cpu_s']:.1f} s, wall {m['wall_s']:.1f} s", file=sys.stderr)
    keys = ("steps_per_s", "train_s", "cpu_s", "wall_s")
    summary = {name: {k: statistics.median(x[k] for x in rs) for k in keys}
               for name, rs in runs.items()}
    ratio = {name: {k: summary[name][k] / summary["before"][k] for k in keys}
             for name in summary if name != "before"}
    first = runs["before"][0]["results"]
    same_as_before = all(x["results"] == first for rs in runs.values() for x in rs)
    repeatable = all(x["results"] == runs["after"][0]["results"] for x in runs["after"])
    out = {"data": a.data, "epochs": a.epochs, "fraction": a.fraction, "rounds": a.rounds,
           "n_train_samples": runs["after"][0]["n_train_samples"],
           "steps": runs["after"][0]["steps"], "omp_num_threads": 1,
           "machine": f"{platform.machine()}, {os.cpu_count()} cores",
           "median": summary, "over_before": ratio,
           "results_identical_to_before": same_as_before, "repeatable": repeatable,
           "final_epoch": runs["after"][0]["results"][-1], "runs": runs}
    out["provenance"] = provenance([a.data])
    stem = Path(a.out)
    stem.parent.mkdir(parents=True, exist_ok=True)
    stem.with_suffix(".json").write_text(json.dumps(out, indent=2))
    last = out["final_epoch"]
    angle = statistics.mean(v for k, v in last.items()
                            if k.endswith("angle_to_mean_median_deg"))
    lines = [
        "# Learner speed: torch Dataset + DataLoader against the batch renderer before it",
        "",
        f"{a.rounds} interleaved rounds, each one run per variant of {a.epochs} epochs of the "
        f"default protocol on {out['n_train_samples']} training samples ({out['steps']} "
        f"steps), OMP_NUM_THREADS=1, {out['machine']}. Medians; ratios to before in "
        "brackets. Process CPU seconds include loader workers.",
        "",
        "| | steps/s | train s | process CPU s | wall s |",
        "|---|---|---|---|---|",
    ]
    for name in summary:
        s, q = summary[name], ratio.get(name)
        cells = [f"{s[k]:.2f}" + (f" ({q[k]:.2f})" if q else "") for k in keys]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += ["", f"Validation numbers identical to before in every run: "
              f"{'yes' if same_as_before else 'no'}; identical across rounds: "
              f"{'yes' if repeatable else 'no'}. Last epoch: val loss {last['val_loss']:.4f}, "
              f"median angle to the cone mean {angle:.2f} deg (mean of the fingers)."]
    stem.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
