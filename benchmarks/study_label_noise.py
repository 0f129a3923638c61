"""Label noise at scale (issue 29 part 1): `vistac experiment label-noise` on the study twin for
the project's default recipe and for the study's CNN, SchoeConv100-V3(FC160).

The data: ``--n`` (3000) configurations of the twin ``sim_assets/scenes/study.yaml`` (the
``lab`` imperfections, 5 % force noise, grasps within 10 degrees of the normal: the twin
calibrated against the study's table by ``study_replay.py``) split by object, generated once
into ``<work>/data``. Its clean forces are redrawn at each level of ``--levels`` (0 0.02 0.05
0.1 0.2 0.4) and seed (``--seeds`` 3) by the generator's own noise model; per level and seed
one model is trained on the noisy labels, selected on the validation split and scored once on
the test split against the clean labels and against the noisy cones.

The models (``--models``):

- ``default``: `vistac train`'s default recipe (pinch view, pinchnet, both fingers),
  ``--default-epochs`` epochs;
- ``default-lean``: the same without mirroring and contact targets (``--no-mirror --no-tta
  --aux-weight 0``), which keeps the twin's one-sided finger pull that mirroring averages away
  (docs/learner.md, "When the labels lean to one side"; on the twin it is the project's best);
- ``v3``: ``--protocol study`` with the rotations reduced as in issue 35's learning curve: one
  random rotation per sample and epoch (``--rotations random --n-rotations 1``) for as many
  epochs as give at least ``--v3-steps`` optimiser steps (default: the replica's, 162
  configurations x 20 rotations x 20 epochs / batch 5 = 12 960), or ``--v3-epochs`` when given
  (a cut: say so).

Beside each level: the noise in the labels themselves (median angle of a noisy test press label
to its clean label) and the noise floor (the clean forces scored against the noisy cones: the
angle to the noisy cone mean and the % in the noisy cone no predictor beats on average), over
the same fingers as the model (V3: index; default: both).

Outputs: ``<results>/<name>.{json,md,png}`` (the tables, the finding per model, the figure: angle
to the clean label, angle to the noisy cone mean and % in the noisy cone against the noise
level, each level's floor dashed), the experiments in ``<work>/<model>/`` (cells.csv,
report.md). Resumable: one cell at a time; a rerun skips finished cells (continuing an
interrupted run from its last epoch) and rewrites the results, so an interrupted job loses at
most one epoch. CPU seconds are measured per cell (training and its two test scorings,
`learnbench.timed_runner`) and kept in ``<work>/<model>_cpu_s.json``.

Cost (measured in `study_curve.py`'s runs on this machine, 2026-11-28, one thread per process;
CPU seconds, user + system): V3 with one random rotation ~0.043 CPU s per training sample
(866 CPU s for 4000 steps), the default recipe ~0.014 (442 CPU s for 21 epochs over 1500
configurations). On the 3000-configuration dataset (2059 training configurations) a V3 cell at
the replica's 12 960 steps is ~2800 CPU s, 18 cells ~14 CPU h: far over the 6-hour budget. At
4000 steps (10 epochs; `study_curve.py` found V3 the same at 4000 and 12 960 steps on the
twin) a cell is ~900 CPU s; a default-recipe cell of 15 epochs (the curve's ~31 000 samples)
~450. The command that fits ~6 CPU h, seeds cut to 2 (never fewer):

    .venv/bin/python benchmarks/study_label_noise.py --seeds 2 --v3-steps 4000 \
        --default-epochs 15 --models default-lean v3 default

(12 cells each: V3 ~3 CPU h, each default arm ~1.5). The results state the epochs and steps.

Usage:
    .venv/bin/python benchmarks/study_label_noise.py                      # the whole run
    .venv/bin/python benchmarks/study_label_noise.py --models v3          # V3 only
    .venv/bin/python benchmarks/study_label_noise.py --n 200 --levels 0 0.2 --seeds 1 \\
        --v3-epochs 1 --default-epochs 1 --work /tmp/x --results /tmp/x   # a quick look
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from learnbench import (  # noqa: E402
    LEAN_LABEL,
    LEAN_RECIPE,
    cell_cpu_s,
    ensure_dataset,
    save,
    timed_runner,
)

import vistac  # noqa: E402
from vistac.dataset import SplitCfg, open_tables  # noqa: E402
from vistac_learn.evaluate.references import noise_floor  # noqa: E402
from vistac_learn.experiments.cells import mean_std, pm, read_rows  # noqa: E402
from vistac_learn.experiments.label_noise import LabelNoiseCfg  # noqa: E402
from vistac_learn.train.config import TrainCfg  # noqa: E402
from vistac_sim.generate.config import GenerateCfg  # noqa: E402
from vistac_sim.objects.config import ObjectsCfg  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
SCENE = REPO / "sim_assets" / "scenes" / "study.yaml"
RESULTS = REPO / "benchmarks" / "results"
REPLICA_STEPS = 162 * 20 * 20 // 5  # the study's 162 configurations x 20 rotations x 20 epochs
LABELS = {"default": "default recipe (pinchnet, pinch view)",
          "default-lean": LEAN_LABEL,
          "v3": "SchoeConv100-V3(FC160), study protocol, 1 random rotation"}
COLOURS = {"v3": "tab:blue", "default": "tab:green", "default-lean": "tab:purple"}
TWIN_NOTE = ("The twin (`sim_assets/scenes/study.yaml`: the `lab` imperfections, 5 % force noise, "
             "grasps within 10 degrees of the normal) is the one calibrated against the study's "
             "table (`benchmarks/study_replay.py`: V3 at 162 configurations scores 92.1 % "
             "correct y, 38.8 % in cone against the study's 91.6 and 41.7).")


def msd(values) -> dict:
    """{mean, std, n} of the finite values (`mean_std`)."""
    return dict(zip(("mean", "std", "n"), mean_std(list(values)), strict=True))


def study_parser(doc: str, name: str, what: str) -> argparse.ArgumentParser:
    """A parser with the options both study scripts share: work folder, results, name, the
    twin, seeds, --no-train, --quiet."""
    p = argparse.ArgumentParser(description=doc.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--work", default=str(REPO / "runs" / name),
                   help=f"folder of the {what} and the experiments (kept for resuming)")
    p.add_argument("--results", default=str(RESULTS), help="where <name>.json|md|png go")
    p.add_argument("--name", default=name, help="results file name")
    p.add_argument("--scene", default=str(SCENE), help="the twin's scene file")
    p.add_argument("--n-objects", type=int, default=64, help="procedural objects of the twin")
    p.add_argument("--seeds", type=int, default=3, help="seeds per cell")
    p.add_argument("--no-train", action="store_true", help="only rewrite the results")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    return p


def save_figure(fig, path: Path) -> None:
    """Lay out, write (110 dpi) and close a figure."""
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def twin_data(work: Path, n: int, seed: int, n_objects: int, scene: Path = SCENE) -> Path:
    """The study twin's dataset of `n` configurations split by object (made once, resumed)."""
    cfg = GenerateCfg.from_file(scene, n=n, seed=seed, objects=ObjectsCfg(n_objects=n_objects),
                                split=SplitCfg(by="object"))
    return ensure_dataset(work, cfg)


def v3_epochs(n_train: int, batch: int, steps: int) -> int:
    """Epochs of one sample per configuration that give at least `steps` optimiser steps."""
    return max(1, math.ceil(steps / math.ceil(n_train / batch)))


def base_cfg(model: str, args: argparse.Namespace, n_train: int) -> TrainCfg:
    """The runs' training settings of `model` (data, out and seed are set per cell)."""
    if model.startswith("default"):
        lean = LEAN_RECIPE if model == "default-lean" else {}
        return TrainCfg.from_protocol("default", epochs=args.default_epochs, device="cpu",
                                      **lean)
    study = TrainCfg.from_protocol("study")
    epochs = args.v3_epochs or v3_epochs(n_train, study.batch_size, args.v3_steps)
    return TrainCfg.from_protocol("study", rotations="random", n_rotations=1, epochs=epochs,
                                  device="cpu")


def run_model(model: str, data: Path, args: argparse.Namespace, base: TrainCfg) -> Path:
    """The label-noise experiment of one model (continued where it stopped), each cell's CPU
    seconds kept in ``<work>/<model>_cpu_s.json``."""
    out = Path(args.work) / model
    cfg = LabelNoiseCfg(data=str(data), out=str(out), levels=tuple(args.levels),
                        seeds=args.seeds)
    vistac.label_noise(cfg, base, progress=not args.quiet,
                       runner=timed_runner(Path(args.work) / f"{model}_cpu_s.json"))
    return out


def floors(out: Path, fingers: tuple[str, ...], levels, seeds: int) -> dict[float, dict]:
    """Per level: the noise floor's angle to the noisy cone mean and % in the noisy cone on the
    test split, mean of `fingers`, mean +- std over the seeds' noisy datasets."""
    res = {}
    for level in levels:
        vals = {"angle": [], "in_cone": []}
        for s in range(seeds):
            folder = out / "data" / f"noise-{level:g}-seed-{s}"
            if not (folder / "manifest.json").exists():
                continue
            t = open_tables(folder)
            m = noise_floor(t, t.rows("test"), fingers)
            vals["angle"].append(np.mean([m[f]["angle_to_mean_median_deg"] for f in fingers]))
            vals["in_cone"].append(np.mean([m[f]["in_cone_pct"] for f in fingers]))
        res[level] = {k: msd(v) for k, v in vals.items()}
    return res


def summary(out: Path, levels, timing: Path) -> list[dict]:
    """Per level: mean +- std over seeds of each measured column, and of the cells' CPU s."""
    rows = [r for r in read_rows(out / "cells.csv") if r["status"] == "ok"]
    res = []
    for level in levels:
        mine = [r for r in rows if abs(r["level"] - level) < 1e-12]
        if not mine:
            continue
        s = {"level": level, "n": len(mine)}
        for k in ("clean_angle_deg", "noisy_angle_deg", "noisy_in_cone_pct", "val_angle_deg",
                  "label_angle_deg"):
            s[k] = msd(r[k] for r in mine)
        s["cpu_s"] = msd(c for r in mine if (c := cell_cpu_s(timing, r["run"])) is not None)
        res.append(s)
    return res


def finding(label: str, rows: list[dict]) -> str:
    """One sentence: from which level accuracy falls (the angle to the clean label above level
    0's by more than both seeds' spreads), and how much of the label noise the repeats and the
    training average away at the highest level."""
    if len(rows) < 2 or rows[0]["level"] != 0:
        return f"{label}: no finding yet (level 0 and another level needed)."
    a = rows[0]["clean_angle_deg"]
    falls = next((r for r in rows[1:] if r["clean_angle_deg"]["mean"] - a["mean"]
                  > a["std"] + r["clean_angle_deg"]["std"]), None)
    top = rows[-1]
    rise = top["clean_angle_deg"]["mean"] - a["mean"]
    noise = top["label_angle_deg"]["mean"]
    away = 100 * (1 - rise / noise) if noise > 0 else float("nan")
    where = (f"accuracy falls from noise level {falls['level']:g} on (angle to the clean label "
             f"{pm(falls['clean_angle_deg']['mean'], falls['clean_angle_deg']['std'], 2)} deg "
             f"against {pm(a['mean'], a['std'], 2)} deg at 0)" if falls else
             f"accuracy does not fall beyond the spread over seeds up to level {top['level']:g}")
    return (f"**{label}**: {where}; at level {top['level']:g} the labels lie {noise:.2f} deg "
            f"from the clean ones, the model's angle to the clean label rises by {rise:+.2f} deg: "
            f"the repeats and the training average away {away:.0f} % of the label noise.")


def table(rows: list[dict], floor: dict) -> str:
    head = ("| noise level | seeds | label noise (deg) | angle to clean label (deg) | angle to "
            "noisy cone mean (deg) | noise floor: angle (deg) | % in noisy cone | noise floor: "
            "% in cone | train CPU s |\n|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in rows:
        f = floor[r["level"]]
        lines.append("| " + " | ".join([
            f"{r['level']:g}", str(r["n"]),
            pm(r["label_angle_deg"]["mean"], r["label_angle_deg"]["std"], 2),
            pm(r["clean_angle_deg"]["mean"], r["clean_angle_deg"]["std"], 2),
            pm(r["noisy_angle_deg"]["mean"], r["noisy_angle_deg"]["std"], 2),
            pm(f["angle"]["mean"], f["angle"]["std"], 2),
            pm(r["noisy_in_cone_pct"]["mean"], r["noisy_in_cone_pct"]["std"]),
            pm(f["in_cone"]["mean"], f["in_cone"]["std"]),
            pm(r["cpu_s"]["mean"], r["cpu_s"]["std"], 0)]) + " |")
    return "\n".join(lines)


def plot(models: dict, path: Path) -> None:
    """Three panels against the noise level: angle to the clean label (the labels' own noise
    dotted), angle to the noisy cone mean and % in the noisy cone (noise floor dashed)."""
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
    keys = (("clean_angle_deg", "angle to the clean label (deg)"),
            ("noisy_angle_deg", "angle to the noisy cone mean (deg)"),
            ("noisy_in_cone_pct", "% in the noisy cone"))
    floor_key = {"noisy_angle_deg": "angle", "noisy_in_cone_pct": "in_cone"}
    for i, (m, entry) in enumerate(models.items()):
        colour, rows = COLOURS[m], entry["summary"]
        x = np.array([r["level"] for r in rows])
        for ax, (k, name) in zip(axes, keys, strict=True):
            ax.errorbar(x, [r[k]["mean"] for r in rows], yerr=[r[k]["std"] for r in rows],
                        fmt="o-", capsize=4, color=colour, label=LABELS[m])
            if k in floor_key:
                f = [entry["floor"][r["level"]][floor_key[k]]["mean"] for r in rows]
                ax.plot(x, f, "--", color=colour, alpha=0.6,
                        label=f"noise floor ({', '.join(entry['fingers'])})")
            elif i == 0:  # the same labels for every model: drawn once
                ax.plot(x, [r["label_angle_deg"]["mean"] for r in rows], ":", color="grey",
                        label="the labels' own noise (median angle to the clean label)")
            ax.set_xlabel("label noise (relative std of the force)")
            ax.set_ylabel(name)
            ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    axes[2].legend(fontsize=7)
    fig.suptitle("Label noise on the calibrated study twin; test split, mean ± std "
                 "over seeds", fontsize=9)
    save_figure(fig, path)


def main(argv: list[str] | None = None) -> int:
    p = study_parser(__doc__, "study_label_noise", "dataset")
    p.add_argument("--data", default=None, help="an existing twin dataset (default: made in "
                   "<work>/data)")
    p.add_argument("--n", type=int, default=3000, help="configurations generated")
    p.add_argument("--data-seed", type=int, default=29, help="the dataset's seed")
    p.add_argument("--levels", type=float, nargs="+", default=[0, 0.02, 0.05, 0.1, 0.2, 0.4])
    p.add_argument("--models", nargs="+", default=["default-lean", "v3", "default"],
                   choices=tuple(LABELS))
    p.add_argument("--v3-steps", type=int, default=REPLICA_STEPS,
                   help="V3: at least this many optimiser steps (sets the epochs)")
    p.add_argument("--v3-epochs", type=int, default=None,
                   help="V3: these epochs instead (a cut of --v3-steps: say so)")
    p.add_argument("--default-epochs", type=int, default=25, help="default recipe's epochs")
    args = p.parse_args(argv)
    work = Path(args.work)
    data = Path(args.data) if args.data else twin_data(work / "data", args.n, args.data_seed,
                                                       args.n_objects, Path(args.scene))
    tables = open_tables(data)
    counts = {s: len(tables.rows(s)) for s in ("train", "val", "test")}
    levels = sorted(args.levels)
    models = {}
    for m in args.models:
        base = base_cfg(m, args, counts["train"])
        out = work / m if args.no_train else run_model(m, data, args, base)
        fingers = ("index",) if base.finger == "index" else ("index", "thumb")
        rows = summary(out, levels, work / f"{m}_cpu_s.json")
        floor = floors(out, fingers, levels, args.seeds)
        steps = base.epochs * math.ceil(counts["train"] * base.rotation_cfg().count
                                        / base.batch_size)
        models[m] = {"label": LABELS[m], "fingers": list(fingers), "epochs": base.epochs,
                     "optimiser_steps": steps, "summary": rows, "floor": floor,
                     "finding": finding(LABELS[m], rows), "table": table(rows, floor),
                     "experiment": str(out)}
    flags = (f"--levels {' '.join(f'{v:g}' for v in levels)} --seeds {args.seeds}")
    commands = [f"vistac generate --scene {Path(args.scene).name} --n {args.n} --n-objects "
                f"{args.n_objects} --split-by object --seed {args.data_seed} --out D"
                if not args.data else f"D = {data}"]
    for m, e in models.items():
        extra = ("--protocol study --rotations random --n-rotations 1 " if m == "v3" else
                 "--no-mirror --no-tta --aux-weight 0 " if m == "default-lean" else "")
        commands.append(f"vistac experiment label-noise --data D {flags} {extra}--epochs "
                        f"{e['epochs']} --out {m}")
    md = [f"# Label noise at scale: the project's recipe and the study's CNN\n\n{TWIN_NOTE}\n",
          "```bash\n" + "\n".join(commands) + "\n```\n",
          f"{args.n} configurations split by object ({counts['train']} / {counts['val']} / "
          f"{counts['test']}); angles: median angle to the cone mean, deg, mean of the model's "
          "fingers; the noisy cones and the noise floor are those of each level's redrawn "
          "labels; mean ± std over seeds; the epoch chosen on the validation split; train "
          "CPU s: training and scoring of one cell, 2 shared cores.\n"]
    for e in models.values():
        md += [f"## {e['label']}\n", f"{e['epochs']} epochs ({e['optimiser_steps']} optimiser "
               f"steps), fingers: {', '.join(e['fingers'])}.\n", e["table"], "",
               e["finding"], ""]
    md.append(f"![label noise]({args.name}.png)")
    result = {"note": TWIN_NOTE, "dataset": str(data), "split_counts": counts,
              "commands": commands, "replica_steps": REPLICA_STEPS,
              "settings": vars(args), "models": models}
    save(Path(args.results), args.name, json.loads(json.dumps(result, default=str)),
         "\n".join(md), datasets=(data,))
    plot(models, Path(args.results) / f"{args.name}.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
