"""Time `vistac generate` against a bare MuJoCo loop doing the same physics and render work.

The bare loop runs in the same number of processes over the same object scenes (built by
vistac's scene compiler, outside nothing: each process builds its own scenes as generate's workers
do) and, per sample: resets, poses the fingers for a fixed valid grasp, settles the same number of
steps, reads both pads' forces with `mj_contactForce`, renders the top view, encodes a PNG and
writes it to disk. What it leaves out is exactly vistac's own work: grasp sampling and redraws,
the press checks, mesh normals, boxes, labels, effects, shards, resume bookkeeping and the final
tables.

Peak memory: the largest resident set of any process of a generate run (`ru_maxrss` of the
waited-for children), measured for two sizes to show it is flat in n.

Usage:
    python benchmarks/generate_vs_bare.py --n 20000 --workers 2 --out runs/bench_generate
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path


def _bare_worker(args: tuple[int, int, str, int]) -> int:
    """One bare-loop process: `count` samples round-robin over the object library."""
    import numpy as np

    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.generate.scenes import ObjectScene, draw_grasp
    from vistac_sim.mj import mujoco
    from vistac_sim.objects.library import build_object, procedural_library
    from vistac_sim.render.png import encode_png

    worker, count, out, seed = args
    cfg = GenerateCfg(seed=seed)
    scenes, grasps = [], []
    for spec in procedural_library(cfg.objects, seed):
        scene = ObjectScene(build_object(spec, cfg.hand.height), cfg)
        grasp = draw_grasp(scene, np.random.default_rng(0), cfg)[0]  # found before the loop
        scenes.append(scene)
        grasps.append(grasp)
    f6 = np.zeros(6)
    folder = Path(out)
    for i in range(count):
        scene, grasp = scenes[i % len(scenes)], grasps[i % len(scenes)]
        m, d = scene.model, scene.press.data
        scene.press.pose(grasp)  # reset + mocap poses + drive
        mujoco.mj_step(m, d, nstep=cfg.physics.settle_steps)
        total = 0.0
        for c in range(d.ncon):
            mujoco.mj_contactForce(m, d, c, f6)
            total += f6[0]
        png = encode_png(scene.view.render(d))  # the same encoder as generate's
        (folder / f"{worker}_{i:06d}.png").write_bytes(png)
    return count


def bare_loop(n: int, workers: int, out: Path, seed: int) -> float:
    out.mkdir(parents=True, exist_ok=True)
    shares = [n // workers + (1 if w < n % workers else 0) for w in range(workers)]
    t0 = time.perf_counter()
    with mp.get_context("spawn").Pool(workers) as pool:
        done = sum(pool.map(_bare_worker, [(w, c, str(out), seed) for w, c in enumerate(shares)]))
    assert done == n
    return time.perf_counter() - t0


def run_generate(n: int, workers: int, out: Path, seed: int) -> tuple[float, float]:
    """Wall time of a `vistac generate` subprocess and the peak RSS (MiB) of its processes."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "vistac.cli", "generate", "--n", str(n),
                    "--noise", "0.05", "--seed", str(seed), "--workers", str(workers),
                    "--out", str(out), "--no-progress"], check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return wall, max(peak, before) / 1024


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--n", type=int, default=20000)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--memory-n", type=int, nargs=2, default=(2000, 20000),
                   help="two sizes whose peak memory is compared (the larger may reuse --n)")
    p.add_argument("--out", type=Path, default=Path("runs/bench_generate"))
    args = p.parse_args()
    shutil.rmtree(args.out, ignore_errors=True)
    args.out.mkdir(parents=True)

    bare = bare_loop(args.n, args.workers, args.out / "bare", args.seed)
    shutil.rmtree(args.out / "bare")
    gen, peak_n = run_generate(args.n, args.workers, args.out / "gen", args.seed)
    shutil.rmtree(args.out / "gen")
    small_n = min(args.memory_n)
    # RUSAGE_CHILDREN keeps the maximum over all children so far: measure the small run first in
    # a fresh interpreter so that its peak is its own.
    probe = subprocess.run(
        [sys.executable, __file__, "--peak-only", str(small_n), str(args.workers),
         str(args.out / "small")], capture_output=True, text=True, check=True)
    peak_small = float(probe.stdout.strip().splitlines()[-1])
    result = {
        "n": args.n, "workers": args.workers, "cpu_count": os.cpu_count(),
        "bare_loop_s": round(bare, 2), "generate_s": round(gen, 2),
        "ratio_generate_over_bare": round(gen / bare, 3),
        "bare_samples_per_s": round(args.n / bare, 1),
        "generate_samples_per_s": round(args.n / gen, 1),
        "peak_rss_mib": {str(small_n): round(peak_small, 1), str(args.n): round(peak_n, 1)},
    }
    (args.out / "result.json").write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--peak-only":
        n, workers, out = int(sys.argv[2]), int(sys.argv[3]), Path(sys.argv[4])
        shutil.rmtree(out, ignore_errors=True)
        _, peak = run_generate(n, workers, out, 0)
        shutil.rmtree(out, ignore_errors=True)
        print(peak)
    else:
        main()
