"""sim2real with a photo-like "real" side: pretrain on clean simulated images of procedural
objects, fine-tune on photographs (`--preset photo`) of other objects (real meshes).

The two datasets (made here unless they exist; generation resumes):

- sim: ``vistac generate --n N_SIM --noise 0.05 --seed 21 --split-by object`` (the
  procedural families, flat-colour renders); ``--sim D`` uses an existing clean dataset instead;
- real: ``vistac generate --n N_REAL --noise 0.05 --seed 22 --split-by object --preset photo
  --objects MESHES``, MESHES: 11 meshes of the `pybullet` wheel that
  ``benchmarks/mesh_collection.py`` uses (`REAL_MESHES`: the bunny, duck and mug scans, spheres,
  a wheel, toy blocks, jenga and domino pieces) and the knob example mesh of
  ``sim_assets/meshes``. They are not the procedural families, so the target differs in objects
  and in appearance; the labels come from the same physics.

Then ``vistac experiment sim2real --sim SIM --real REAL --fractions F.. --seeds S --epochs E
--out OUT/s2r`` (through the Python API; a killed run continues where it stopped when the same
command runs again). Writes ``sim2real_photo.md`` / ``.json`` / ``.png`` into ``--results``: the
experiment's table, the zero-shot gap (the sim-only model on the sim test split and on the real
test split), the gain of fine-tuning over training from scratch per fraction, the commands,
wall and CPU time and the machine.

Usage:
    python benchmarks/sim2real_photo.py --out bench/s2r_photo --seeds 2 --epochs 15
    python benchmarks/sim2real_photo.py --out bench/s2r_photo --sim D   # an existing clean D
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import resource
import shutil
import time
from pathlib import Path

from learnbench import ensure_dataset, headline_data, save
from mesh_collection import fetch_pybullet

import vistac
from vistac_learn.experiments.sim2real import Sim2RealCfg
from vistac_sim.assets import EXAMPLE_MESHES
from vistac_sim.objects.config import ObjectsCfg

# The target's objects: the convex meshes of the collection (no decomposition needed) and three
# scans whose CoACD decomposition is cheap enough to make once (it is cached on disk); the other
# non-convex meshes cost minutes of CPU each on the shared 2-core machine.
REAL_MESHES = ("bunny.obj", "duck.obj", "objects/mug.obj", "sphere_smooth.obj", "soccerball.obj",
               "toys/cylinder.obj", "toys/prism.obj", "toys/cube.obj", "jenga/jenga.obj",
               "domino/domino.obj", "racecar/meshes/left_front_wheel.STL")


def real_meshes(folder: Path, wheel: str | None) -> list[Path]:
    """The target's objects: `REAL_MESHES` of the pybullet wheel and the knob example mesh."""
    root = folder / "pybullet_data"
    chosen = [p for p in fetch_pybullet(folder, wheel)
              if p.relative_to(root).as_posix() in REAL_MESHES]
    return [*chosen, EXAMPLE_MESHES / "knob_m.obj"]


def cpu_s() -> float:
    """CPU seconds of this process and its finished children."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def summary_row(rows: list[dict], arm: str, fraction: float) -> dict | None:
    return next((r for r in rows if r["arm"] == arm and abs(float(r["fraction"]) - fraction)
                 < 1e-9), None)


def read_results(path: Path) -> list[dict]:
    """``results.csv`` of the experiment (mean and std over seeds per arm and fraction)."""
    import csv

    with path.open() as fh:
        return list(csv.DictReader(fh))


def gap_lines(results: list[dict], fractions: list[float]) -> tuple[list[str], dict]:
    """The zero-shot gap and the fine-tuning gain per fraction, as sentences and numbers."""
    out, nums = [], {}
    sim = summary_row(results, "sim-only", 0.0)
    if sim:
        a, b = float(sim["sim_test_angle_deg_mean"]), float(sim["test_angle_deg_mean"])
        nums["zero_shot"] = {"sim_test_deg": a, "real_test_deg": b, "gap_deg": b - a}
        out.append(f"Zero-shot gap: the sim-only model scores {a:.2f} deg on the sim test split "
                   f"and {b:.2f} deg on the photo test split ({b - a:+.2f} deg).")
    gains = {}
    for f in fractions:
        sc, ft = summary_row(results, "scratch", f), summary_row(results, "finetune", f)
        if sc and ft:
            gains[f"{f:g}"] = {"scratch_deg": float(sc["test_angle_deg_mean"]),
                               "finetune_deg": float(ft["test_angle_deg_mean"]),
                               "gain_deg": float(sc["test_angle_deg_mean"])
                               - float(ft["test_angle_deg_mean"])}
    if gains:
        nums["gain"] = gains
        out.append("Fine-tuning gain over from scratch (deg, positive: pretraining helps): "
                   + "; ".join(f"fraction {k}: {g['gain_deg']:+.2f} ({g['scratch_deg']:.2f} -> "
                               f"{g['finetune_deg']:.2f})" for k, g in gains.items()) + ".")
    return out, nums


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("bench/s2r_photo"),
                    help="work folder (datasets, meshes, the experiment)")
    ap.add_argument("--results", type=Path, default=Path("benchmarks/results"))
    ap.add_argument("--sim", type=Path, default=None,
                    help="an existing clean dataset as the source (default: N_SIM made here)")
    ap.add_argument("--n-sim", type=int, default=1000)
    ap.add_argument("--n-real", type=int, default=800)
    ap.add_argument("--wheel", default=None, help="pybullet 3.2.7 wheel (default: from PyPI)")
    ap.add_argument("--fractions", type=float, nargs="+", default=[0.1, 0.33, 1.0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--epochs", type=int, default=15, help="epochs of every run (default: "
                    "the default recipe's)")
    ap.add_argument("--max-missing-pct", type=float, default=10.0,
                    help="--max-missing-pct of the runs: the locator loses a few %% of the "
                    "fingertips in photographs (default 1 refuses them)")
    ap.add_argument("--max-cells", type=int, default=None,
                    help="stop after this many new cells (run again to continue)")
    ap.add_argument("--data-only", action="store_true", help="make the datasets and stop")
    ap.add_argument("--name", default="sim2real_photo")
    a = ap.parse_args()
    t0, c0 = time.perf_counter(), cpu_s()
    sim = a.sim or ensure_dataset(a.out / "sim", headline_data(a.n_sim, seed=21))
    meshes = real_meshes(a.out / "meshes", a.wheel)
    real_cfg = dataclasses.replace(headline_data(a.n_real, seed=22, preset="photo"),
                                   objects=ObjectsCfg(paths=tuple(map(str, meshes))))
    real = ensure_dataset(a.out / "real", real_cfg)
    data_s = time.perf_counter() - t0
    if a.data_only:
        print(f"datasets: {sim} {real} ({data_s:.0f} s)")
        return
    cfg = Sim2RealCfg(sim=str(sim), real=str(real), out=str(a.out / "s2r"),
                      fractions=tuple(a.fractions), seeds=a.seeds)
    base = vistac.TrainCfg.from_protocol("default", epochs=a.epochs, device="cpu",
                                         max_missing_pct=a.max_missing_pct)
    vistac.sim2real(cfg, base, max_cells=a.max_cells, progress=True)
    report = (a.out / "s2r" / "report.md").read_text()
    results = read_results(a.out / "s2r" / "results.csv")
    lines, nums = gap_lines(results, sorted(a.fractions))
    man = json.loads((Path(real) / "manifest.json").read_text())
    commands = [
        f"vistac generate --n {a.n_sim} --noise 0.05 --seed 21 --split-by object --out SIM"
        if a.sim is None else f"SIM = {sim}",
        f"vistac generate --n {a.n_real} --noise 0.05 --seed 22 --split-by object "
        "--preset photo --objects MESHES --out REAL",
        f"vistac experiment sim2real --sim SIM --real REAL --fractions "
        f"{' '.join(f'{f:g}' for f in a.fractions)} --seeds {a.seeds} --epochs {a.epochs} "
        f"--max-missing-pct {a.max_missing_pct:g} --out s2r"]
    result = {"sim": str(sim), "real": str(real), "meshes": [str(m) for m in meshes],
              "real_counts": man["counts"], "skipped_meshes": man.get("skipped_meshes"),
              "commands": commands, "fractions": a.fractions, "seeds": a.seeds,
              "epochs": a.epochs, "results": results, **nums,
              "wall_s": time.perf_counter() - t0, "data_wall_s": data_s,
              "cpu_s": cpu_s() - c0}
    md = ("# sim2real, photo-like real side\n\n```bash\n" + "\n".join(commands) + "\n```\n\n"
          f"Real side: {man['counts']['configs']} configurations of {man['counts']['objects']} "
          f"meshes (split {man['counts']['split']}). This invocation: "
          f"{result['wall_s']:.0f} s wall, {result['cpu_s']:.0f} s CPU (a resumed run counts "
          "only its own part).\n\n" + "\n\n".join(lines) + "\n\n"
          + report.split("\n", 1)[1].replace("![sim2real](sim2real.png)", "").strip())
    save(a.results, a.name, result, md, datasets=(sim, real))
    shutil.copyfile(a.out / "s2r" / "sim2real.png", a.results / f"{a.name}.png")


if __name__ == "__main__":
    main()
