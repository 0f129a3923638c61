"""Time `vistac generate` against a bare MuJoCo loop doing the same physics and render work.

The bare loop is the floor: the same number of processes over the same object scenes (built by
vistac's scene compiler; each process builds the scenes of its share of the objects, as
generate's workers do) and, per sample: reset and pose the fingers for a fixed valid grasp,
settle the same number of steps, read both pads' forces with `mj_contactForce`, render the
227 px top view, encode a PNG (the same encoder) and write it to disk. What it leaves out is
exactly vistac's own work: grasp sampling and redraws, the press checks, mesh normals, boxes,
labels, effects, shards, resume bookkeeping, the final tables, and the `vistac` process itself
(its imports: it builds and screens the objects before the run). Both start alike: a fresh
interpreter, a fork server that imports the simulator once, workers forked from it; both are
timed from their interpreter's start, and the CPU time of every process they start counts
(the fork server and its workers are adopted and waited for: `adopt_orphans`).

The benchmark reports:
1. the ratio generate / bare at `--n` (`--repeats` interleaved pairs; the ratio of the medians),
   of wall time and of CPU time (user + system of all their processes: the fairer measure on a
   machine that other jobs share),
2. where the time goes: per-sample milliseconds per part of both, profiled in one process
   (`generate_breakdown.py`, at `--profile-n`),
3. per-sample cost and peak memory against the number of configurations (`--scale-n`): each size
   is a `vistac generate` run in a fresh interpreter; peak memory is the largest resident set of
   any of its processes (`ru_maxrss` of the waited-for children).

Usage:
    python benchmarks/generate_vs_bare.py --n 4000 --workers 2 --out runs/bench_generate
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import resource
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

RESULTS = Path(__file__).parent / "results"


def _bare_worker(args: tuple[int, int, int, str, int]) -> int:
    """One bare-loop process: `count` samples round-robin over its share of the objects."""
    import numpy as np

    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.generate.rigs import ObjectRig, draw_grasp
    from vistac_sim.mj import mujoco
    from vistac_sim.objects.library import build_object, procedural_library
    from vistac_sim.render.png import encode_png

    worker, workers, count, out, seed = args
    cfg = GenerateCfg(seed=seed)
    scenes, grasps = [], []
    for spec in procedural_library(cfg.objects, seed)[worker::workers]:
        scene = ObjectRig(build_object(spec, cfg.hand.height), cfg)
        grasp = draw_grasp(scene, np.random.default_rng(0), cfg)[0]  # found before the loop
        scenes.append(scene)
        grasps.append(grasp)
    f6 = np.zeros(6)
    folder = Path(out)
    for i in range(count):
        scene, grasp = scenes[i % len(scenes)], grasps[i % len(scenes)]
        m, d = scene.model, scene.press.data
        scene.press.pose(grasp)  # reset + mocap poses + drive
        mujoco.mj_step(m, d, nstep=cfg.physics.approach_steps)  # the press's two phases
        scene.press.release()
        mujoco.mj_step(m, d, nstep=cfg.physics.settle_steps)
        total = 0.0
        for c in range(d.ncon):
            mujoco.mj_contactForce(m, d, c, f6)
            total += f6[0]
        png = encode_png(scene.view.render(d))  # the same encoder as generate's
        (folder / f"{worker}_{i:06d}.png").write_bytes(png)
    return count


def adopt_orphans() -> None:
    """Make this process the reaper of its orphaned descendants (Linux `PR_SET_CHILD_SUBREAPER`).

    `generate`'s workers are forked by a fork server that outlives the `vistac` process by a
    moment; reparented here and waited for (`reap_orphans`), their CPU time and memory count in
    this process's `RUSAGE_CHILDREN` like those of every other descendant.
    """
    import ctypes

    if ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0) != 0:
        raise OSError(ctypes.get_errno(), "prctl(PR_SET_CHILD_SUBREAPER) failed")


def reap_orphans() -> None:
    """Wait for every remaining child (orphans adopted by `adopt_orphans` included)."""
    while True:
        try:
            os.waitpid(-1, 0)
        except ChildProcessError:
            return


def _children_cpu() -> float:
    """CPU seconds (user + system) of all waited-for descendants so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


# modules a bare worker uses: imported once by the fork server its workers fork from, as
# generate's workers are (`vistac.engine.ForkServer`)
BARE_PRELOAD = ["vistac_sim.generate.config", "vistac_sim.generate.rigs",
                "vistac_sim.objects.library", "vistac_sim.render.png", "vistac_sim.mj"]


def bare_pool(n: int, workers: int, out: Path, seed: int) -> int:
    """The bare loop's processes (run in a fresh interpreter by `bare_loop`)."""
    shares = [n // workers + (1 if w < n % workers else 0) for w in range(workers)]
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(BARE_PRELOAD)
    with ctx.Pool(workers) as pool:
        return sum(pool.map(_bare_worker, [(w, workers, c, str(out), seed)
                                           for w, c in enumerate(shares)]))


def bare_loop(n: int, workers: int, out: Path, seed: int) -> tuple[float, float]:
    """Wall time and CPU time (s) of the bare loop: `n` samples in `workers` processes, started
    the way generate starts its own (a fresh interpreter, a fork server, forked workers)."""
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    cpu0, t0 = _children_cpu(), time.perf_counter()
    done = subprocess.run([sys.executable, __file__, "--bare-run", str(n), str(workers), str(out),
                           str(seed)], check=True, capture_output=True, text=True)
    reap_orphans()
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    assert int(done.stdout.split()[-1]) == n
    shutil.rmtree(out)
    return wall, cpu


def run_generate(n: int, workers: int, out: Path, seed: int) -> tuple[float, float, float]:
    """Wall time and CPU time (s) of a `vistac generate` subprocess (its workers included) and
    the peak RSS (MiB) of the largest child process so far (fresh interpreters measure one
    run)."""
    shutil.rmtree(out, ignore_errors=True)
    cpu0, t0 = _children_cpu(), time.perf_counter()
    subprocess.run([sys.executable, "-m", "vistac.cli", "generate", "--n", str(n),
                    "--noise", "0.05", "--seed", str(seed), "--workers", str(workers),
                    "--out", str(out), "--no-progress"], check=True, stdout=subprocess.DEVNULL)
    reap_orphans()  # the fork server and its workers, reparented here
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    shutil.rmtree(out, ignore_errors=True)
    return wall, cpu, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024


def scale_point(n: int, workers: int, out: Path) -> dict:
    """One size of the scaling table, measured in a fresh interpreter."""
    probe = subprocess.run([sys.executable, __file__, "--one-run", str(n), str(workers),
                            str(out)], capture_output=True, text=True, check=True)
    wall, cpu, peak = json.loads(probe.stdout.strip().splitlines()[-1])
    return {"n": n, "wall_s": round(wall, 2), "ms_per_config": round(1e3 * wall / n, 3),
            "cpu_ms_per_config": round(1e3 * cpu / n, 3), "peak_rss_mib": round(peak, 1)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--n", type=int, default=4000)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=3, help="interleaved bare/generate pairs")
    p.add_argument("--profile-n", type=int, default=1000, help="size of the profiled runs")
    p.add_argument("--scale-n", type=int, nargs="*", default=[1000, 10000],
                   help="sizes of the per-sample cost and memory table")
    p.add_argument("--out", type=Path, default=Path("runs/bench_generate"))
    p.add_argument("--results", type=Path, default=RESULTS)
    p.add_argument("--label", default="", help="note written with the results (e.g. the commit)")
    args = p.parse_args()
    adopt_orphans()
    shutil.rmtree(args.out, ignore_errors=True)
    args.out.mkdir(parents=True)

    pairs = []  # (bare wall, generate wall, bare CPU, generate CPU)
    for r in range(args.repeats):
        bare, bare_cpu = bare_loop(args.n, args.workers, args.out / "bare", args.seed)
        gen, gen_cpu, _ = run_generate(args.n, args.workers, args.out / "gen", args.seed)
        pairs.append((bare, gen, bare_cpu, gen_cpu))
        print(f"pair {r}: bare {bare:.2f} s ({bare_cpu:.1f} CPU s), generate {gen:.2f} s "
              f"({gen_cpu:.1f} CPU s)", flush=True)
    bare_med, gen_med, bare_cpu_med, gen_cpu_med = (statistics.median(p[i] for p in pairs)
                                                    for i in range(4))

    from generate_breakdown import profile_bare, profile_generate

    parts = {"generate": profile_generate(args.profile_n, args.seed, args.out / "prof_gen"),
             "bare": profile_bare(args.profile_n, args.seed, args.out / "prof_bare")}
    scaling = [scale_point(n, args.workers, args.out / f"scale_{n}") for n in args.scale_n]
    result = {
        "label": args.label, "n": args.n, "workers": args.workers, "cpu_count": os.cpu_count(),
        "pairs_s": [[round(b, 2), round(g, 2)] for b, g, _, _ in pairs],
        "pairs_cpu_s": [[round(b, 2), round(g, 2)] for _, _, b, g in pairs],
        "bare_loop_cpu_s": round(bare_cpu_med, 2), "generate_cpu_s": round(gen_cpu_med, 2),
        "cpu_ratio_generate_over_bare": round(gen_cpu_med / bare_cpu_med, 3),
        "bare_loop_s": round(bare_med, 2), "generate_s": round(gen_med, 2),
        "ratio_generate_over_bare": round(gen_med / bare_med, 3),
        "bare_samples_per_s": round(args.n / bare_med, 1),
        "generate_samples_per_s": round(args.n / gen_med, 1),
        "profile_n": args.profile_n, "breakdown_ms_per_sample": parts, "scaling": scaling,
    }
    print(json.dumps(result, indent=2))
    from generate_report import write_report

    write_report(result, args.results)


if __name__ == "__main__":
    if len(sys.argv) == 6 and sys.argv[1] == "--bare-run":
        print(bare_pool(int(sys.argv[2]), int(sys.argv[3]), Path(sys.argv[4]), int(sys.argv[5])))
    elif len(sys.argv) == 5 and sys.argv[1] == "--one-run":
        n, workers, out = int(sys.argv[2]), int(sys.argv[3]), Path(sys.argv[4])
        adopt_orphans()
        print(json.dumps(run_generate(n, workers, out, 0)))
    else:
        main()
