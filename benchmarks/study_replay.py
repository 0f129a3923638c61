"""The study's table replayed in simulation: its CNNs trained as the study trained them, on a
simulated twin of its set-up, scored on a large test split of held-out objects.

The twin is the scene file ``sim_assets/scenes/study.yaml`` (the ``lab`` imperfections, 5 %
force noise). One dataset of ``--n`` configurations split by object: ``--n-train`` (162, the
study's size) of its training configurations are trained on (``--train-fraction``), its
validation split selects the epoch (the study selected on its test set; we never do), its test
split (> 500 configurations of objects no training image shows) is scored once per run.

For every model of ``--models`` and every seed of ``--seeds``: ``vistac train --protocol
study`` (edge-index images at 20 rotations of 18 degrees, Adam, MSE, lr 1e-4, batch 5, 20
epochs), then its test split scored. Beside them: the twin's noise floor and the pinch baseline
(both on the unrotated test images), the project's default recipe trained on the same 162
configurations, and the study's own figures. A 34-configuration test split (the study's) moves
the figures by sampling alone: each run's test configurations are resampled ``--resamples``
times in groups of 34 and the 5-95 % range of % correct y and % in cone is shown beside them.

Resumable: a rerun reuses the dataset and finished runs, continues unfinished ones, and
rewrites the results (``<name>.json``, ``.md``, ``.png``) after every run, so results land as
they finish.

Usage:
    .venv/bin/python benchmarks/study_replay.py                       # the whole replay
    .venv/bin/python benchmarks/study_replay.py --seeds 0 --epochs 2  # a quick look
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from learnbench import ensure_dataset, reference_entries, run_entry  # noqa: E402

from vistac.dataset import SplitCfg, open_tables  # noqa: E402
from vistac.provenance import provenance  # noqa: E402
from vistac_learn.evaluate.references import clean_yz_columns  # noqa: E402
from vistac_learn.metrics.scoring import STUDY_COLUMNS, score  # noqa: E402
from vistac_learn.models import model_info  # noqa: E402
from vistac_sim.generate.config import GenerateCfg  # noqa: E402
from vistac_sim.objects.config import ObjectsCfg  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
SCENE = REPO / "sim_assets" / "scenes" / "study.yaml"
RESULTS = REPO / "benchmarks" / "results"

# The study's own figures (its section 9: index finger, edge-index images, 34 test
# configurations x 20 rotations), in the keys of `cone_metrics`.
STUDY_KEYS = tuple(k for _, k in STUDY_COLUMNS)
STUDY_ROWS = {
    "schoeconv100-v3-fc160": (91.6, 41.7, 9.27, 60.5, 14.0, 60.1, 2.2e-3),
    "smallconv": (76.5, 26.4, 52.3, 107.0, 47.9, 96.4, 4e-3),
    "schoeconv100-v5": (92.4, 42.0, 7.96, 53.1, 12.5, 60.8, 1.9e-3),
    "alexnet": (86.3, 35.4, 25.6, 73.5, 34.0, 78.3, 2.4e-3),
    "schoeconv227-v1": (94.0, 41.7, 7.34, 43.2, 11.2, 58.4, 1.9e-3),
    "schoeconv227-v2": (94.1, 41.2, 7.26, 41.7, 9.8, 58.4, 2.0e-3),
}
RESAMPLED = ("correct_y_pct", "in_cone_pct")  # the columns shown with a 34-configuration spread


def dataset(args: argparse.Namespace) -> Path:
    """The twin's dataset, generated once into <work>/data with the scene file's grasp spreads;
    with ``--approach-spread``/``--closing-spread`` given, into <work>/data-a<A>c<C>."""
    cfg = GenerateCfg.from_file(args.scene, n=args.n, seed=args.data_seed,
                                objects=ObjectsCfg(n_objects=args.n_objects),
                                split=SplitCfg(by="object", fractions=tuple(args.split)))
    approach = getattr(args, "approach_spread", None)
    closing = getattr(args, "closing_spread", None)
    if approach is None and closing is None:
        return ensure_dataset(Path(args.work) / "data", cfg)
    grasp = dataclasses.replace(
        cfg.grasp, approach_spread_deg=cfg.grasp.approach_spread_deg if approach is None
        else approach, closing_spread_deg=cfg.grasp.closing_spread_deg if closing is None
        else closing)
    folder = f"data-a{grasp.approach_spread_deg:g}c{grasp.closing_spread_deg:g}"
    return ensure_dataset(Path(args.work) / folder, dataclasses.replace(cfg, grasp=grasp))


def add_grasp_options(p: argparse.ArgumentParser) -> None:
    """``--approach-spread`` and ``--closing-spread``, the grasp spreads `dataset` reads
    (default: the scene file's)."""
    p.add_argument("--approach-spread", type=float, default=None,
                   help="grasp: max degrees of a finger's axis off its target's normal "
                   "(None: the scene file's; benchmarks/study_spread.py measures what it "
                   "changes)")
    p.add_argument("--closing-spread", type=float, default=None,
                   help="grasp: max degrees of the closing axis off the index target's normal "
                   "(None: the scene file's)")


def constant_predictor(tables) -> dict:
    """Index-finger metrics on the test split of a net that learnt nothing: every test
    configuration predicted as the mean training label."""
    train, test = tables.rows("train"), tables.rows("test")
    mean = tables.mean_label("index")
    pred = np.tile(mean[train].mean(0), (len(test), 1))
    return score(pred, tables, test, test, ("index",))["index"]


def lean_oracle(tables) -> dict:
    """Index-finger metrics on the test split of a predictor that knows each configuration's
    geometry and has learnt the set-up's lean: the noise-free force's direction turned by the
    mean angle (circular) from it to the training labels. Not a net: the headroom a net that
    reads the geometry from the images could reach on the twin."""
    train, test = tables.rows("train"), tables.rows("test")
    yz = tables.configs[clean_yz_columns("index")].to_numpy(float)
    clean = np.arctan2(yz[:, 0], yz[:, 1])
    mean = tables.mean_label("index")
    lean = np.angle(np.mean(np.exp(1j * (np.arctan2(mean[train, 0], mean[train, 1])
                                         - clean[train]))))
    turned = clean[test] + lean
    pred = np.stack([np.sin(turned), np.cos(turned)], axis=1)
    return score(pred, tables, test, test, ("index",))["index"]


def train_fraction(tables, n_train: int) -> float:
    """The `--train-fraction` that keeps `n_train` of the training configurations (the
    trainer keeps ceil(fraction x n))."""
    n = len(tables.rows("train"))
    if n_train > n:
        raise SystemExit(f"--n-train {n_train}: the training split has only {n} "
                         "configurations; raise --n")
    return min(1.0, (n_train - 0.5) / n)


def resampled(tables, run: str, size: int, draws: int, seed: int) -> dict:
    """`RESAMPLED` metrics of `draws` test splits of `size` configurations drawn (without
    replacement) from the run's scored test predictions: 5 %, 50 %, 95 % quantiles and std."""
    pred = pd.read_parquet(Path(run) / "eval" / "test" / "predictions.parquet")
    row_of = {c: i for i, c in enumerate(tables.configs["config_id"].to_numpy())}
    item_row = np.array([row_of[c] for c in pred["config_id"]])
    p = pred[["pred_index_y", "pred_index_z"]].to_numpy()
    rows = np.unique(item_row)
    rng = np.random.default_rng(seed)
    vals = {k: [] for k in RESAMPLED}
    for _ in range(draws):
        pick = np.sort(rng.choice(rows, size=min(size, len(rows)), replace=False))
        keep = np.isin(item_row, pick)
        m = score(p[keep], tables, pick, item_row[keep], ("index",))["index"]
        for k in RESAMPLED:
            vals[k].append(m[k])
    return {k: {"q05": float(np.quantile(v, 0.05)), "q50": float(np.median(v)),
                "q95": float(np.quantile(v, 0.95)), "std": float(np.std(v))}
            for k, v in vals.items()}


def summarise(runs: list[dict]) -> dict:
    """Mean and std over seeds of the index finger's metrics, CPU seconds and spreads."""
    keys = [*STUDY_KEYS, "angle_to_mean_median_deg"]
    out = {"n_seeds": len(runs), "seeds": [r["seed"] for r in runs]}
    for k in keys:
        v = np.array([r["metrics"]["index"][k] for r in runs], float)
        out[k] = {"mean": float(v.mean()), "std": float(v.std(ddof=1)) if len(v) > 1 else 0.0}
    cpu = [r["train_cpu_s"] for r in runs if r.get("train_cpu_s")]
    out["train_cpu_s"] = float(np.mean(cpu)) if cpu else None
    if all("resampled_34" in r for r in runs):
        out["resampled_34"] = {k: {q: float(np.mean([r["resampled_34"][k][q] for r in runs]))
                                   for q in ("q05", "q50", "q95", "std")} for k in RESAMPLED}
    return out


def fmt(key: str, v: float) -> str:
    if v is None or not np.isfinite(v):
        return "-"
    if key == "mse_mean":
        return f"{v:.2e}"
    return f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}"


def _cell(key: str, v, seeds: int) -> str:
    """A value, or a {mean, std} over seeds (the std shown for more than one seed)."""
    if v is None:
        return "-"
    if isinstance(v, dict):
        return fmt(key, v["mean"]) + (f" ± {fmt(key, v['std'])}" if seeds > 1 else "")
    return fmt(key, v)


def table(rows: list[dict], note: str) -> str:
    """Markdown: the study's columns (mean +- std over seeds), the 34-configuration spread of
    the first two, the angle to the cone mean and the training CPU seconds."""
    head = ["model / setting", "seeds", *(h for h, _ in STUDY_COLUMNS),
            "% correct y, % in cone at 34 test configs (5-95 %)", "median angle to mean (deg)",
            "train CPU s"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for r in rows:
        s = r["summary"]
        seeds = s.get("n_seeds", 1)
        spread = s.get("resampled_34")
        cpu = s.get("train_cpu_s")
        cells = [r["label"], str(seeds) if r["kind"] == "model" else "-",
                 *(_cell(k, s.get(k), seeds) for k in STUDY_KEYS),
                 "-" if spread is None else ", ".join(
                     f"{spread[k]['q05']:.0f}-{spread[k]['q95']:.0f}" for k in RESAMPLED),
                 _cell("angle_to_mean_median_deg", s.get("angle_to_mean_median_deg"), seeds),
                 "-" if not cpu else f"{cpu:.0f}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n\n" + note


def plot(rows: list[dict], path: Path) -> None:
    """Left: % correct y and % in cone per row (mean +- std over seeds, the 34-configuration
    5-95 % range as a thin bar, the study's figure as a star). Right: median angle to the cone
    mean against training CPU seconds."""
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.5))
    models = [r for r in rows if r["kind"] in ("model", "study")]
    for j, key in enumerate(RESAMPLED):
        for i, r in enumerate(models):
            s = r["summary"]
            x = i + (j - 0.5) * 0.35
            colour = ("tab:blue", "tab:orange")[j]
            if r["kind"] == "study":
                ax.plot(x, s[key], "*", ms=14, color=colour, mec="k")
                continue
            ax.errorbar(x, s[key]["mean"], yerr=s[key]["std"], fmt="o", color=colour,
                        capsize=4, label=("% correct y", "% in cone")[j] if i == 0 else None)
            if "resampled_34" in s:
                q = s["resampled_34"][key]
                ax.vlines(x + 0.08, q["q05"], q["q95"], color=colour, alpha=0.4, lw=3)
    ax.set_xticks(range(len(models)), [r["label"] for r in models], rotation=20, ha="right",
                  fontsize=8)
    ax.set_ylabel("% (index finger)")
    ax.set_ylim(0, 100)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8, title="dot: seeds' mean ± std; bar: 34-config "
              "5-95 %; star: study", title_fontsize=7)
    for r in rows:
        s = r["summary"]
        if r["kind"] != "model" or not s.get("train_cpu_s"):
            continue
        a = s["angle_to_mean_median_deg"]
        bx.errorbar(s["train_cpu_s"], a["mean"], yerr=a["std"], fmt="o", capsize=4)
        bx.annotate(r["label"], (s["train_cpu_s"], a["mean"]), fontsize=7,
                    textcoords="offset points", xytext=(4, 4))
    for r in rows:
        if r["kind"] == "reference":
            bx.axhline(r["summary"]["angle_to_mean_median_deg"]["mean"], ls="--", lw=1,
                       color="grey")
            bx.annotate(r["label"], (bx.get_xlim()[0], r["summary"]["angle_to_mean_median_deg"]
                                     ["mean"]), fontsize=7, color="grey")
    bx.set_xscale("log")
    bx.set_xlabel("training CPU seconds (2 cores)")
    bx.set_ylabel("median angle to the cone mean (deg, index)")
    bx.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def replay(args: argparse.Namespace) -> dict:
    """Train and score everything (resuming), rewriting the results after each run."""
    work = Path(args.work)
    data = dataset(args)
    tables = open_tables(data)
    counts = {s: len(tables.rows(s)) for s in ("train", "val", "test")}
    frac = train_fraction(tables, args.n_train)
    print(f"dataset {data}: {counts}; training on {args.n_train} (fraction {frac:.4f})",
          flush=True)
    refs = [{"label": e["label"], "kind": "reference",
             "summary": {"n_seeds": 1, **{k: {"mean": e["metrics"]["index"][k], "std": 0.0}
                                         for k in (*STUDY_KEYS, "angle_to_mean_median_deg")}}}
            for e in [*reference_entries(data, ("index",)),
                      {"label": "constant (mean training label)",
                       "metrics": {"index": constant_predictor(tables)}}]]
    study_common = {"train_fraction": frac, "epochs": args.epochs,
                    "n_rotations": args.n_rotations, "cache_dir": str(work / "cache")}
    arms = [(m, "study", {"model": m, **study_common}) for m in args.models]
    if args.default_recipe:
        arms.append(("default", "default", {"train_fraction": frac,
                                            "cache_dir": str(work / "cache")}))
    done: dict[str, list[dict]] = {a[0]: [] for a in arms}
    result: dict = {}

    def write() -> None:
        rows = []
        for name, protocol, _ in arms:
            label = (model_info(name, 1, 2).get("display", name) if protocol == "study"
                     else "default recipe (pinch view)")
            if done[name]:
                rows.append({"label": f"{label}, twin", "kind": "model", "name": name,
                             "protocol": protocol, "summary": summarise(done[name]),
                             "runs": done[name]})
            if name in STUDY_ROWS:
                rows.append({"label": f"{label}, the study (real)", "kind": "study",
                             "name": name, "summary": dict(zip(STUDY_KEYS, STUDY_ROWS[name],
                                                               strict=True))})
        rows += refs
        note = (f"Index finger. Twin: `{Path(args.scene).relative_to(REPO)}`, "
                f"{args.n} configurations of {args.n_objects} procedural objects split by "
                f"object ({counts['train']} / {counts['val']} / {counts['test']}); trained on "
                f"{args.n_train} training configurations x {args.n_rotations} rotations, "
                f"{args.epochs} epochs (default recipe: its own 25 epochs, both fingers, the "
                "index shown), the epoch chosen on the validation split, scored once on the "
                f"{counts['test']} test configurations (study protocol: x {args.n_rotations} "
                "rotations). Mean ± std over seeds; the spread column: 5-95 % of % correct y and "
                f"% in cone over {args.resamples} test splits of {args.test_size} configurations "
                "resampled from each run's, averaged over seeds. Noise floor and pinch baseline "
                "on the unrotated test images. Training CPU seconds: user + system, 2 cores.")
        result.update({"provenance": provenance([data]), "dataset": str(data),
                       "split_counts": counts, "settings": vars(args),
                       "rows": rows, "table": table(rows, note)})
        out = Path(args.results)
        out.mkdir(parents=True, exist_ok=True)
        (out / f"{args.name}.json").write_text(json.dumps(result, indent=2) + "\n")
        (out / f"{args.name}.md").write_text(f"# The study's table, replayed in simulation\n\n"
                                             f"{result['table']}\n")
        plot(rows, out / f"{args.name}.png")

    for seed in args.seeds:
        for name, protocol, changes in arms:
            t0 = time.perf_counter()
            e = run_entry(data, work, f"{name} seed {seed}", protocol=protocol, seed=seed,
                          progress=not args.quiet, **changes)
            e["seed"] = seed
            e["resampled_34"] = resampled(tables, e["run"], args.test_size, args.resamples,
                                          seed)
            done[name].append(e)
            print(f"== {name} seed {seed}: {time.perf_counter() - t0:.0f} s", flush=True)
            write()
    print(result["table"], flush=True)
    return result


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--work", default=str(REPO / "runs" / "study_replay"),
                   help="folder of the dataset and the runs (kept for resuming)")
    p.add_argument("--results", default=str(RESULTS), help="where <name>.json|md|png go")
    p.add_argument("--name", default="study_replay", help="results file name")
    p.add_argument("--scene", default=str(SCENE), help="the twin's scene file")
    p.add_argument("--n", type=int, default=1300, help="configurations generated")
    p.add_argument("--n-objects", type=int, default=64, help="procedural objects")
    p.add_argument("--split", type=float, nargs=3, default=[0.42, 0.06, 0.52],
                   help="train / val / test fractions of the objects")
    p.add_argument("--data-seed", type=int, default=0, help="the dataset's seed")
    add_grasp_options(p)
    p.add_argument("--n-train", type=int, default=162, help="training configurations used")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="training seeds")
    p.add_argument("--models", nargs="+", default=["schoeconv100-v3-fc160", "smallconv"])
    p.add_argument("--no-default-recipe", dest="default_recipe", action="store_false",
                   help="leave the project's default recipe out")
    p.add_argument("--epochs", type=int, default=20, help="study protocol epochs")
    p.add_argument("--n-rotations", type=int, default=20, help="study protocol rotations")
    p.add_argument("--test-size", type=int, default=34, help="resampled test split size")
    p.add_argument("--resamples", type=int, default=1000, help="resampled test splits")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    args = p.parse_args(argv)
    replay(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
