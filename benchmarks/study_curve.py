"""The study's CNN given more data: SchoeConv100-V3(FC160)'s learning curve on the simulated
twin (issue 35, part 2), beside the project's default recipe, the twin's noise floor, a net
that learnt nothing (the constant predictor: the mean training label) and the headroom (the
noise-free force turned by the mean lean of the training labels: geometry known, no net).

One dataset of the twin (``sim_assets/scenes/study.yaml``, ``--n`` configurations split by
object) serves every size: each run trains on a nested seeded subset of its training split
(``--train-fraction``; for one seed, a smaller size is a subset of a larger one), selects its
epoch on the validation split and is scored once on the whole test split (held-out objects,
>= 500 configurations), which all sizes share.

Recipe per size (`--protocol study`: edge-index images, Adam, MSE, lr 1e-4, batches of 5):

- at the study's size (``--study-size``, 162) and below: exactly the study's, 20 fixed
  rotations of 18 degrees, 20 epochs: 162 x 20 x 20 / 5 = 12 960 optimiser steps;
- above it: one random rotation per sample and epoch (``--rotations random --n-rotations 1``,
  validation on one random rotation per configuration too) and at least ``--min-steps``
  optimiser steps (default the replica's 12 960): ``epochs = ceil(min_steps x batch / n)``.

Every run is scored on the test split at the study's 20 fixed rotations, whatever it trained
with, so that the sizes stay comparable. The default recipe (its own settings, both fingers,
the index shown) trains on the same subsets with the learning curve's epochs
(`learning_curve.epochs_for`: >= 31 000 samples, 3 to 30 epochs), as it is and (``default-lean``)
without what hides the twin's lean: mirrored training samples and test views (a mirror flips
r_y, so the finger pull's sideways lean averages out) and the auxiliary contact targets (they
pull the composed geometry toward the unleaned truth): ``--no-mirror --no-tta --aux-weight 0``.
``--arms`` picks what is trained (e.g. one arm per process, sharing ``--work``).

Cost: ``--estimate`` trains one epoch at the largest size (random rotations; its own run folder)
and prints the CPU hours of the whole curve; over ``--budget-hours`` the plan says what it
cuts: optimiser steps of the sizes above the study's first (never below one epoch), never
seeds below 2. ``--plan`` prints the plan and the estimate from a measured epoch without
training. ``--cut`` applies the cut.

Resumable: a rerun reuses the dataset and finished runs, continues unfinished ones and rewrites
``<name>.json``, ``.md`` and ``.png`` after every run.

Usage:
    .venv/bin/python benchmarks/study_curve.py --estimate        # one epoch at 5000, the plan
    .venv/bin/python benchmarks/study_curve.py                   # the whole curve
    .venv/bin/python benchmarks/study_curve.py --big             # + 20 000 (its own dataset)
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import os
import sys
import time
from pathlib import Path
from unittest import mock

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from learnbench import (  # noqa: E402
    LEAN_LABEL,
    LEAN_RECIPE,
    cpu_s,
    finished_run,
    reference_entries,
    run_entry,
)
from learning_curve import epochs_for  # noqa: E402
from study_replay import (  # noqa: E402
    STUDY_KEYS,
    STUDY_ROWS,
    constant_predictor,
    dataset,
    lean_oracle,
    summarise,
    table,
    train_fraction,
)
from studybench import V3, record, twin_parser  # noqa: E402

import vistac_learn.evaluate.run as evaluate_module  # noqa: E402
from vistac.dataset import open_tables  # noqa: E402
from vistac.provenance import provenance  # noqa: E402
from vistac_learn.data.fingertip_table import fingertip_table  # noqa: E402

STUDY_BATCH = 5
REPLICA_STEPS = 162 * 20 * 20 // STUDY_BATCH  # 12 960
VAL_COST = 0.35  # CPU of one validation sample against one training sample (no backward pass)
DEFAULT_RUN_CPU_S = 600.0  # the default recipe per run (learning_curve.json: 200-570 CPU s)
ANGLE = "angle_to_mean_median_deg"
# the project's default recipe as it is, and with what keeps the twin's lean: no mirrored
# training samples or test views (mirroring flips r_y, so a sideways pull's lean averages out)
# and no auxiliary contact targets (they pull the geometry toward the unleaned truth)
LEAN = "default-lean"
ARMS = {V3: ("SchoeConv100-V3(FC160), study protocol", "tab:blue", {}),
        "default": ("default recipe", "tab:green", {}),
        LEAN: (LEAN_LABEL, "tab:purple", LEAN_RECIPE)}
NOMINAL_CPU_PER_SAMPLE = 2 / 40  # V3 at ~40 samples/s on 2 idle cores


@contextlib.contextmanager
def scored_at(n_rotations: int):
    """`evaluate_run` scores at `n_rotations` fixed rotations of 18 degrees, whatever the run
    trained with (the run's settings are otherwise kept)."""
    real = evaluate_module.load_run

    def load(run):
        cfg, meta = real(run)
        if cfg.rotations == "none":
            return cfg, meta
        return dataclasses.replace(cfg, rotations="fixed", n_rotations=n_rotations,
                                   rotation_step=18.0), meta

    with mock.patch.object(evaluate_module, "load_run", load):
        yield


def v3_recipe(size: int, args: argparse.Namespace, min_steps: int) -> dict:
    """The study protocol's changes at one size (see the module's docstring)."""
    if size <= args.study_size:
        return {"epochs": args.study_epochs, "n_rotations": 20, "rotations": "fixed"}
    epochs = max(1, math.ceil(min_steps * STUDY_BATCH / size))
    return {"epochs": epochs, "n_rotations": 1, "rotations": "random"}


def plan(args: argparse.Namespace, counts: dict, min_steps: int) -> list[dict]:
    """Every run of the curve: arm, size, seed, changes, optimiser steps, samples."""
    runs = []
    for size in args.sizes:
        r = v3_recipe(size, args, min_steps)
        samples = size * r["n_rotations"] * r["epochs"]
        runs += [{"arm": V3, "size": size, "seed": s, "changes": r,
                  "steps": math.ceil(size * r["n_rotations"] / STUDY_BATCH) * r["epochs"],
                  "samples": samples,
                  "val_samples": counts["val"] * r["n_rotations"] * r["epochs"]}
                 for s in args.seeds]
        e = epochs_for(size, 31000, 3, 30)
        runs += [{"arm": arm, "size": size, "seed": s, "changes": {"epochs": e, **ARMS[arm][2]},
                  "steps": math.ceil(size / 32) * e, "samples": size * e, "val_samples": 0}
                 for arm in ("default", LEAN) if arm in args.arms for s in args.seeds]
    runs = [r for r in runs if r["arm"] in args.arms]
    # the first seed of every size first: a curve early, the other seeds after it
    return sorted(runs, key=lambda r: (args.seeds.index(r["seed"]), r["size"],
                                       list(ARMS).index(r["arm"])))


def estimate_h(runs: list[dict], cpu_per_sample: float) -> float:
    """CPU hours of `runs`: V3 samples (validation at `VAL_COST`) x the measured CPU seconds
    per training sample; the default recipe at `DEFAULT_RUN_CPU_S` a run."""
    s = sum((r["samples"] + VAL_COST * r["val_samples"]) * cpu_per_sample if r["arm"] == V3
            else DEFAULT_RUN_CPU_S for r in runs)
    return s / 3600


def budget(args, counts, cpu_per_sample) -> tuple[int, list[str]]:
    """The optimiser steps of the sizes above the study's that keep the estimate within
    `--budget-hours` (the replica's 12 960 when it fits), and the plan's lines (the first:
    the estimate)."""
    lines, steps = [], args.min_steps
    full = estimate_h(plan(args, counts, steps), cpu_per_sample)
    lines.append(f"measured: {cpu_per_sample:.4f} CPU s per V3 training sample "
                 f"({1 / cpu_per_sample * 2:.0f} samples/s on 2 cores); the whole curve "
                 f"({len(args.sizes)} sizes x {len(args.seeds)} seeds, min steps {steps}) "
                 f"= {full:.1f} CPU hours")
    if full > args.budget_hours:
        while steps > 1000 and estimate_h(plan(args, counts, steps), cpu_per_sample) > \
                args.budget_hours:
            steps = int(steps * 0.9)
        lines.append(f"over the {args.budget_hours:g} h budget: cut the optimiser steps of the "
                     f"sizes above {args.study_size} from {args.min_steps} to {steps} (fewer "
                     f"epochs; one random rotation already), seeds stay {len(args.seeds)} "
                     f"(never below 2): {estimate_h(plan(args, counts, steps), cpu_per_sample):.1f}"
                     f" CPU hours. Rerun with --cut to apply it (or --min-steps {steps}).")
        if estimate_h(plan(args, counts, steps), cpu_per_sample) > args.budget_hours:
            lines.append("still over: the study-size runs alone (20 fixed rotations x "
                         f"{args.study_epochs} epochs) exceed it; drop a size (--sizes) or "
                         "train the study size with fewer --study-epochs, never seeds below 2")
    for r in plan(args, counts, steps):
        if r["seed"] == args.seeds[0]:
            lines.append(f"  {r['arm']:>22} n={r['size']:>5}: {r['changes']}, "
                         f"{r['steps']} steps")
    return steps, lines


def measure_epoch(data: Path, work: Path, args, tables) -> float:
    """CPU seconds per training sample of one V3 epoch at the largest size (random
    rotation), its validation pass included."""
    size = max(args.sizes)
    frac = train_fraction(tables, size)
    c0 = cpu_s()
    fingertip_table(tables, cache_dir=str(work / "cache"))  # once per dataset, not per epoch
    print(f"fingertips of {len(tables.configs)} configurations located: "
          f"{cpu_s() - c0:.0f} CPU s (once, cached)", flush=True)
    e = run_entry(data, work, f"measure one epoch n{size}", protocol="study", seed=0,
                  progress=not args.quiet, model=V3, train_fraction=frac, epochs=1,
                  rotations="random", n_rotations=1, cache_dir=str(work / "cache"))
    per = e["train_cpu_s"] / (size + VAL_COST * len(tables.rows("val")))
    print(f"one V3 epoch at {size} configurations: {e['train_cpu_s']:.0f} CPU s, "
          f"{e['train_wall_s']:.0f} s wall", flush=True)
    return per


def plot(rows: list[dict], refs: list[dict], path: Path) -> None:
    """% in cone and median angle to the cone mean against training configurations (log),
    and the angle against training CPU seconds; noise floor and the study's V3 as marks."""
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.2))
    for arm, (label, colour, _) in ARMS.items():
        mine = sorted((r for r in rows if r["arm"] == arm), key=lambda r: r["size"])
        if not mine:
            continue
        x = [r["size"] for r in mine]
        for ax, key in zip(axes[:2], ("in_cone_pct", ANGLE), strict=True):
            ax.errorbar(x, [r["summary"][key]["mean"] for r in mine],
                        yerr=[r["summary"][key]["std"] for r in mine], fmt="o-", capsize=4,
                        color=colour, label=label)
        axes[2].errorbar([r["summary"]["train_cpu_s"] or np.nan for r in mine],
                         [r["summary"][ANGLE]["mean"] for r in mine],
                         yerr=[r["summary"][ANGLE]["std"] for r in mine], fmt="o-",
                         capsize=4, color=colour, label=label)
        for r in mine:
            axes[2].annotate(str(r["size"]), (r["summary"]["train_cpu_s"] or np.nan,
                                              r["summary"][ANGLE]["mean"]), fontsize=7,
                             textcoords="offset points", xytext=(4, 4))
    study = dict(zip(STUDY_KEYS, STUDY_ROWS[V3], strict=True))
    axes[0].plot(162, study["in_cone_pct"], "*", ms=14, color="tab:blue", mec="k",
                 label="the study (real, 34 test configurations)")
    styles = (("--", "grey"), (":", "grey"), ("-.", "grey"), ("--", "tab:red"))
    for ref, (style, colour) in zip(refs, styles, strict=False):
        for ax, key in ((axes[0], "in_cone_pct"), (axes[1], ANGLE), (axes[2], ANGLE)):
            ax.axhline(ref["metrics"]["index"][key], ls=style, lw=1, color=colour,
                       label=ref["label"] if ax is axes[0] else None)
    sizes = sorted({r["size"] for r in rows if r.get("size")})
    for ax in axes[:2]:
        ax.set_xscale("log")
        ax.set_xticks(sizes, [str(n) for n in sizes])
        ax.minorticks_off()
        ax.set_xlabel("training configurations")
    axes[0].set_ylabel("% in cone (index, test)")
    axes[1].set_ylabel("median angle to the cone mean (deg, index)")
    axes[2].set_xscale("log")
    axes[2].set_xlabel("training CPU seconds (user + system)")
    axes[2].set_ylabel("median angle to the cone mean (deg, index)")
    fig.legend(*axes[0].get_legend_handles_labels(), fontsize=7, loc="lower center", ncol=4)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout(rect=(0, 0.14, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def curve(args: argparse.Namespace) -> dict:
    """Train and score everything (resuming), rewriting the results after each run."""
    work = Path(args.work) / f"n{args.n}"
    args.work = str(work)
    data = dataset(args)
    tables = open_tables(data)
    counts = {s: len(tables.rows(s)) for s in ("train", "val", "test")}
    print(f"dataset {data}: {counts}", flush=True)
    if counts["test"] < 500:
        print(f"warning: {counts['test']} test configurations (< 500)", flush=True)
    steps, lines = args.min_steps, []
    measured = Path(args.work) / "cpu_per_sample.json"
    if args.estimate and not measured.exists():
        measured.write_text(json.dumps({"cpu_per_sample": measure_epoch(data, work, args,
                                                                       tables)}))
    per = json.loads(measured.read_text())["cpu_per_sample"] if measured.exists() else None
    steps, lines = budget(args, counts, per or NOMINAL_CPU_PER_SAMPLE)
    if per is None:
        lines[0] = lines[0].replace("measured:", "nominal (not measured; --estimate measures):")
    print("\n".join(lines), flush=True)
    if not (args.cut and per):
        steps = args.min_steps
    if args.plan or args.estimate:
        return {}
    steps_note = (f"the replica's {REPLICA_STEPS}" if steps == REPLICA_STEPS else
                  f"cut from {args.min_steps} for the budget" if steps != args.min_steps else
                  f"--min-steps; the replica's is {REPLICA_STEPS}")
    refs = [*reference_entries(data, ("index",)),
            {"label": "constant (mean training label)",
             "metrics": {"index": constant_predictor(tables)}},
            {"label": "geometry known: clean force + mean lean (no net)",
             "metrics": {"index": lean_oracle(tables)}}]
    runs = plan(args, counts, steps)
    done: dict[tuple[str, int], list[dict]] = {}
    result: dict = {}

    def write() -> None:
        rows = []
        for (arm, size), entries in sorted(done.items(), key=lambda kv: (kv[0][0], kv[0][1])):
            name = ARMS[arm][0]
            rows.append({"label": f"{name}, {size} configurations", "kind": "model",
                         "arm": arm, "size": size, "summary": summarise(entries),
                         "recipe": entries[0]["recipe"], "runs": entries})
        ref_rows = [{"label": r["label"], "kind": "reference",
                     "summary": {"n_seeds": 1, **{k: {"mean": r["metrics"]["index"][k],
                                                      "std": 0.0}
                                                  for k in (*STUDY_KEYS, ANGLE)}}}
                    for r in refs]
        note = (f"Index finger, SchoeConv100-V3(FC160) by `--protocol study` on the twin "
                f"`{Path(args.scene).name}` ({args.n} configurations of {args.n_objects} "
                f"objects split by object: {counts['train']} / {counts['val']} / "
                f"{counts['test']}), nested training subsets per seed. At {args.study_size} "
                f"configurations and below: 20 fixed rotations, {args.study_epochs} epochs "
                f"(the study's: 20). Above: one random rotation per sample and epoch, epochs so "
                f"that the optimiser steps >= {steps} ({steps_note}); each row's "
                "recipe is in the JSON. Every run's epoch chosen on the validation split, "
                "scored once on the whole test split at 20 fixed rotations. Default recipe: its "
                "own settings, `learning_curve.epochs_for` epochs; 'no mirror, no contact "
                "targets': the same with `--no-mirror --no-tta --aux-weight 0`. Mean ± std "
                "over seeds; "
                "training CPU seconds: user + system (OMP_NUM_THREADS="
                f"{os.environ.get('OMP_NUM_THREADS', 'unset')} when written).")
        if lines:
            note += "\n\nPlan and cost:\n\n" + "\n".join(f"    {x}" for x in lines)
        result.update({"provenance": provenance([data]), "dataset": str(data),
                       "split_counts": counts, "min_steps": steps,
                       "settings": {k: (str(v) if isinstance(v, Path) else v)
                                    for k, v in vars(args).items()},
                       "rows": rows, "references": ref_rows,
                       "table": table(rows + ref_rows, note)})
        out = Path(args.results)
        out.mkdir(parents=True, exist_ok=True)
        (out / f"{args.name}.json").write_text(json.dumps(result, indent=2) + "\n")
        (out / f"{args.name}.md").write_text("# The study's CNN given more data: V3's learning "
                                             f"curve on the twin\n\n{result['table']}\n")
        plot(rows, refs, out / f"{args.name}.png")

    for r in runs:
        frac = train_fraction(tables, r["size"])
        t0 = time.perf_counter()
        label = f"{r['arm']} n{r['size']} seed {r['seed']}"
        if args.gather and not finished_run(work, label, r["changes"]["epochs"]):
            print(f"== {label}: not finished, left out (--gather)", flush=True)
            continue
        common = {"train_fraction": frac, "cache_dir": str(work / "cache")}
        with scored_at(20):
            if r["arm"] == V3:
                e = run_entry(data, work, label, protocol="study", seed=r["seed"],
                              progress=not args.quiet, model=V3, **common, **r["changes"])
            else:
                e = run_entry(data, work, label, seed=r["seed"], progress=not args.quiet,
                              **common, **r["changes"])
        e["recipe"] = {**r["changes"], "steps": r["steps"]}
        record(done, (r["arm"], r["size"]), e, r["seed"], t0, write)
    print(result.get("table", ""), flush=True)
    return result


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    p = twin_parser(__doc__, "study_curve", (7200, 240, (0.8, 0.05, 0.15)))
    p.add_argument("--sizes", type=int, nargs="+", default=[162, 500, 1500, 5000],
                   help="training configurations")
    p.add_argument("--big", action="store_true",
                   help="add 20 000 training configurations (with --n 26000 unless --n is given: "
                        "a dataset of its own, every size retrained on it)")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="training seeds")
    p.add_argument("--study-size", type=int, default=162,
                   help="up to this size: the study's 20 fixed rotations and epochs")
    p.add_argument("--study-epochs", type=int, default=20, help="epochs up to --study-size")
    p.add_argument("--min-steps", type=int, default=REPLICA_STEPS,
                   help="optimiser steps (batches of 5) of each size above --study-size")
    p.add_argument("--arms", nargs="+", choices=list(ARMS), default=list(ARMS),
                   help=f"what is trained: the study's V3, the default recipe, and ({LEAN}) the "
                   "default recipe without mirroring or contact targets")
    p.add_argument("--estimate", action="store_true",
                   help="train one V3 epoch at the largest size, print the plan and its CPU hours")
    p.add_argument("--plan", action="store_true", help="print the plan (and a measured "
                   "estimate) without training")
    p.add_argument("--budget-hours", type=float, default=6.0, help="CPU hours the curve may take")
    p.add_argument("--cut", action="store_true",
                   help="apply the budget's cut of optimiser steps (needs a measured epoch)")
    p.add_argument("--gather", action="store_true",
                   help="train nothing: the results of the runs finished in --work (others "
                   "left out and named)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    args = p.parse_args(argv)
    if args.big:
        args.sizes = sorted({*args.sizes, 20000})
        if "--n" not in (argv if argv is not None else sys.argv):
            args.n = 26000
    args.sizes = sorted(args.sizes)
    if len(args.seeds) < 2:
        print("note: fewer than 2 seeds (a quick look, not the curve)", flush=True)
    curve(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
