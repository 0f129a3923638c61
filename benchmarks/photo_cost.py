"""Cost of `--preset photo` against the clean preset: per configuration, and memory.

1. paired: `make_configuration` of the same configurations under the clean and the photo config
   (and photo without shadows, and without shadows and JPEG), in a rotating order per
   configuration (load changes on a shared machine hit all alike); CPU time
   (`time.process_time`, all threads of this process, the renderer's included) and wall time,
   after a warm-up pass that builds every scene (and the texture bank) once;
2. whole `generate` runs, one worker in this process, clean / photo / photo --masks,
   round-robin `--rounds` times after a warm-up run of each: median wall and CPU time;
3. memory: the peak resident set of a fresh `vistac generate` process (one worker), clean and
   photo, at `--n` and at 4 x `--n` configurations (flat: about the same peak).

    .venv/bin/python benchmarks/photo_cost.py --n 40 --rounds 4
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from vistac.provenance import provenance
from vistac_sim.effects import build_pipeline
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.configuration import make_configuration
from vistac_sim.generate.rigs import RigCache
from vistac_sim.generate.run import generate, object_specs
from vistac_sim.render.config import RenderCfg

RESULTS = Path(__file__).parent / "results"


def config(preset: str, n: int, seed: int, masks: bool = False, **off: None) -> GenerateCfg:
    """The preset's config; `off` names effects switched off (``shadows=None``)."""
    c = GenerateCfg.from_preset(preset, n=n, seed=seed, render=RenderCfg(masks=masks))
    return dataclasses.replace(c, effects=dataclasses.replace(c.effects, **off)) if off else c


def paired(n: int, seed: int, rounds: int) -> dict[str, dict[str, float]]:
    """Summed CPU and wall seconds of `make_configuration` per variant over n x rounds: clean,
    photo, and photo without its costliest parts (no shadows; no shadows and no JPEG)."""
    cfgs = {p: config(p, n, seed) for p in ("clean", "photo")}
    cfgs["photo, no shadows"] = config("photo", n, seed, shadows=None)
    cfgs["photo, no shadows, no JPEG"] = config("photo", n, seed, shadows=None, jpeg=None)
    specs, _ = object_specs(cfgs["clean"], seed)
    scenes = {p: RigCache(specs, c, size=64) for p, c in cfgs.items()}
    pipes = {p: build_pipeline(c.effects) for p, c in cfgs.items()}
    total = {p: {"cpu": 0.0, "wall": 0.0} for p in cfgs}
    try:
        for p in cfgs:  # warm-up: every scene and the texture bank built once
            for cid in range(n):
                make_configuration(cid, seed, scenes[p], cfgs[p], pipes[p])
        names = list(cfgs)
        for r in range(rounds):
            for cid in range(n):
                shift = (cid + r) % len(names)
                for p in names[shift:] + names[:shift]:  # a rotating order
                    c0, w0 = time.process_time(), time.perf_counter()
                    make_configuration(cid, seed, scenes[p], cfgs[p], pipes[p])
                    total[p]["cpu"] += time.process_time() - c0
                    total[p]["wall"] += time.perf_counter() - w0
    finally:
        for s in scenes.values():
            s.close()
    return total


def whole_runs(n: int, seed: int, rounds: int) -> dict[str, dict[str, list[float]]]:
    variants = {"clean": config("clean", n, seed), "photo": config("photo", n, seed),
                "photo --masks": config("photo", n, seed, masks=True)}
    times = {k: {"wall": [], "cpu": []} for k in variants}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(rounds + 1):  # round 0: warm-up
            for name, c in variants.items():
                out = Path(tmp) / f"{r}_{name.replace(' ', '')}"
                c0, w0 = time.process_time(), time.perf_counter()
                generate(c, out, workers=1, progress=False)
                cpu, wall = time.process_time() - c0, time.perf_counter() - w0
                shutil.rmtree(out)
                if r:
                    times[name]["wall"].append(wall)
                    times[name]["cpu"].append(cpu)
    return times


def peak_rss_mib(n: int, seed: int, preset: str = "photo") -> float:
    """Peak resident set (MiB) of a fresh `vistac generate --preset P --workers 1` process,
    read by a fresh wrapper process whose only child it is (so no earlier child counts)."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "vistac.cli", "generate", "--out", f"{tmp}/d", "--n",
               str(n), "--seed", str(seed), "--preset", preset, "--workers", "1",
               "--no-progress"]
        wrapper = ("import resource, subprocess, sys; "
                   f"subprocess.run({cmd!r}, check=True, capture_output=True); "
                   "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
        out = subprocess.run([sys.executable, "-c", wrapper], check=True, capture_output=True,
                             text=True)
    return int(out.stdout.split()[-1]) / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=40, help="configurations per run")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--skip-memory", action="store_true")
    args = ap.parse_args()
    res: dict = {"n": args.n, "rounds": args.rounds}
    pair = paired(args.n, args.seed, args.rounds)
    per = args.n * args.rounds
    res["paired_ms_per_config"] = {p: {k: v / per * 1e3 for k, v in t.items()}
                                   for p, t in pair.items()}
    runs = whole_runs(args.n, args.seed, args.rounds)
    res["runs_s"] = runs
    if not args.skip_memory:
        res["peak_rss_mib"] = {p: {str(n): peak_rss_mib(n, args.seed, p)
                                   for n in (args.n, 4 * args.n)} for p in ("clean", "photo")}
    res["provenance"] = provenance()
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "photo_cost.json").write_text(json.dumps(res, indent=2) + "\n")
    lines = [f"# photo preset cost (n = {args.n}, 1 worker, {args.rounds} rounds; shared, "
             "noisy 2-core machine)", "",
             "| measure | clean | photo | photo / clean |", "|---|---|---|---|"]
    pm = res["paired_ms_per_config"]
    for k in ("cpu", "wall"):
        lines.append(f"| paired make_configuration, {k} ms per configuration | "
                     f"{pm['clean'][k]:.2f} | {pm['photo'][k]:.2f} | "
                     f"{pm['photo'][k] / pm['clean'][k]:.2f} x |")
        for v in ("photo, no shadows", "photo, no shadows, no JPEG"):
            lines.append(f"| ... {v}, {k} | | {pm[v][k]:.2f} | "
                         f"{pm[v][k] / pm['clean'][k]:.2f} x |")
    for k in ("cpu", "wall"):
        med = {v: statistics.median(runs[v][k]) for v in runs}
        lines.append(f"| whole generate run, {k} s (median) | {med['clean']:.2f} | "
                     f"{med['photo']:.2f} (masks: {med['photo --masks']:.2f}) | "
                     f"{med['photo'] / med['clean']:.2f} x |")
    if "peak_rss_mib" in res:
        lines.append("")
        for p, peaks in res["peak_rss_mib"].items():
            text = ", ".join(f"n = {n}: {v:.0f} MiB" for n, v in peaks.items())
            lines.append(f"Peak resident set of `generate --preset {p} --workers 1`: {text}.  ")
    text = "\n".join(lines) + "\n"
    (RESULTS / "photo_cost.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
