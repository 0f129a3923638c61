"""sim-to-real for the study's CNN through the real path (issue 29 part 2): V3 pretrained on the
simulated twin, fine-tuned on a study-sized, photo-like "real" side read back by `vistac ingest`.

- **sim**: the twin ``sim_assets/scenes/study.yaml`` (``lab`` imperfections, 5 % noise,
  grasps within 10 degrees: calibrated against the study's table by ``study_replay.py``),
  ``--n-sim`` (3000) configurations of procedural objects split by object: the dataset of
  ``benchmarks/study_label_noise.py`` (the same settings; ``--sim D`` reuses one).
- **real**: ``--n-real`` (200, the study's 196) configurations of meshes the sim side never
  shows: ``--meshes`` convex solids made here with trimesh (`make_meshes`: ellipsoids, cones,
  frusta, capsules, wedges and random convex polytopes, none an extrusion like the procedural
  families) plus the two example meshes of ``sim_assets/meshes``. Rendered with ``--preset
  photo`` appearance and the twin's sensor and hand imperfections (the scene file
  `REAL_SCENE`, written into the work folder), written as FTS-3 recordings (``--recordings``)
  plus images, and read back by ``vistac ingest`` split by object (``--objects-csv``): the
  path a lab's recordings take, unchanged. Ingest leaves the finger boxes the study's views
  crop by NaN; training locates them in the images (`vistac_learn.data.located_boxes`), as
  the study found them with its finger finder.
- **experiments** (`vistac experiment sim2real`, fractions 0.1 0.33 1, ``--seeds`` 3):
  ``v3``: ``--protocol study`` (the real runs as the study trained: 20 fixed rotations, 20
  epochs); its sim-only pretraining with one random rotation per sample and epoch
  (``--sim-rotations random --sim-n-rotations 1``) for at least the replica's 12 960 optimiser
  steps (``--sim-epochs``); zero-shot, scratch and fine-tuned. ``v3-frozen``: the same with
  ``--freeze features`` (its sim-only and from-scratch runs are v3's, linked, not trained
  again).
  ``default``: the project's default recipe on the same data; ``default-lean``: the same
  without mirroring and contact targets (``--no-mirror --no-tta --aux-weight 0``), which keeps
  the twin's one-sided finger pull (docs/learner.md, "When the labels lean to one side").

Outputs: ``<results>/<name>.{json,md,png}``: per experiment the table (real test median angle
to the cone mean, % in cone, train CPU s per cell, mean ± std over seeds), the zero-shot gap and
the gain of pretraining per fraction; the figure: real test angle against the fraction of real
data, per arm and experiment. Resumable: the datasets and finished cells are kept; a rerun
continues, and ``--no-train`` only rewrites the results.

Cost (measured in `study_curve.py`'s runs on this machine, 2026-11-28, one thread per process;
CPU seconds, user + system): V3 trains at about 0.043 CPU s per sample with one random
rotation (fixed rotations are rendered once and cost a little less), the default recipe at
about 0.014. Per seed: pretraining at 4000 steps ~900 CPU s (at the replica's 12 960, ~2800);
the real runs as the study trained them (20 fixed rotations x 20 epochs over ~120
configurations at fraction 1: 48 000 samples) ~2000 CPU s at fraction 1, ~2900 over the three
fractions, twice (scratch and fine-tuned), the frozen fine-tuning ~1000 more: ~7800 CPU s a
seed, ~6.5 CPU h for 3 seeds at 4000 pretraining steps. Cut, pretraining steps first (the
curve found V3 the same at 4000 and 12 960 steps), seeds to 2 (never fewer); the real side
keeps the study's protocol. The command that fits ~6 CPU h:

    .venv/bin/python benchmarks/study_sim2real.py --sim runs/study_label_noise/data \
        --seeds 2 --sim-steps 4000

(V3 and its frozen fine-tuning ~4.4 CPU h, the default arms minutes each). Generating the
datasets costs minutes (the 200-configuration twin took 50 s wall here).

Usage:
    .venv/bin/python benchmarks/study_sim2real.py --sim runs/study_label_noise/data
    .venv/bin/python benchmarks/study_sim2real.py --n-sim 200 --n-real 60 --seeds 1 \\
        --fractions 0.5 1 --sim-epochs 1 --epochs 1 --default-epochs 1 --n-rotations 2 \\
        --work /tmp/x --results /tmp/x                                   # a quick look
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import os
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import trimesh  # noqa: E402
import yaml  # noqa: E402
from learnbench import (  # noqa: E402
    LEAN_LABEL,
    LEAN_RECIPE,
    cell_cpu_s,
    ensure_dataset,
    save,
    timed_runner,
)
from study_label_noise import (  # noqa: E402
    REPLICA_STEPS,
    SCENE,
    TWIN_NOTE,
    msd,
    save_figure,
    study_parser,
    twin_data,
    v3_epochs,
)

import vistac  # noqa: E402
from vistac.dataset import SplitCfg, open_tables  # noqa: E402
from vistac.dataset.ingest.config import IngestSources  # noqa: E402
from vistac_learn.experiments import sim2real as S  # noqa: E402
from vistac_learn.experiments.cells import open_experiment, pm, read_rows  # noqa: E402
from vistac_learn.train.config import TrainCfg  # noqa: E402
from vistac_sim.assets import EXAMPLE_MESHES  # noqa: E402
from vistac_sim.effects.presets import PRESETS, load_scene  # noqa: E402
from vistac_sim.generate.config import GenerateCfg  # noqa: E402
from vistac_sim.objects.config import ObjectsCfg  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "benchmarks" / "results"
EXPERIMENTS = {"v3": "SchoeConv100-V3(FC160), study protocol",
               "v3-frozen": "SchoeConv100-V3(FC160), fine-tuned with --freeze features",
               "default": "default recipe (pinchnet, pinch view)",
               "default-lean": LEAN_LABEL}
COLOURS = {"v3": "tab:blue", "v3-frozen": "tab:orange", "default": "tab:green",
           "default-lean": "tab:purple"}
ARMS = {"sim-only": "sim only (zero-shot)", "scratch": "from scratch",
        "finetune": "sim-pretrained, fine-tuned"}


def real_scene(path: Path, twin: Path = SCENE) -> Path:
    """A scene file: the `photo` preset's appearance with the twin's sensor and hand
    imperfections (the twin's preset's effects but its shadows, which `photo` sets, then the
    twin's own effects, recording and physics)."""
    twin_data_ = load_scene(twin)
    base = dict(PRESETS[twin_data_.get("preset", "clean")].get("effects", {}))
    base.pop("shadows", None)  # the photo preset's own soft shadows
    scene = {"preset": "photo", "effects": {**base, **twin_data_.get("effects", {})}}
    for key in ("recording", "physics"):
        if key in twin_data_:
            scene[key] = twin_data_[key]
    path.parent.mkdir(parents=True, exist_ok=True)
    text = ("# written by benchmarks/study_sim2real.py: the photo preset with the sensor and hand "
            f"imperfections of {twin.name}\n" + yaml.safe_dump(scene, sort_keys=True))
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path


def make_meshes(folder: Path) -> list[Path]:
    """Convex solids the procedural families (extrusions) never show, written as OBJ (sizes are
    rescaled by the generator to its footprint range), plus the example meshes."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(29)
    made: dict[str, trimesh.Trimesh] = {}
    for i, axes in enumerate(((1, 0.6, 0.5), (1, 0.8, 0.35), (1, 0.45, 0.45), (1, 1, 0.6))):
        made[f"ellipsoid_{i}.obj"] = trimesh.creation.icosphere(3).apply_scale(axes)
    for i, (r, h) in enumerate(((1.0, 1.2), (0.7, 1.6))):
        made[f"cone_{i}.obj"] = trimesh.creation.cone(r, h, sections=48)
    for i, (r1, r2, h) in enumerate(((1.0, 0.5, 0.8), (1.0, 0.7, 0.4))):
        ring = np.linspace(0, 2 * np.pi, 40, endpoint=False)
        pts = [(r * np.cos(a), r * np.sin(a), z) for r, z in ((r1, 0.0), (r2, h)) for a in ring]
        made[f"frustum_{i}.obj"] = trimesh.convex.convex_hull(np.array(pts))
    for i, (r, h) in enumerate(((0.4, 2.0), (0.5, 1.2))):
        cap = trimesh.creation.capsule(height=h, radius=r, count=[24, 24])
        made[f"capsule_{i}.obj"] = cap.apply_transform(
            trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
    wedge = np.array([(0, 0, 0), (2, 0, 0), (0, 1.2, 0), (2, 1.2, 0), (0, 0, 0.9), (0, 1.2, 0.9)])
    made["wedge.obj"] = trimesh.convex.convex_hull(wedge)
    for i in range(5):
        pts = rng.normal(size=(12 + 3 * i, 3)) * (1.0, rng.uniform(0.5, 1.0), 0.5)
        made[f"polytope_{i}.obj"] = trimesh.convex.convex_hull(pts)
    paths = []
    for name, mesh in made.items():
        path = folder / name
        if not path.exists():
            mesh.export(path)
        paths.append(path)
    return [*paths, EXAMPLE_MESHES / "knob_m.obj", EXAMPLE_MESHES / "bracket_mm.stl"]


def real_data(work: Path, args: argparse.Namespace) -> Path:
    """Generate the real side with recordings and ingest its recordings and images (the finger
    boxes stay NaN: training locates them)."""
    out = work / "real"
    gen = work / "real_generated"
    if not (out / "manifest.json").exists():
        cfg = GenerateCfg.from_file(real_scene(work / "real_scene.yaml", Path(args.scene)),
                                    n=args.n_real, seed=args.real_seed, recordings=True,
                                    objects=ObjectsCfg(paths=tuple(map(str, make_meshes(
                                        work / "meshes")))))
        ensure_dataset(gen, cfg)
        configs = open_tables(gen).configs
        objects = work / "real_objects.csv"
        with objects.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["config_id", "object_id"])
            for c, o in zip(configs["config_id"], configs["object_id"], strict=True):
                w.writerow([int(c), o])
        split = SplitCfg(by="object", fractions=tuple(args.real_split))
        vistac.ingest(IngestSources(images=gen / "images", recordings=gen / "recordings",
                                    objects_csv=objects, split=split, seed=args.real_seed), out)
    return out


def base_cfgs(args: argparse.Namespace, n_sim_train: int) -> dict[str, tuple[TrainCfg, dict]]:
    """Per experiment: the runs' settings and the `Sim2RealCfg` extras."""
    study = TrainCfg.from_protocol("study", epochs=args.epochs, n_rotations=args.n_rotations,
                                   device="cpu", max_missing_pct=args.max_missing_pct)
    sim_epochs = args.sim_epochs or v3_epochs(n_sim_train, study.batch_size, args.sim_steps)
    pre = {"sim_epochs": sim_epochs, "sim_rotations": "random", "sim_n_rotations": 1}
    default = TrainCfg.from_protocol("default", epochs=args.default_epochs, device="cpu",
                                     max_missing_pct=args.max_missing_pct)
    return {"v3": (study, {**pre, "freeze": "none"}),
            "v3-frozen": (study, {**pre, "freeze": "features"}),
            "default": (default, {"freeze": "none"}),
            "default-lean": (dataclasses.replace(default, **LEAN_RECIPE), {"freeze": "none"})}


def link_shared_runs(work: Path, cfg: S.Sim2RealCfg, base: TrainCfg) -> None:
    """The frozen experiment's sim-only and from-scratch runs are v3's (the same settings; only
    the fine-tuned ones freeze): its folder is made as `vistac.sim2real` makes it, and its
    ``runs/sim/seed-S`` and ``runs/scratch/fraction-F/seed-S`` link to v3's (their cells are
    scored again, not trained)."""
    cfg = S.resolved(cfg)
    open_experiment(cfg, dataclasses.replace(base, data=cfg.real, out=""), S.KIND)
    shared = [Path("sim") / f"seed-{s}" for s in range(cfg.seeds)]
    shared += [Path("scratch") / f"fraction-{f:g}" / f"seed-{s}" for f in cfg.fractions
               for s in range(cfg.seeds)]
    missing = [p for p in shared if not (work / "v3" / "runs" / p / "metrics.csv").exists()]
    if missing:
        raise SystemExit(f"v3-frozen shares v3's runs: run the v3 experiment first (no "
                         f"{work / 'v3' / 'runs' / missing[0]})")
    for part in shared:
        link = Path(cfg.out) / "runs" / part
        if not link.exists() and not link.is_symlink():
            link.parent.mkdir(parents=True, exist_ok=True)
            os.symlink((work / "v3" / "runs" / part).resolve(), link, target_is_directory=True)


def run_experiment(name: str, sim: Path, real: Path, args: argparse.Namespace,
                   base: TrainCfg, extra: dict) -> Path:
    work = Path(args.work)
    cfg = S.Sim2RealCfg(sim=str(sim), real=str(real), out=str(work / name),
                        fractions=tuple(args.fractions), seeds=args.seeds, **extra)
    if name == "v3-frozen":
        link_shared_runs(work, cfg, base)
    if not args.no_train:
        vistac.sim2real(cfg, base, progress=not args.quiet,
                        runner=timed_runner(work / f"{name}_cpu_s.json"))
    return Path(cfg.out)


def summary(out: Path, timing: Path) -> list[dict]:
    """Per arm and fraction: mean +- std over seeds of the real test angle, % in cone, the sim
    test angle and the cells' CPU s."""
    rows = [r for r in read_rows(out / "cells.csv") if r["status"] == "ok"]
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["arm"], float(r["fraction"])), []).append(r)
    res = []
    for (arm, fraction), mine in groups.items():
        s = {"arm": arm, "fraction": fraction, "n": len(mine)}
        for k in ("test_angle_deg", "test_in_cone_pct", "sim_test_angle_deg", "val_angle_deg"):
            s[k] = msd(r[k] for r in mine)
        s["cpu_s"] = msd(c for r in mine if (c := cell_cpu_s(timing, r["run"])) is not None)
        res.append(s)
    return res


def findings(label: str, rows: list[dict]) -> str:
    """The zero-shot gap and the gain of pretraining per fraction, in sentences."""
    find = {(r["arm"], r["fraction"]): r for r in rows}
    out = []
    sim = find.get(("sim-only", 0.0))
    if sim:
        a, b = sim["sim_test_angle_deg"]["mean"], sim["test_angle_deg"]["mean"]
        out.append(f"zero-shot, the sim-only model scores {a:.2f} deg on the sim test split and "
                   f"{pm(b, sim['test_angle_deg']['std'], 2)} deg on the real one "
                   f"({b - a:+.2f} deg from the change of domain)")
    gains = []
    for f in sorted({r["fraction"] for r in rows if r["arm"] != "sim-only"}):
        sc, ft = find.get(("scratch", f)), find.get(("finetune", f))
        if sc and ft:
            d = sc["test_angle_deg"]["mean"] - ft["test_angle_deg"]["mean"]
            spread = sc["test_angle_deg"]["std"] + ft["test_angle_deg"]["std"]
            verdict = ("helps" if d > spread else "hurts" if -d > spread
                       else "is within the seeds' spread")
            gains.append(f"at fraction {f:g} pretraining {verdict} "
                         f"({sc['test_angle_deg']['mean']:.2f} -> "
                         f"{ft['test_angle_deg']['mean']:.2f} deg, {d:+.2f})")
    if gains:
        out.append("; ".join(gains))
    return f"**{label}**: " + ("; ".join(out) if out else "no cells finished yet") + "."


def table(rows: list[dict]) -> str:
    lines = ["| model | real training data | seeds | real test angle (deg) | real test % in "
             "cone | sim test angle (deg) | train CPU s |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        frac = "none" if r["arm"] == "sim-only" else f"{r['fraction']:g}"
        sim = pm(r["sim_test_angle_deg"]["mean"], r["sim_test_angle_deg"]["std"], 2)
        lines.append(f"| {ARMS[r['arm']]} | {frac} | {r['n']} | "
                     f"{pm(r['test_angle_deg']['mean'], r['test_angle_deg']['std'], 2)} | "
                     f"{pm(r['test_in_cone_pct']['mean'], r['test_in_cone_pct']['std'])} | "
                     f"{sim if r['arm'] == 'sim-only' else '-'} | "
                     f"{pm(r['cpu_s']['mean'], r['cpu_s']['std'], 0)} |")
    return "\n".join(lines)


def plot(exps: dict, path: Path) -> None:
    """Real test angle against the fraction of real training data: scratch (dotted), fine-tuned
    (solid), zero-shot (a horizontal band), one colour per experiment."""
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for name, e in exps.items():
        colour, rows = COLOURS[name], e["summary"]
        for arm, style in (("scratch", "o:"), ("finetune", "s-")):
            mine = sorted((r for r in rows if r["arm"] == arm), key=lambda r: r["fraction"])
            if mine and not (name == "v3-frozen" and arm == "scratch"):
                ax.errorbar([r["fraction"] for r in mine],
                            [r["test_angle_deg"]["mean"] for r in mine],
                            yerr=[r["test_angle_deg"]["std"] for r in mine], fmt=style,
                            capsize=4, color=colour, label=f"{name}: {ARMS[arm]}")
        sim = next((r for r in rows if r["arm"] == "sim-only"), None)
        if sim and name != "v3-frozen":
            m, s = sim["test_angle_deg"]["mean"], sim["test_angle_deg"]["std"]
            ax.axhspan(m - s, m + s, color=colour, alpha=0.15)
            ax.axhline(m, color=colour, ls="--", lw=1, label=f"{name}: zero-shot")
    ax.set_xscale("log")
    ax.set_xlabel("fraction of the real training split")
    ax.set_ylabel("real test median angle to the cone mean (deg)")
    ax.set_title("sim-to-real through ingest (the calibrated twin); mean ± std over seeds",
                 fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    save_figure(fig, path)


def main(argv: list[str] | None = None) -> int:
    p = study_parser(__doc__, "study_sim2real", "datasets")
    p.add_argument("--sim", default=None, help="an existing twin dataset (e.g. "
                   "study_label_noise.py's <work>/data); default: made in <work>/sim")
    p.add_argument("--n-sim", type=int, default=3000, help="simulated configurations")
    p.add_argument("--sim-seed", type=int, default=29, help="the sim dataset's seed")
    p.add_argument("--n-real", type=int, default=200, help="real-side configurations")
    p.add_argument("--real-seed", type=int, default=30, help="the real side's seed (and split)")
    p.add_argument("--real-split", type=float, nargs=3, default=[0.6, 0.2, 0.2],
                   help="train / val / test fractions of the real side's objects")
    p.add_argument("--fractions", type=float, nargs="+", default=[0.1, 0.33, 1.0])
    p.add_argument("--experiments", nargs="+", default=list(EXPERIMENTS),
                   choices=tuple(EXPERIMENTS))
    p.add_argument("--epochs", type=int, default=20, help="V3 real-side epochs (the study's)")
    p.add_argument("--n-rotations", type=int, default=20, help="V3 real-side fixed rotations")
    p.add_argument("--sim-steps", type=int, default=REPLICA_STEPS,
                   help="V3 pretraining: at least this many optimiser steps (sets --sim-epochs)")
    p.add_argument("--sim-epochs", type=int, default=None,
                   help="V3 pretraining epochs instead (a cut of --sim-steps: say so)")
    p.add_argument("--default-epochs", type=int, default=25, help="default recipe's epochs")
    p.add_argument("--max-missing-pct", type=float, default=10.0,
                   help="fingertips the locator may miss in the photographs (%%)")
    p.add_argument("--data-only", action="store_true", help="make the datasets and stop")
    args = p.parse_args(argv)
    work = Path(args.work)
    sim = Path(args.sim) if args.sim else twin_data(work / "sim", args.n_sim, args.sim_seed,
                                                    args.n_objects, Path(args.scene))
    real = real_data(work, args)
    man = json.loads((real / "manifest.json").read_text())
    sim_train = len(open_tables(sim).rows("train"))
    if args.data_only:
        print(f"datasets: {sim} {real}: {man['counts']}")
        return 0
    cfgs = base_cfgs(args, sim_train)
    exps = {}
    for name in args.experiments:
        base, extra = cfgs[name]
        out = run_experiment(name, sim, real, args, base, extra)
        rows = summary(out, work / f"{name}_cpu_s.json")
        exps[name] = {"label": EXPERIMENTS[name], "summary": rows, "table": table(rows),
                      "finding": findings(EXPERIMENTS[name], rows), "experiment": str(out),
                      "settings": {"epochs": base.epochs, "n_rotations": base.n_rotations,
                                   "rotations": base.rotations, **extra}}
    fr = " ".join(f"{f:g}" for f in args.fractions)
    pre = cfgs["v3"][1]
    commands = [
        f"vistac generate --scene {Path(args.scene).name} --n {args.n_sim} --n-objects "
        f"{args.n_objects} --split-by object --seed {args.sim_seed} --out SIM"
        if not args.sim else f"SIM = {sim}",
        f"vistac generate --scene real_scene.yaml --objects MESHES --n {args.n_real} --seed "
        f"{args.real_seed} --recordings --out GEN",
        f"vistac ingest --recordings GEN/recordings --images GEN/images --objects-csv "
        f"real_objects.csv --split-by object --split {' '.join(map(str, args.real_split))} "
        f"--seed {args.real_seed} --out REAL",
        f"vistac experiment sim2real --sim SIM --real REAL --fractions {fr} --seeds "
        f"{args.seeds} --protocol study --epochs {args.epochs} --n-rotations {args.n_rotations} "
        f"--sim-epochs {pre['sim_epochs']} --sim-rotations random --sim-n-rotations 1 "
        f"--max-missing-pct {args.max_missing_pct:g} [--freeze features] --out v3",
        f"vistac experiment sim2real --sim SIM --real REAL --fractions {fr} --seeds "
        f"{args.seeds} --epochs {args.default_epochs} --max-missing-pct "
        f"{args.max_missing_pct:g} [--no-mirror --no-tta --aux-weight 0] --out default"]
    md = [f"# sim-to-real for the study's CNN, through `vistac ingest`\n\n{TWIN_NOTE}\n",
          "```bash\n" + "\n".join(commands) + "\n```\n",
          f"Sim: {sim_train} training configurations of procedural objects. Real: "
          f"{man['counts']['configs']} ingested configurations of {man['counts']['objects']} "
          f"meshes the sim side never shows (split {man['counts']['split']}), photo-like, "
          "with the twin's sensor and hand imperfections. Angles: median angle to the cone "
          "mean on the real test split (V3: index finger; default: mean of both); the epoch "
          "chosen on the validation split of the dataset trained on; mean ± std over seeds; "
          "train CPU s: training and scoring of one cell, 2 shared cores (the frozen "
          "experiment's sim-only and from-scratch cells are v3's runs, scored again).\n"]
    for e in exps.values():
        s = e["settings"]
        md += [f"## {e['label']}\n", f"Real runs: {s['epochs']} epochs, rotations "
               f"{s['rotations']} x {s['n_rotations']}" + (
                   f"; sim pretraining: {s['sim_epochs']} epochs of one random rotation"
                   if "sim_epochs" in s else "") + f"; fine-tuning freezes {s['freeze']}.\n",
               e["table"], "", e["finding"], ""]
    md.append(f"![sim2real]({args.name}.png)")
    result = {"note": TWIN_NOTE, "sim": str(sim), "real": str(real),
              "real_counts": man["counts"], "commands": commands, "settings": vars(args),
              "experiments": exps, "meshes": sorted(p.name for p in (work / "meshes").glob("*"))}
    save(Path(args.results), args.name, json.loads(json.dumps(result, default=str)),
         "\n".join(md), datasets=(sim, real))
    plot(exps, Path(args.results) / f"{args.name}.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
