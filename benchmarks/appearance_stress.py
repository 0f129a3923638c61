"""Appearance stress test (ImageNet-C for this task): predictors scored on test images perturbed
toward photographs, one axis at a time and all at once.

Every test image of the dataset is perturbed (`vistac_learn.data.perturb`, drawn from
(seed, row, perturbation)); each predictor sees the perturbed images only (a trained run finds
its fingertips in them with the locator, as on real photographs) and is scored against the
unchanged labels: median angle to the cone mean per finger, its degradation over the clean
images, and how many fingers the locator lost. Predictors are listed in `PREDICTORS` (a name
and a factory), so adding one (e.g. the pinch baseline) is one line.

``--photo-data P``: the same configurations rendered with ``--preset photo`` (same seed and
settings, hence identical labels; checked); adds the images row ``photo preset`` (P's test
images, scored against the same labels).

Runs: ``--run LABEL=FOLDER`` (repeatable) scores existing runs; without it, small default-recipe
runs are trained into ``--out`` with ``--epochs`` epochs: on the dataset with and without
train-time appearance augmentation (``--appearance A`` and ``0``) and, given ``--photo-data``,
one on the photo dataset. Without ``--data``, 1000 configurations are made in ``--out`` (and,
with ``--photo``, their photo twin).

Writes ``appearance_stress.md`` / ``.json`` and ``appearance_stress.png`` (degradation per axis
and finger, one panel per predictor) into ``--results``.

Usage:
    python benchmarks/appearance_stress.py --out bench/stress --results benchmarks/results
    python benchmarks/appearance_stress.py --data D --run clean=runs/r1 --run aug=runs/r2
    python benchmarks/appearance_stress.py --out bench/stress_photo --photo   # all made here

The committed ``benchmarks/results/appearance_stress.*``: D is ``vistac generate --n 3000
--noise 0.05 --seed 21 --split-by object``, D_PHOTO the same with ``--preset photo``; R is
``vistac train --data D --out R --finger both`` (the default recipe, seed 0; R1 the same with
``--seed 1``), R_PHOTO ``vistac train --data D_PHOTO --out R_PHOTO --finger both
--max-missing-pct 10``:

    python benchmarks/appearance_stress.py --data D --photo-data D_PHOTO \
        --run "default (--appearance 0.5), seed 0=R" \
        --run "trained on photo (+ --appearance 0.5)=R_PHOTO" --true-tips
    python benchmarks/appearance_stress.py --data D --photo-data D_PHOTO \
        --run "default (--appearance 0.5), seed 1=R1" --images all --no-baselines \
        --name appearance_stress_seed1
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from learnbench import ensure_dataset, headline_data, run_entry, save, slug

from vistac.dataset import FINGERS, DatasetTables, open_tables
from vistac.errors import UserError
from vistac_learn.data.fingertip_table import (
    FingertipTable,
    fingertip_table,
    located_in,
    record,
)
from vistac_learn.data.fingertips import Fingertip
from vistac_learn.data.perturb import PERTURBATIONS, Scene, perturb, segment
from vistac_learn.data.samples import SampleSet, SampleSpec, moved_fingertip
from vistac_learn.data.tip_coverage import MAX_MISSING_PCT
from vistac_learn.data.variants import read_rgb
from vistac_learn.evaluate.geometric import GeometricCfg, predict_image
from vistac_learn.evaluate.pinch import PinchCfg, dataset_friction
from vistac_learn.evaluate.pinch import predict_image as pinch_image
from vistac_learn.evaluate.run import load_model, load_run
from vistac_learn.metrics.scoring import predict, predict_mirror_averaged, score
from vistac_learn.train.build import build_view, input_size, resolve_device

# A predictor maps (dataset, rows, their images, the homographies from the clean renders to
# them or None) to (len(rows), 4) predictions, index then thumb (r_y, r_z), and the number of
# fingers it could not find; or to None where it cannot score those images.
Predictor = Callable[[DatasetTables, np.ndarray, list[np.ndarray], list[np.ndarray] | None],
                     tuple[np.ndarray, int] | None]


def true_tips(tables: DatasetTables, rows: np.ndarray, homs: list[np.ndarray]
              ) -> FingertipTable:
    """What a perfect locator would give on perturbed images: the fingertips located in the
    clean renders (within 2 px / 3 deg of the simulator's on every clean test image), moved by
    each image's homography."""
    clean = fingertip_table(tables)
    by_row = {int(r): h for r, h in zip(rows, homs, strict=True)}
    cids = tables.configs["config_id"].to_numpy()
    return FingertipTable(pd.DataFrame([
        record(int(cids[r]), {f: moved_fingertip(clean.get(r, f), by_row[r]) if r in by_row
                              else Fingertip.missing("not scored") for f in FINGERS})
        for r in range(len(tables.configs))]))


def run_predictor(run: Path, oracle: bool = False) -> Predictor:
    """A trained run (both fingers) that finds its fingertips in the images it is given,
    scored as `vistac evaluate` scores it (with its mirrored view averaged in when the run's
    recipe says so, `TrainCfg.tta`). `oracle`: given the true fingertips instead (`true_tips`;
    only for images made from the clean renders by a known homography)."""
    cfg, _ = load_run(run)
    if cfg.finger != "both":
        raise UserError(f"{run}: trained on --finger {cfg.finger}; the stress test needs both")
    dev = resolve_device("cpu")
    model, _ = load_model(run, cfg, "best", dev)
    size = input_size(cfg, model)
    view = build_view(cfg)

    def predict_rows(tables, rows, images, homs):
        if oracle and homs is None:
            return None
        by_row = dict(zip((int(r) for r in rows), images, strict=True))
        tips = None
        if view.needs_tips:
            tips = true_tips(tables, rows, homs) if oracle else located_in(tables, rows, images)
        def samples(mirror: bool) -> SampleSet:
            spec = SampleSpec(view, size, FINGERS, "mean", cfg.seed, cfg.rotation_cfg(),
                              mirror=mirror)
            return SampleSet(tables, rows, spec, tips, images=lambda r: by_row[int(r)])

        # the recipe's test-time augmentation, as `vistac evaluate` applies it
        pred = predict_mirror_averaged(model, samples, dev, cfg.eval_batch_size) if cfg.tta \
            else predict(model, samples(False), dev, cfg.eval_batch_size)
        lost = sum(tips.failures(rows, f) for f in FINGERS) if tips is not None else 0
        return pred, lost

    return predict_rows


def image_baseline(predict_one: Callable) -> Callable[[], Predictor]:
    """A non-learned baseline that works image by image, from the same fingertip locator:
    ``predict_one(img, colours, tables) -> ((2F,) prediction, fingers that fell back)``."""
    def make() -> Predictor:
        def predict_rows(tables, rows, images, homs):
            colours = {f: tables.finger_rgb(f) for f in FINGERS}
            out, lost = [], 0
            for img in images:
                p, fails = predict_one(img, colours, tables)
                out.append(p)
                lost += fails
            return np.stack(out), lost

        return predict_rows

    return make


# the surface-normal (geometric) baseline and the pinch baseline (closing axis, friction
# cone): as `vistac evaluate` runs it (flat renders by their colours, any other image through
# the learned segmenter), by colours alone, and always through the segmenter
geometric_predictor = image_baseline(
    lambda img, colours, tables: predict_image(img, colours, FINGERS, GeometricCfg()))


def pinch_predictor_of(cfg: PinchCfg) -> Callable[[], Predictor]:
    """The pinch baseline with these settings."""
    return image_baseline(lambda img, colours, tables: pinch_image(
        img, colours, FINGERS, dataset_friction(tables), cfg))


PINCH_BASELINES = {"pinch baseline": PinchCfg(),
                   "pinch baseline, colours only": PinchCfg(segmented=False),
                   "pinch baseline, segmented": PinchCfg(segmented=True)}


ORACLE = ", true fingertips"  # label suffix of a run given the true fingertips


def predictors(runs: dict[str, Path], baselines: bool = True, oracle: bool = False
               ) -> dict[str, Callable[[], Predictor]]:
    """Every predictor to score, by label (factories, built once); `oracle`: each run also
    with the true fingertips (`true_tips`)."""
    out = {label: (lambda r=run: run_predictor(r)) for label, run in runs.items()}
    if oracle:
        out |= {label + ORACLE: (lambda r=run: run_predictor(r, oracle=True))
                for label, run in runs.items()}
    if baselines:
        out["geometric baseline"] = geometric_predictor
        out |= {label: pinch_predictor_of(cfg) for label, cfg in PINCH_BASELINES.items()}
    return out


PHOTO_PRESET = "photo preset"  # the images row of the photo-rendered twin dataset


def photo_twin(tables: DatasetTables, photo: Path) -> DatasetTables:
    """The dataset `photo` if it holds the configurations and labels of `tables`.

    Raises:
        UserError: other configurations or other labels.
    """
    twin = open_tables(photo)
    same = (len(twin.configs) == len(tables.configs)
            and twin.presses.equals(tables.presses)
            and all(np.array_equal(twin.rows(s), tables.rows(s)) for s in ("train", "test")))
    if not same:
        raise UserError(f"--photo-data {photo}: not the same configurations and labels as "
                        f"--data {tables.root} (make it with the same command and --preset photo)")
    return twin


def perturbed_images(tables: DatasetTables, rows: np.ndarray, name: str, seed: int,
                     photo: DatasetTables | None = None
                     ) -> tuple[list[np.ndarray], list[np.ndarray] | None]:
    """The test images under one perturbation (``clean``: as rendered; ``photo preset``:
    `photo`'s images of the same rows) and the homographies from the clean renders to them
    (None for the photo preset, a render of its own)."""
    if name == PHOTO_PRESET:
        return [read_rgb(photo.image_path(int(row))) for row in rows], None
    colours = {f: tables.finger_rgb(f) for f in FINGERS}
    k = (("clean", *PERTURBATIONS)).index(name)
    out, homs = [], []
    for row in rows:
        rgb = read_rgb(tables.image_path(int(row)))
        hom = np.eye(3)
        if name != "clean":
            scene = Scene(segment(rgb, colours, tables.table_rgb), colours)
            done = perturb(name, rgb, scene, np.random.default_rng([seed, int(row), k]))
            rgb, hom = done.rgb, done.homography
        out.append(rgb)
        homs.append(hom)
    return out, homs


def stress(tables: DatasetTables, rows: np.ndarray, preds: dict[str, Callable[[], Predictor]],
           names: tuple[str, ...], seed: int, photo: DatasetTables | None = None) -> dict:
    """Median angle to the cone mean per predictor, perturbation and finger."""
    built = {label: make() for label, make in preds.items()}
    res = {label: {} for label in built}
    item_row = np.asarray(rows)
    for name in names:
        t0 = time.perf_counter()
        images, homs = perturbed_images(tables, rows, name, seed, photo)
        for label, fn in built.items():
            got = fn(tables, rows, images, homs)
            if got is None:
                continue
            pred, lost = got
            sc = score(pred, tables, rows, item_row, FINGERS)
            res[label][name] = {f: float(sc[f]["angle_to_mean_median_deg"]) for f in FINGERS}
            res[label][name]["fingers_lost"] = int(lost)
        print(f"{name}: {time.perf_counter() - t0:.0f} s", flush=True)
    for per in res.values():
        for name in per:
            for f in FINGERS:
                per[name][f"{f}_delta"] = per[name][f] - per["clean"][f]
    return res


def markdown(res: dict, names: tuple[str, ...]) -> str:
    """One row per predictor and perturbation: angle (deg) and change over clean per finger."""
    head = ["predictor", "images", "index (deg)", "thumb (deg)", "index +-", "thumb +-",
            "fingers lost"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for label, per in res.items():
        for name in (n for n in names if n in per):
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
            ax.bar(x + (k - 0.5) * 0.38,
                   [per[n][f"{f}_delta"] if n in per else np.nan for n in axes_names], 0.38,
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
    ap.add_argument("--photo-data", type=Path, default=None,
                    help="the dataset's configurations rendered with --preset photo: adds the "
                    "'photo preset' images row (and, without --run, a run trained on it)")
    ap.add_argument("--photo", action="store_true",
                    help="without --data: also make the photo twin of the dataset made here")
    ap.add_argument("--run", action="append", default=[], metavar="LABEL=FOLDER",
                    help="a trained run to score (repeatable); default: train two")
    ap.add_argument("--epochs", type=int, default=8, help="epochs of the runs trained here")
    ap.add_argument("--appearance", type=float, default=0.5,
                    help="--appearance of the augmented run trained here")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--limit", type=int, default=0, help="score only the first N test "
                    "configurations (0: all; for a quick look)")
    ap.add_argument("--images", nargs="+", default=None, metavar="NAME",
                    help="image sets to score besides clean (default: every perturbation, and "
                    f"'{PHOTO_PRESET}' with --photo-data)")
    ap.add_argument("--no-baselines", action="store_true",
                    help="score the runs only, not the geometric and pinch baselines")
    ap.add_argument("--add", type=Path, action="append", default=[], metavar="JSON",
                    help="results (.json) of an earlier invocation on the same test images: "
                    "its predictors join the table (split a long benchmark into parts)")
    ap.add_argument("--name", default="appearance_stress")
    ap.add_argument("--true-tips", action="store_true", help="also score each run given the "
                    "true fingertips (those of the clean render moved by the perturbation's "
                    "homography): what is the locator's and what the model's")
    ap.add_argument("--baselines-only", action="store_true", help="score the image-only "
                    "baselines alone (no run trained or scored)")
    a = ap.parse_args()
    data = a.data or ensure_dataset(a.out / "data" / "d1000", headline_data(1000, seed=21))
    photo_data = a.photo_data
    if photo_data is None and a.photo and a.data is None:
        photo_data = ensure_dataset(a.out / "data" / "d1000-photo",
                                    headline_data(1000, seed=21, preset="photo"))
    runs = {}
    for spec in a.run:
        label, _, folder = spec.partition("=")
        if not folder:
            raise SystemExit(f"--run {spec!r}: expected LABEL=FOLDER")
        runs[label] = Path(folder)
    train_s = {}
    if not runs and not a.baselines_only:
        todo = [(f"default, {a.epochs} epochs", data, 0.0),
                (f"default + appearance {a.appearance:g}, {a.epochs} epochs", data,
                 a.appearance)]
        if photo_data is not None:
            todo.append((f"default, trained on photo, {a.epochs} epochs", photo_data, 0.0))
        for label, on, app in todo:
            t0 = time.perf_counter()
            # photographs: the locator loses a few % of the fingertips (default limit 1 %)
            run_entry(on, a.out, label, "default", False, finger="both", epochs=a.epochs,
                      appearance=app, max_missing_pct=10.0 if on == photo_data else MAX_MISSING_PCT)
            runs[label] = a.out / "runs" / slug(label)
            train_s[label] = time.perf_counter() - t0
    tables = open_tables(data)
    rows = tables.rows("test")
    if a.limit:
        rows = rows[:a.limit]
    photo = photo_twin(tables, photo_data) if photo_data is not None else None
    every = ("clean", *PERTURBATIONS, *((PHOTO_PRESET,) if photo is not None else ()))
    unknown = sorted(set(a.images or ()) - set(every))
    if unknown:
        raise UserError(f"--images: unknown {', '.join(unknown)}; choose from "
                        f"{', '.join(every)}")
    names = every if a.images is None else ("clean", *(n for n in every[1:] if n in a.images))
    t0 = time.perf_counter()
    res = stress(tables, rows, predictors(runs, not a.no_baselines, a.true_tips), names, a.seed,
                 photo)
    cfgs = {label: dataclasses.asdict(load_run(run)[0]) for label, run in runs.items()}
    for path in a.add:
        earlier = json.loads(path.read_text())
        if (earlier["data"], earlier["n_test_configs"], earlier["seed"]) != (
                str(data), int(len(rows)), a.seed):
            raise UserError(f"--add {path}: scored on other images (data, test rows or seed)")
        res.update(earlier["results"])
        cfgs.update(earlier["run_configs"])
        runs.update({k: Path(v) for k, v in earlier["runs"].items()})
    res = dict(sorted(res.items(), key=lambda kv: kv[0] not in cfgs))  # runs, then baselines
    names = tuple(n for n in every if any(n in per for per in res.values()))
    result = {"data": str(data), "photo_data": str(photo_data) if photo_data else None,
              "n_test_configs": int(len(rows)), "seed": a.seed,
              "runs": {k: str(v) for k, v in runs.items()}, "run_configs": cfgs,
              "train_wall_s": train_s, "stress_wall_s": time.perf_counter() - t0,
              "results": res}
    md = (f"Appearance stress on the test split of {data} ({len(rows)} configurations of "
          "held-out objects); median angle to the cone mean (deg) and its change over clean "
          f"images; perturbations drawn from seed {a.seed}. Runs: "
          + "; ".join(f"{k}: trained on {cfgs[k]['data']}, {cfgs[k]['epochs']} epochs, "
                      f"appearance {cfgs[k]['appearance']}"
                      for k in runs) + "."
          + (f" Row `{PHOTO_PRESET}`: the same test configurations rendered with "
             f"`--preset photo` ({photo_data})." if photo is not None else "")
          + "\n\n" + markdown(res, names))
    a.results.mkdir(parents=True, exist_ok=True)
    plot(res, names, a.results / f"{a.name}.png")
    save(a.results, a.name, result, md, datasets=(data, photo_data))


if __name__ == "__main__":
    main()
