"""Explain the gap between the twin and the study (issue 35, part 1): the study replay's V3 row
(SchoeConv100-V3(FC160), 162 training configurations, `--protocol study`) on twins with each
imperfection of the scene switched off in turn, and with the `photo` appearance on top.

Each variant is the twin's scene file (``sim_assets/scenes/study.yaml``: the ``lab`` preset,
5 % force noise) with one change, written into ``<work>/scenes/`` (never into sim_assets):

- ``no placement_error``, ``no finger_pull``, ``no fts3``, ``no overlay_error``: that effect
  ``false`` (`vistac_sim.effects.presets`: an optional effect is switched off by ``false``);
- ``noise 0``: ``effects.noise: 0``;
- ``+ photo appearance``: the ``photo`` preset's appearance effects over the twin's (textured
  objects and table, lighting, a phone camera, fingers drawn by hand; labels untouched).

Every variant's dataset is generated from the same seed, size, objects and split as the replay
(``--n 1300 --n-objects 64 --split 0.42 0.06 0.52 --seed 0``), so they differ only by the
effect. Each is trained as the replay trains (``--n-train`` 162 configurations, 20 fixed
rotations, 20 epochs, the epoch chosen on validation, the test split scored once) for every seed
of ``--seeds``. The full twin's row comes from ``benchmarks/results/study_replay.json`` when its
settings are the same (``--full-from``), else it is trained here too.

The table: % correct y, % in cone and the median angle to the cone mean of each variant (mean
± std over seeds), what the imperfection costs (the variant without it minus the full twin, so a
positive cost means the effect lowers the figure), the variant's own noise floor and the
training CPU seconds.

``--untrained``: no training; each variant's row is the constant predictor (the mean training
label for every test configuration), what V3 scores on the full twin at 162 configurations
(docs/results.md), so the table says in minutes what each effect costs a net that learns the
set-up's mean direction and nothing else (default name ``study_gap_untrained``).

Resumable: a rerun reuses datasets and finished runs and rewrites ``<name>.json|md|png``.

Usage:
    .venv/bin/python benchmarks/study_gap.py
    .venv/bin/python benchmarks/study_gap.py --variants no_fts3 noise_0 --seeds 0 1
    # two processes on one --work, then a gathering rerun of every variant:
    .venv/bin/python benchmarks/study_gap.py --variants no_finger_pull noise_0 --name part_a &
    .venv/bin/python benchmarks/study_gap.py --variants photo no_fts3 --skip-full --name part_b
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from learnbench import reference_entries, run_entry  # noqa: E402
from study_replay import (  # noqa: E402
    RESULTS,
    constant_predictor,
    dataset,
    fmt,
    summarise,
    train_fraction,
)
from studybench import V3, record, scene_file, twin_parser  # noqa: E402

from vistac.dataset import open_tables  # noqa: E402
from vistac.provenance import provenance  # noqa: E402
from vistac_learn.evaluate.references import LABELS  # noqa: E402
from vistac_learn.models import model_info  # noqa: E402
from vistac_sim.effects.presets import PRESETS  # noqa: E402

KEYS = (("% correct y", "correct_y_pct"), ("% in cone", "in_cone_pct"),
        ("median ° to mean", "angle_to_mean_median_deg"))
# variant name -> (label, the effects it changes over the twin's scene file)
VARIANTS = {
    "full": ("full twin (study.yaml)", {}),
    "no_placement_error": ("no placement error", {"placement_error": False}),
    "no_finger_pull": ("no finger pull", {"finger_pull": False}),
    "no_fts3": ("no FTS-3 model", {"fts3": False}),
    "no_overlay_error": ("no overlay error", {"overlay_error": False}),
    "noise_0": ("force noise 0", {"noise": 0.0}),
    "photo": ("+ photo appearance", PRESETS["photo"]["effects"]),
}
ADDED = ("photo",)  # variants that add an effect to the twin (the others take one away)
REPLAY_KEYS = ("scene", "n", "n_objects", "split", "data_seed", "n_train", "epochs",
               "n_rotations")


def replay_row(args: argparse.Namespace) -> dict | None:
    """The full twin's V3 row of the replay's results, when they were made with the same
    dataset and protocol settings (else None)."""
    path = Path(args.full_from)
    if not path.exists():
        return None
    res = json.loads(path.read_text())

    def same(settings: dict) -> dict:  # a scene file compared by its text (another checkout)
        scene = Path(settings.get("scene", ""))
        return {k: (scene.read_text() if scene.is_file() else None) if k == "scene"
                else settings.get(k) for k in REPLAY_KEYS}

    if same(vars(args)) != same(res.get("settings", {})):
        print(f"{path}: other settings than this run's; the full twin is trained here",
              flush=True)
        return None
    rows = [r for r in res["rows"] if r.get("name") == args.model and r["kind"] == "model"]
    if not rows or rows[0]["summary"]["n_seeds"] < len(args.seeds):
        return None
    floor = [r for r in res["rows"] if r["label"] == LABELS["noise_floor"]]
    return {**rows[0], "noise_floor": {k: v["mean"] for k, v in floor[0]["summary"].items()
                                       if isinstance(v, dict)} if floor else None}


def cost_table(rows: list[dict], note: str) -> str:
    """Markdown: each variant's figures (mean ± std), the cost of the effect against the full
    twin, the variant's noise floor and the training CPU seconds."""
    head = ["twin", "seeds", *(h for h, _ in KEYS), "cost in % correct y", "cost in % in cone",
            "noise floor % in cone", "train CPU s"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    full = next((r for r in rows if r["variant"] == "full"), None)
    for r in rows:
        s = r["summary"]
        untrained = s["seeds"] == [None]
        cells = [r["label"], "-" if untrained else str(s["n_seeds"]),
                 *(fmt(k, s[k]["mean"]) + ("" if untrained else f" ± {fmt(k, s[k]['std'])}")
                   for _, k in KEYS)]
        sign = -1 if r["variant"] in ADDED else 1  # an added effect: the twin is "without"
        for k in ("correct_y_pct", "in_cone_pct"):
            cells.append("-" if full is None or r is full else
                         f"{sign * (s[k]['mean'] - full['summary'][k]['mean']):+.1f}")
        floor = r.get("noise_floor")
        cells += ["-" if floor is None else fmt("in_cone_pct", floor["in_cone_pct"]),
                  "-" if not s.get("train_cpu_s") else f"{s['train_cpu_s']:.0f}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n\n" + note


def plot(rows: list[dict], path: Path) -> None:
    """% correct y and % in cone per variant (mean ± std over seeds), the full twin's as lines."""
    fig, ax = plt.subplots(figsize=(9, 4.5))
    for j, (name, key) in enumerate(KEYS[:2]):
        colour = ("tab:blue", "tab:orange")[j]
        for i, r in enumerate(rows):
            s = r["summary"][key]
            ax.errorbar(i + (j - 0.5) * 0.3, s["mean"], yerr=s["std"], fmt="o", capsize=4,
                        color=colour, label=name if i == 0 else None)
            if r["variant"] == "full":
                ax.axhline(s["mean"], color=colour, lw=1, ls=":")
    ax.set_xticks(range(len(rows)), [r["label"] for r in rows], rotation=20, ha="right",
                  fontsize=8)
    ax.set_ylim(0, 100)
    ax.set_ylabel("% (index finger, test)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, title="dots: each variant; dotted: full twin",
              title_fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def gap(args: argparse.Namespace) -> dict:
    """Generate, train and score every variant (resuming), rewriting the results each run."""
    if len(args.seeds) < 2:
        print("note: fewer than 2 seeds (a quick look, not the table)", flush=True)
    work = Path(args.work)
    variants = list(dict.fromkeys(["full", *args.variants]))
    full_row = None if args.untrained else replay_row(args)
    if full_row is not None or args.skip_full:
        variants.remove("full")
    done: dict[str, list[dict]] = {}
    datasets: dict[str, Path] = {}
    floors: dict[str, dict] = {}
    result: dict = {}

    def write() -> None:
        rows = []
        if full_row is not None:
            rows.append({"variant": "full", "label": VARIANTS["full"][0] + ", from "
                         f"{Path(args.full_from).name}", "summary": full_row["summary"],
                         "noise_floor": full_row["noise_floor"]})
        rows += [{"variant": v, "label": VARIANTS[v][0], "summary": summarise(done[v]),
                  "noise_floor": floors.get(v), "runs": done[v],
                  "scene_changes": VARIANTS[v][1]} for v in variants if done.get(v)]
        what = ("The constant predictor (no training: the mean training label for every "
                "test configuration)" if args.untrained else
                f"{model_info(args.model, 1, 2).get('display', args.model)}, `--protocol "
                f"study` on {args.n_train} "
                f"training configurations x {args.n_rotations} rotations, {args.epochs} epochs, "
                "the epoch chosen on validation,")
        note = (f"Index finger. {what} scored once on each variant's test split "
                f"(held-out objects). Each variant: `{Path(args.scene).name}` with one effect "
                f"changed, its own dataset of {args.n} configurations from seed "
                f"{args.data_seed}. Cost: the variant's figure (without the effect) minus "
                "the full twin's, for an added effect the reverse (positive: the effect "
                "lowers it). Mean ± std over seeds; training CPU seconds: user + system "
                f"(OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')} when written).")
        result.update({"provenance": provenance(list(datasets.values())),
                       "datasets": {k: str(v) for k, v in datasets.items()},
                       "settings": {k: (str(v) if isinstance(v, Path) else v)
                                    for k, v in vars(args).items()},
                       "rows": rows, "table": cost_table(rows, note)})
        out = Path(args.results)
        out.mkdir(parents=True, exist_ok=True)
        (out / f"{args.name}.json").write_text(json.dumps(result, indent=2) + "\n")
        who = "a net that learnt nothing" if args.untrained else \
            model_info(args.model, 1, 2).get("display", args.model)
        (out / f"{args.name}.md").write_text("# What each imperfection of the twin costs "
                                             f"{who}\n\n{result['table']}\n")
        plot(rows, out / f"{args.name}.png")

    for v in variants:
        scene = args.scene if v == "full" else str(scene_file(Path(args.scene), v,
                                                               VARIANTS[v][1], work))
        vargs = argparse.Namespace(**{**vars(args), "work": str(work / v), "scene": scene})
        datasets[v] = dataset(vargs)
        refs = reference_entries(datasets[v], ("index",))
        floors[v] = refs[0]["metrics"]["index"] if refs else None
        if args.untrained:
            const = constant_predictor(open_tables(datasets[v]))
            done[v] = [{"seed": None, "metrics": {"index": const}}]
    if args.untrained:
        write()
        print(result["table"], flush=True)
        return result
    for seed in args.seeds:
        for v in variants:
            tables = open_tables(datasets[v])
            extra = {"max_missing_pct": args.photo_max_missing_pct} if v == "photo" else {}
            t0 = time.perf_counter()
            e = run_entry(datasets[v], work / v, f"{v} {args.model} seed {seed}", protocol="study",
                          seed=seed, progress=not args.quiet, model=args.model,
                          train_fraction=train_fraction(tables, args.n_train),
                          epochs=args.epochs, n_rotations=args.n_rotations,
                          cache_dir=str(work / v / "cache"), **extra)
            record(done, v, e, seed, t0, write)
    print(result.get("table", ""), flush=True)
    return result


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    p = twin_parser(__doc__, "study_gap", (1300, 64, (0.42, 0.06, 0.52)))
    p.add_argument("--variants", nargs="+", default=[v for v in VARIANTS if v != "full"],
                   choices=list(VARIANTS), help="variants besides the full twin")
    p.add_argument("--full-from", default=str(RESULTS / "study_replay.json"),
                   help="the replay's results, read for the full twin's row when they match")
    p.add_argument("--n-train", type=int, default=162, help="training configurations used")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="training seeds")
    p.add_argument("--epochs", type=int, default=20, help="study protocol epochs")
    p.add_argument("--n-rotations", type=int, default=20, help="study protocol rotations")
    p.add_argument("--photo-max-missing-pct", type=float, default=10.0,
                   help="--max-missing-pct of the photo variant (the locator on photo renders)")
    p.add_argument("--model", default=V3, help="the study's net trained per variant (SmallConv, "
                   "5 minutes a run, scores as V3 does on the twin: docs/results.md)")
    p.add_argument("--untrained", action="store_true",
                   help="no training: the constant predictor per variant (minutes)")
    p.add_argument("--skip-full", action="store_true",
                   help="leave the full twin out (a second process sharing --work trains the "
                   "other variants; a gathering rerun without it adds the full twin's row)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    args = p.parse_args(argv)
    if args.untrained and args.name == "study_gap":
        args.name = "study_gap_untrained"
    gap(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
