"""Cost of the effect pipeline: `generate` with every effect disabled vs the pipeline bypassed,
and the extra time of each preset (and of a few single effects and `--recordings`).

"Bypassed" replaces the `Pipeline`'s stage methods by constant no-ops (no stage lists are looked
at, no effects can run): what `generate` cost before effects existed. Two measurements:

1. paired: `make_configuration` per configuration, disabled and bypassed in alternating order,
   summed (load changes on a shared machine hit both alike);
2. whole `generate` runs of each variant in this process with one worker, round-robin
   `--rounds` times after one warm-up run of every variant (object cache, lazy imports); the
   median wall time is reported.

    .venv/bin/python benchmarks/effects_cost.py --n 40 --rounds 3
"""

from __future__ import annotations

import argparse
import contextlib
import json
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from vistac.config import apply
from vistac.provenance import provenance
from vistac_sim.effects.finger_pull import FingerPullCfg
from vistac_sim.effects.fts3 import Fts3Cfg
from vistac_sim.effects.placement_error import PlacementErrorCfg
from vistac_sim.effects.registry import Pipeline, build_pipeline
from vistac_sim.generate.config import GenerateCfg
from vistac_sim.generate.configuration import make_configuration
from vistac_sim.generate.rigs import RigCache
from vistac_sim.generate.run import generate, object_specs


@contextlib.contextmanager
def bypassed_pipeline():
    """Pipeline stages as constant no-ops for the duration of the block."""
    saved = {k: Pipeline.__dict__[k] for k in ("changes_physics", "needs_series", "apply_grasp",
                                               "apply_force", "apply_sensor", "apply_image")}
    Pipeline.changes_physics = property(lambda self: False)
    Pipeline.needs_series = property(lambda self: False)
    Pipeline.apply_grasp = lambda self, grasp, rng: grasp
    Pipeline.apply_force = lambda self, forces, rng: forces
    Pipeline.apply_sensor = lambda self, series, dt, rng: series
    Pipeline.apply_image = lambda self, view, rng: view
    try:
        yield
    finally:
        for k, v in saved.items():
            setattr(Pipeline, k, v)


def variants(n: int, seed: int) -> dict[str, tuple[GenerateCfg, bool]]:
    """name -> (config, bypass the pipeline?)."""
    def cfg(preset: str = "clean", noise: float = 0.0, recordings: bool = False, **effects):
        c = GenerateCfg.from_preset(preset, noise=noise, n=n, seed=seed)
        return apply(c, {"effects": effects, "recording": {"write": recordings}})

    return {
        "bypassed": (cfg(), True),
        "all disabled": (cfg(), False),
        "clean --noise 0.05": (cfg(noise=0.05), False),
        "--recordings (no effect)": (cfg(recordings=True), False),
        "fts3 only": (cfg(fts3=Fts3Cfg()), False),
        "finger_pull only": (cfg(finger_pull=FingerPullCfg()), False),
        "placement_error only": (cfg(placement_error=PlacementErrorCfg()), False),
        "lab --noise 0.05": (cfg("lab", 0.05), False),
        "harsh --noise 0.05": (cfg("harsh", 0.05), False),
        "lab --noise 0.05 --recordings": (cfg("lab", 0.05, True), False),
    }


def timed_run(c: GenerateCfg, bypass: bool, root: Path) -> float:
    out = Path(tempfile.mkdtemp(dir=root)) / "d"
    ctx = bypassed_pipeline() if bypass else contextlib.nullcontext()
    with ctx:
        t0 = time.perf_counter()
        generate(c, out, workers=1, progress=False)
        wall = time.perf_counter() - t0
    shutil.rmtree(out.parent)
    return wall


def paired_overhead(n: int, seed: int, rounds: int) -> tuple[float, float]:
    """Seconds of `make_configuration` over n configurations, all effects disabled vs bypassed,
    alternating per configuration (so that load changes on a shared machine hit both alike)."""
    c = GenerateCfg(n=n, seed=seed)
    specs, _ = object_specs(c, seed)
    scenes = RigCache(specs, c, size=64)
    pipeline = build_pipeline(c.effects)
    total = {"disabled": 0.0, "bypassed": 0.0}
    try:
        for cid in range(n):  # warm-up: build every scene once
            make_configuration(cid, seed, scenes, c, pipeline)
        for r in range(rounds):
            for cid in range(n):
                order = ("disabled", "bypassed") if (cid + r) % 2 else ("bypassed", "disabled")
                for name in order:
                    ctx = bypassed_pipeline() if name == "bypassed" else contextlib.nullcontext()
                    with ctx:
                        t0 = time.perf_counter()
                        make_configuration(cid, seed, scenes, c, pipeline)
                        total[name] += time.perf_counter() - t0
    finally:
        scenes.close()
    return total["disabled"], total["bypassed"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=40, help="configurations per run")
    ap.add_argument("--rounds", type=int, default=3, help="runs per variant (round-robin)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", nargs="*", default=None, help="variant names to run")
    ap.add_argument("--json", default=None, help="write the results here too")
    args = ap.parse_args()
    runs = variants(args.n, args.seed)
    if args.only:
        runs = {k: v for k, v in runs.items() if k in args.only or k in ("bypassed",
                                                                          "all disabled")}
    disabled, bypassed = paired_overhead(args.n, args.seed, args.rounds)
    print(f"paired, per configuration ({args.rounds} x {args.n} configurations): all disabled "
          f"{disabled:.2f} s, bypassed {bypassed:.2f} s, ratio {disabled / bypassed:.3f}\n")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for c, bypass in runs.values():  # warm-up: object cache, lazy imports, renderers
            timed_run(c, bypass, root)
        times: dict[str, list[float]] = {k: [] for k in runs}
        for _ in range(args.rounds):
            for name, (c, bypass) in runs.items():
                times[name].append(timed_run(c, bypass, root))
    med = {k: statistics.median(v) for k, v in times.items()}
    base = med["all disabled"]
    print(f"n = {args.n} configurations x 6 repeats, 1 worker, median of {args.rounds} runs\n")
    print("| variant | wall s (median) | runs | vs all disabled |")
    print("|---|---|---|---|")
    for k, v in med.items():
        spread = ", ".join(f"{t:.2f}" for t in times[k])
        print(f"| {k} | {v:.2f} | {spread} | {v / base:.3f} x ({v - base:+.2f} s) |")
    print(f"\nall disabled / bypassed = {base / med['bypassed']:.3f}")
    if args.json:
        Path(args.json).write_text(json.dumps({"n": args.n, "times": times,
                                                     "provenance": provenance()}, indent=2))


if __name__ == "__main__":
    main()
