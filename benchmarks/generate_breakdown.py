"""Where the time of `vistac generate` goes: one process, cProfile, time per part per sample.

`profile_generate` runs `generate` in this process (workers=1) and `profile_bare` runs the bare
loop of `generate_vs_bare.py` in this process, both under cProfile; `breakdown` turns a profile
into milliseconds per sample for each part of the pipeline. A part is the cumulative time of the
functions that do it (matched by file and function name, so the split survives small moves),
with nested parts subtracted; "other" is whatever is left (per-sample Python: rows, labels,
random streams, bookkeeping). cProfile slows Python-heavy parts more than C-heavy ones (MuJoCo,
zlib), so the parts are a profile's split, and the benchmark's ratio is measured without it.
"""

from __future__ import annotations

import cProfile
import pstats
import shutil
import time
from pathlib import Path

# part -> (file name, function name) whose cumulative times add up to it; order = table order.
PARTS: dict[str, list[tuple[str, str]]] = {
    "object build (meshes, convex pieces)": [("library.py", "build_object")],
    "scene compile (MjSpec, MjData)": [("model.py", "compile_model"), ("press.py", "__init__")],
    "renderer set-up": [("topview.py", "__init__")],
    "grasp sampling (and redraws)": [("grasps.py", "sample")],
    "settle (mj_step, mj_forward)": [("~", "<built-in method mujoco._functions.mj_step>"),
                                     ("~", "<built-in method mujoco._functions.mj_forward>")],
    "press pose, force read, checks": [("press.py", "pose"), ("press.py", "_read"),
                                       ("checks.py", "check_physics")],
    "surface normals (labels' reference)": [("normals.py", "surface_normals")],
    "render (MuJoCo, 227 px)": [("topview.py", "render"), ("shot_render.py", "render_shot")],
    "finger boxes": [("topview.py", "finger_boxes"), ("shot_render.py", "shot_boxes")],
    "effects (force, scene, sensor)": [("registry.py", "apply_force"),
                                       ("registry.py", "apply_grasp"),
                                       ("session.py", "simulate_session")],
    "PNG encode": [("png.py", "encode_png")],
    "image write": [("files.py", "atomic_write_bytes"), ("pathlib.py", "write_bytes"),
                    ("chunks.py", "_write_image")],
    "shard write (Arrow per chunk)": [("shards.py", "write_shard")],
    "final tables and manifest": [("shards.py", "finalize")],
    "scene close": [("scenes.py", "close")],
}
# calls that do not count towards a part: the final tables write JSON too
NOT_FROM: dict[str, list[tuple[str, str]]] = {
    "image write": [("files.py", "atomic_write_json")],
}


def _matches(key: tuple, wanted: list[tuple[str, str]]) -> bool:
    file, _, func = key
    return any(func == f and (file == w or file.endswith("/" + w)) for w, f in wanted)


def _cumulative(stats: pstats.Stats, keys: list[tuple[str, str]],
                not_from: list[tuple[str, str]]) -> float:
    """Cumulative time of the functions `keys`, their calls to each other counted once, less
    their direct calls from `not_from`."""
    total = 0.0
    for key, (_, _, _, ct, callers) in stats.stats.items():  # type: ignore[attr-defined]
        if _matches(key, keys):
            total += ct - sum(v[3] for c, v in callers.items()
                              if _matches(c, keys) or _matches(c, not_from))
    return total


def breakdown(stats: pstats.Stats, total_s: float, n: int) -> dict[str, float]:
    """Milliseconds per sample of each part, "other" last (sums to total_s / n)."""
    out = {}
    for part, keys in PARTS.items():
        out[part] = _cumulative(stats, keys, NOT_FROM.get(part, []))
    out["other (rows, labels, streams, bookkeeping)"] = total_s - sum(out.values())
    return {k: round(1e3 * v / n, 4) for k, v in out.items()}


def _profiled(fn, *args) -> tuple[pstats.Stats, float]:
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    prof.enable()
    fn(*args)
    prof.disable()
    return pstats.Stats(prof), time.perf_counter() - t0


def profile_generate(n: int, seed: int, out: Path) -> dict[str, float]:
    """Per-sample breakdown (ms) of an in-process `generate` of `n` configurations."""
    # Imported before the clock, as generate's fork server imports the workers' modules and
    # pandas (`vistac_sim.generate.WORKER_MODULES`) before its workers start; the bare loop's
    # likewise.
    import importlib

    from vistac_sim.generate import WORKER_MODULES
    from vistac_sim.generate.config import GenerateCfg
    from vistac_sim.generate.run import generate

    for name in WORKER_MODULES:
        importlib.import_module(name)

    cfg = GenerateCfg.from_preset(noise=0.05, n=n, seed=seed)  # what the benchmark's CLI run uses
    shutil.rmtree(out, ignore_errors=True)
    stats, total = _profiled(generate, cfg, out, 1, False, False)
    shutil.rmtree(out, ignore_errors=True)
    return {"total": round(1e3 * total / n, 4), **breakdown(stats, total, n)}


def profile_bare(n: int, seed: int, out: Path) -> dict[str, float]:
    """Per-sample breakdown (ms) of the bare loop run in this process."""
    from generate_vs_bare import _bare_worker

    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    stats, total = _profiled(_bare_worker, (0, 1, n, str(out), seed))
    shutil.rmtree(out, ignore_errors=True)
    return {"total": round(1e3 * total / n, 4), **breakdown(stats, total, n)}
