"""Does a change to generation's code cost speed? `vistac generate` from this tree and from
another source tree (same options, same seed), interleaved run by run, timed in wall and CPU
seconds (every process of a run counted: its fork server and workers are adopted and waited for,
as in `generate_vs_bare.py`).

Writes `benchmarks/results/generate_before_after.{json,md}` (or under `--results`).

    python benchmarks/generate_before_after.py --before-src SRC [--n 1500] [--workers 2]
        [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from generate_vs_bare import _children_cpu, adopt_orphans, reap_orphans

from vistac.provenance import provenance

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).resolve().parent / "results"


def timed_generate(src: Path, out: Path, n: int, workers: int, seed: int) -> tuple[float, float]:
    """Wall and CPU seconds of one `vistac generate` run of the code in `src`."""
    shutil.rmtree(out, ignore_errors=True)
    env = {**os.environ, "PYTHONPATH": str(src)}
    cpu0, t0 = _children_cpu(), time.perf_counter()
    subprocess.run([sys.executable, "-m", "vistac.cli", "generate", "--n", str(n), "--noise",
                    "0.05", "--seed", str(seed), "--workers", str(workers), "--out", str(out),
                    "--no-progress"], env=env, cwd=src, check=True, stdout=subprocess.DEVNULL)
    reap_orphans()
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    shutil.rmtree(out, ignore_errors=True)
    return wall, cpu


def markdown(r: dict) -> str:
    lines = [f"# generate: before and after ({r['label'] or 'this tree'})", "",
             f"`vistac generate --n {r['n']} --noise 0.05 --workers {r['workers']}`, "
             f"{r['repeats']} interleaved pairs on {r['cpu_count']} cores (a shared machine: "
             "CPU seconds are the fairer measure). Medians:", "",
             "| code | wall (s) | CPU (s) |", "|---|---:|---:|"]
    for k in ("before", "after"):
        lines.append(f"| {k} | {r[k]['wall_s']:.2f} | {r[k]['cpu_s']:.2f} |")
    lines += ["", f"after / before: wall {r['wall_ratio']:.3f}, CPU {r['cpu_ratio']:.3f}", "",
              "Pairs (wall s, CPU s): " + "; ".join(
                  f"before {b[0]:.2f}/{b[1]:.2f}, after {a[0]:.2f}/{a[1]:.2f}"
                  for b, a in zip(r["before"]["runs"], r["after"]["runs"], strict=True)), ""]
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--before-src", type=Path, required=True, help="source tree of the 'before'")
    p.add_argument("--n", type=int, default=1500)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--out", type=Path, default=Path("runs/bench_before_after"))
    p.add_argument("--results", type=Path, default=RESULTS)
    p.add_argument("--label", default="", help="what changed (written with the results)")
    args = p.parse_args()
    adopt_orphans()
    trees = {"before": args.before_src.resolve(), "after": ROOT}
    runs: dict[str, list[tuple[float, float]]] = {k: [] for k in trees}
    for r in range(args.repeats):
        for k, src in (trees.items() if r % 2 == 0 else reversed(trees.items())):
            runs[k].append(timed_generate(src, args.out.resolve() / k, args.n, args.workers,
                                          args.seed))
            print(f"pair {r} {k}: {runs[k][-1][0]:.2f} s, {runs[k][-1][1]:.2f} CPU s",
                  flush=True)
    result = {"label": args.label, "n": args.n, "workers": args.workers,
              "repeats": args.repeats, "cpu_count": os.cpu_count()}
    for k, rs in runs.items():
        result[k] = {"wall_s": statistics.median(w for w, _ in rs),
                     "cpu_s": statistics.median(c for _, c in rs),
                     "runs": [[round(w, 2), round(c, 2)] for w, c in rs]}
    result["wall_ratio"] = round(result["after"]["wall_s"] / result["before"]["wall_s"], 3)
    result["cpu_ratio"] = round(result["after"]["cpu_s"] / result["before"]["cpu_s"], 3)
    result["provenance"] = provenance()
    args.results.mkdir(parents=True, exist_ok=True)
    (args.results / "generate_before_after.json").write_text(json.dumps(result, indent=2) + "\n")
    (args.results / "generate_before_after.md").write_text(markdown(result))
    print(markdown(result))


if __name__ == "__main__":
    main()
