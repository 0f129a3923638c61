"""Appearance stress test (ImageNet-C for this task): predictors scored on test images perturbed
toward photographs, one axis at a time and all at once.

Every test image of the dataset is perturbed (`vistac_learn.data.perturb`, drawn from
(seed, row, perturbation)); each predictor sees the perturbed images only (a trained run finds
its fingertips in them with the locator, as on real photographs) and is scored against the
unchanged labels: median angle to the cone mean per finger, its degradation over the clean
images, and how many fingers the locator lost. Predictors are listed in `PREDICTORS` (a name
and a factory), so adding one (e.g. the pinch baseline) is one line.

Runs: ``--run LABEL=FOLDER`` (repeatable) scores existing runs; without it, two small default-
recipe runs are trained into ``--out`` on the dataset, identical but for train-time appearance
augmentation (``--appearance 0`` and ``--appearance A``), with ``--epochs`` epochs.

Writes ``appearance_stress.md`` / ``.json`` and ``appearance_stress.png`` (degradation per axis
and finger, one panel per predictor) into ``--results``.

Usage:
    python benchmarks/appearance_stress.py --out bench/stress --results benchmarks/results
    python benchmarks/appearance_stress.py --data D --run clean=runs/r1 --run aug=runs/r2
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from learnbench import ensure_dataset, machine, run_entry, save, slug  # noqa: E402

from vistac.dataset import FINGERS, DatasetTables, open_dataset  # noqa: E402
from vistac.errors import UserError  # noqa: E402
from vistac_learn.data.fingertips import located_in  # noqa: E402
from vistac_learn.data.perturb import PERTURBATIONS, Scene, perturb, segment  # noqa: E402
from vistac_learn.data.samples import SampleSet  # noqa: E402
from vistac_learn.data.variants import read_rgb  # noqa: E402
from vistac_learn.evaluate.geometric import GeometricCfg, predict_image  # noqa: E402
from vistac_learn.evaluate.pinch import dataset_friction  # noqa: E402
from vistac_learn.evaluate.pinch import predict_image as pinch_image  # noqa: E402
from vistac_learn.evaluate.run import load_model, load_run  # noqa: E402
from vistac_learn.metrics.scoring import predict, score  # noqa: E402
from vistac_learn.train.config import build_view, input_size, resolve_device  # noqa: E402

# A predictor maps (dataset, rows, their images) to (len(rows), 4) predictions, index then
# thumb (r_y, r_z), and the number of fingers it could not find.
Predictor = Callable[[DatasetTables, np.ndarray, list[np.ndarray]], tuple[np.ndarray, int]]


def run_predictor(run: Path) -> Predictor:
    """A trained run (both fingers) that finds its fingertips in the images it is given."""
    cfg, _ = load_run(run)
    if cfg.finger != "both":
        raise UserError(f"{run}: trained on --finger {cfg.finger}; the stress test needs both")
    dev = resolve_device("cpu")
    model, _ = load_model(run, cfg, "best", dev)
    size = input_size(cfg, model)
    view = build_view(cfg)

    def predict_rows(tables, rows, images):
        by_row = dict(zip((int(r) for r in rows), images, strict=True))
        tips = located_in(tables, rows, images) if view.needs_tips else None
        ds = SampleSet(tables, rows, view, size, FINGERS, "mean", cfg.seed, cfg.rotation_cfg(),
                       None, tips, images=lambda r: by_row[int(r)])
        pred = predict(model, ds, dev, cfg.eval_batch_size)
        lost = sum(tips.failures(rows, f) for f in FINGERS) if tips is not None else 0
        return pred, lost

    return predict_rows


def image_baseline(predict_one: Callable) -> Callable[[], Predictor]:
    """A non-learned baseline that works image by image, from the same fingertip locator:
    ``predict_one(img, colours, tables) -> ((2F,) prediction, fingers that fell back)``."""
    def make() -> Predictor:
        def predict_rows(tables, rows, images):
            colours = {f: tables.finger_rgb(f) for f in FINGERS}
            out, lost = [], 0
            for img in images:
                p, fails = predict_one(img, colours, tables)
                out.append(p)
                lost += fails
            return np.stack(out), lost

        return predict_rows

    return make


# the surface-normal (geometric) baseline and the pinch baseline (closing axis, friction cone)
geometric_predictor = image_baseline(
    lambda img, colours, tables: predict_image(img, colours, FINGERS, GeometricCfg()))
pinch_predictor = image_baseline(
    lambda img, colours, tables: pinch_image(img, colours, FINGERS, dataset_friction(tables)))


def predictors(runs: dict[str, Path]) -> dict[str, Callable[[], Predictor]]:
    """Every predictor to score, by label (factories, built once)."""
    out = {label: (lambda r=run: run_predictor(r)) for label, run in runs.items()}
    out["geometric baseline"] = geometric_predictor
    out["pinch baseline"] = pinch_predictor
    return out


def perturbed_images(tables: DatasetTables, rows: np.ndarray, name: str, seed: int
                     ) -> list[np.ndarray]:
    """The test images under one perturbation (``clean``: as rendered)."""
    colours = {f: tables.finger_rgb(f) for f in FINGERS}
    k = (("clean", *PERTURBATIONS)).index(name)
    out = []
    for row in rows:
        rgb = read_rgb(tables.image_path(int(row)))
        if name != "clean":
            scene = Scene(segment(rgb, colours, tables.table_rgb), colours)
            rgb = perturb(name, rgb, scene, np.random.default_rng([seed, int(row), k])).rgb
        out.append(rgb)
    return out


def stress(tables: DatasetTables, rows: np.ndarray, preds: dict[str, Callable[[], Predictor]],
           names: tuple[str, ...], seed: int) -> dict:
    """Median angle to the cone mean per predictor, perturbation and finger."""
    built = {label: make() for label, make in preds.items()}
    res = {label: {} for label in built}
    item_row = np.asarray(rows)
    for name in names:
        t0 = time.perf_counter()
        images = perturbed_images(tables, rows, name, seed)
        for label, fn in built.items():
            pred, lost = fn(tables, rows, images)
            sc = score(pred, tables, rows, item_row, FINGERS)
            res[label][name] = {f: float(sc[f]["angle_to_mean_median_deg"]) for f in FINGERS}
            res[label][name]["fingers_lost"] = int(lost)
        print(f"{name}: {time.perf_counter() - t0:.0f} s", flush=True)
    for per in res.values():
        for name in names:
            for f in FINGERS:
                per[name][f"{f}_delta"] = per[name][f] - per["clean"][f]
    return res


def markdown(res: dict, names: tuple[str, ...]) -> str:
    """One row per predictor and perturbation: angle (deg) and change over clean per finger."""
    head = ["predictor", "images", "index (deg)", "thumb (deg)", "index +-", "thumb +-",
            "fingers lost"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for label, per in res.items():
        for name in names:
            m = per[name]
            lines.append("| " + " | ".join([
                label, name, f"{m['index']:.2f}", f"{m['thumb']:.2f}",
                "" if name == "clean" else f"{m['index_delta']:+.2f}",
                "" if name == "clean" else f"{m['thumb_delta']:+.2f}",
                str(m["fingers_lost"])]) + " |")
    return "\n".join(lines)


def plot(res: dict, names: tuple[str, ...], path: Path) -> None:
    """Degradation (deg over clean) per perturbation and finger, one panel per predictor."""
    axes_names = [n for n in names if n != "clean"]
    fig, axs = plt.subplots(1, len(res), figsize=(4.2 * len(res), 3.6), sharey=True,
                            squeeze=False)
    x = np.arange(len(axes_names))
    for ax, (label, per) in zip(axs[0], res.items(), strict=True):
        for k, f in enumerate(FINGERS):
            ax.bar(x + (k - 0.5) * 0.38, [per[n][f"{f}_delta"] for n in axes_names], 0.38,
                   label=f)
        ax.axhline(0, color="k", lw=0.6)
        ax.set_xticks(x, axes_names, rotation=40, ha="right")
        clean = per["clean"]
        ax.set_title(f"{label}\nclean {clean['index']:.2f} / {clean['thumb']:.2f} deg",
                     fontsize=9)
    axs[0][0].set_ylabel("median angle to cone mean,\nchange over clean (deg)")
    axs[0][0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("bench/stress"),
                    help="work folder (dataset, trained runs)")
    ap.add_argument("--results", type=Path, default=Path("benchmarks/results"))
    ap.add_argument("--data", type=Path, default=None,
                    help="dataset (default: 1000 configurations made in --out)")
    ap.add_argument("--run", action="append", default=[], metavar="LABEL=FOLDER",
                    help="a trained run to score (repeatable); default: train two")
    ap.add_argument("--epochs", type=int, default=8, help="epochs of the runs trained here")
    ap.add_argument("--appearance", type=float, default=0.5,
                    help="--appearance of the augmented run trained here")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--limit", type=int, default=0, help="score only the first N test "
                    "configurations (0: all; for a quick look)")
    ap.add_argument("--name", default="appearance_stress")
    a = ap.parse_args()
    data = a.data or ensure_dataset(a.out / "data" / "d1000", "--n", "1000", "--noise", "0.05",
                                    "--seed", "21", "--split-by", "object")
    runs = {}
    for spec in a.run:
        label, _, folder = spec.partition("=")
        if not folder:
            raise SystemExit(f"--run {spec!r}: expected LABEL=FOLDER")
        runs[label] = Path(folder)
    train_s = {}
    if not runs:
        for label, app in ((f"default, {a.epochs} epochs", 0.0),
                           (f"default + appearance {a.appearance:g}, {a.epochs} epochs",
                            a.appearance)):
            t0 = time.perf_counter()
            run_entry(data, a.out, label, "default", False, finger="both", epochs=a.epochs,
                      appearance=app)
            runs[label] = a.out / "runs" / slug(label)
            train_s[label] = time.perf_counter() - t0
    tables = open_dataset(data)
    rows = tables.rows("test")
    if a.limit:
        rows = rows[:a.limit]
    names = ("clean", *PERTURBATIONS)
    t0 = time.perf_counter()
    res = stress(tables, rows, predictors(runs), names, a.seed)
    cfgs = {label: dataclasses.asdict(load_run(run)[0]) for label, run in runs.items()}
    result = {"data": str(data), "n_test_configs": int(len(rows)), "seed": a.seed,
              "runs": {k: str(v) for k, v in runs.items()}, "run_configs": cfgs,
              "train_wall_s": train_s, "stress_wall_s": time.perf_counter() - t0,
              "machine": machine(), "results": res}
    md = (f"Appearance stress on the test split of {data} ({len(rows)} configurations of "
          "held-out objects); median angle to the cone mean (deg) and its change over clean "
          f"images; perturbations drawn from seed {a.seed}. Runs: "
          + "; ".join(f"{k}: {cfgs[k]['epochs']} epochs, appearance {cfgs[k]['appearance']}"
                      for k in runs) + ".\n\n" + markdown(res, names))
    a.results.mkdir(parents=True, exist_ok=True)
    plot(res, names, a.results / f"{a.name}.png")
    save(a.results, a.name, result, md)


if __name__ == "__main__":
    main()
