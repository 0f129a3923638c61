"""Contact targets on photo renders: what they change, and where the rest of the error goes.

Since the one projection (`vistac.projection`, issue 30), the simulator's contact points,
normals and finger axes are known on every ``--preset photo`` image (before, the learner's
`contact_truth` dropped them for any tilted, rolled or perspective camera, i.e. for every photo
image), so the default recipe trained on photo renders learns them as auxiliary targets. This
script trains that run (the default recipe, no option) and scores it on the held-out test
configurations:

1. with `vistac evaluate` (the recipe's mirrored view averaged in) on the photo renders and on
   the clean renders of the same configurations (``--score NAME=DATA``, the test split of each;
   by default the training data's as "photo renders"), beside the run trained before without
   the targets (issue 30: 1.72 / 2.01 deg on photo renders, 1.74 / 1.86 on clean ones);
2. where the rest goes on the photo renders (`pinch_diagnosis.diagnose`, no mirrored view): the
   label composed from the model's geometry in crops around the located fingertips, then
   around the simulator's fingertips as drawn (`simulator_fingertips`: a perfect locator), then
   with the simulator's contact points swapped in, then with all of the simulator's geometry
   (contact points, normals, crop tilts: the composition's floor). The steps' differences are
   the locator's share, the contact points' share and the rest of the model's.

Before any of it, without a model: the simulator's contact points, normals and finger axes of
the photo test split composed into the label through crops around the simulator's fingertips
(`pinch_prior.composed`, `simulator_fingertips`), beside the noise floor: that the new targets
are right on photo images; and, once a training has cached them, the located fingertips
against the simulator's: the locator's accuracy.

Each step is skipped when its output is there: rerun the same command to resume (datasets,
training, scores). ``--no-train`` stops before training when the run is not finished (on a
machine too busy to train) and writes what it has.

Usage (D_PHOTO: ``vistac generate --n 3000 --noise 0.05 --seed 21 --split-by object --preset
photo``, made here when missing; D the same without ``--preset``; R is ``vistac train --data
D_PHOTO --out R``, trained here when missing or unfinished):

    python benchmarks/photo_aux.py --photo-data D_PHOTO --run R --score "clean renders=D"
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from learnbench import cpu_s, ensure_dataset, headline_data, save, slug
from pinch_diagnosis import diagnose
from pinch_prior import composed

import vistac
from vistac.dataset import FINGERS, open_tables, unit_labels
from vistac.dataset.schema import clean_force_columns
from vistac_learn.data.fingertip_table import (
    FingertipTable,
    fingertip_table,
    simulator_fingertips,
)
from vistac_learn.evaluate.config import EvaluateCfg
from vistac_learn.evaluate.references import LABELS
from vistac_learn.evaluate.run import evaluate_run
from vistac_learn.metrics.scoring import score

METRIC = "angle_to_mean_median_deg"
BEFORE = {"photo renders": {"index": 1.72, "thumb": 2.01},  # issue 30: the same recipe and
          "clean renders": {"index": 1.74, "thumb": 1.86}}  # data, without the contact targets
CLEAN_DEFAULT = {"index": 1.06, "thumb": 1.11}  # issue 30: the clean-trained default, clean


def finished(run: Path) -> bool:
    """Whether `run` has trained every epoch of the default recipe."""
    done = run / "metrics.csv"
    return done.exists() and len(done.read_text().strip().splitlines()) - 1 >= \
        vistac.TrainCfg().epochs


def cached_tips(photo: Path) -> FingertipTable | None:
    """The dataset's located fingertips when a training has cached them, else None (locating
    3000 photo images costs about 1100 CPU s)."""
    if not any((photo / "cache").glob("fingertips-*.parquet")):
        return None
    return fingertip_table(open_tables(photo))


def prior(photo: Path) -> dict:
    """Median angles of the simulator's geometry composed into the label through crops around
    the simulator's fingertips (`simulator_fingertips`) of the photo test split, and of the
    noise floor (no model, no locator)."""
    t = open_tables(photo)
    tips = simulator_fingertips(t, int(t.render["image_size"]))
    rows = t.rows("test")
    floor = np.concatenate([unit_labels(t.configs[clean_force_columns(f)].to_numpy(float))
                            for f in FINGERS], axis=1)[rows]
    kept = ("simulator contacts, normals, finger axes", "... no friction clamp")
    entries = {"noise floor (noise-free force)": floor,
               **{k: v for k, v in composed(photo, tips=tips).items() if k in kept}}
    out = {}
    for name, pred in entries.items():
        m = score(pred, t, rows, rows, FINGERS)
        out[name] = {f: float(m[f][METRIC]) for f in FINGERS}
    return out


def locator_errors(photo: Path, found: FingertipTable) -> dict:
    """Per finger, on the photo test split: the located fingertips against the simulator's as
    drawn (`simulator_fingertips`): tip distance (px) median and 90th percentile, share within
    2 px and 3 deg, fingers not found."""
    t = open_tables(photo)
    rows = t.rows("test")
    truth = simulator_fingertips(t, int(t.render["image_size"]))
    out = {}
    for f in FINGERS:
        got = [found.get(int(r), f) for r in rows]
        want = [truth.get(int(r), f) for r in rows]
        ok = np.array([g.ok for g in got])
        dist = np.array([np.hypot(*(g.tip - w.tip)) for g, w in zip(got, want, strict=True)])
        turn = np.degrees(np.arccos(np.clip([g.axis @ w.axis for g, w in
                                             zip(got, want, strict=True)], -1.0, 1.0)))
        good = ok & (dist < 2.0) & (turn < 3.0)
        out[f] = {"tip_px_median": float(np.median(dist[ok])),
                  "tip_px_p90": float(np.percentile(dist[ok], 90)),
                  "within_2px_3deg_pct": float(100 * good.mean()), "not_found": int((~ok).sum())}
    return out


def trained(data: Path, run: Path) -> dict:
    """Train the default recipe on `data` into `run` unless finished (resumed if unfinished);
    the seconds this call spent (none when nothing was left to train)."""
    if finished(run):
        return {}
    t0, c0 = time.perf_counter(), cpu_s()
    vistac.train(vistac.TrainCfg(), data=data, out=run,
                 resume=(run / "checkpoints" / "last.pt").exists())
    return {"wall_s": time.perf_counter() - t0, "cpu_s": cpu_s() - c0}


def scored(run: Path, data: Path, name: str) -> dict:
    """`vistac evaluate --run RUN --data DATA` (cached under the run's ``eval/NAME``)."""
    out = run / "eval" / name
    path, best = out / "metrics.json", run / "checkpoints" / "best.pt"
    if path.exists() and path.stat().st_mtime > best.stat().st_mtime:
        return json.loads(path.read_text())
    return evaluate_run(EvaluateCfg(run=str(run), data=str(data), no_plots=True, device="cpu",
                                    cross_dataset=True), out)


def split_of_the_rest(run: Path, photo: Path) -> dict:
    """Composed-label medians per finger: the model around located and around true fingertips,
    with the simulator's contact points, with all of its geometry (test split)."""
    t = open_tables(photo)
    located = diagnose(run, "test")
    true = diagnose(run, "test", tips=simulator_fingertips(t, int(t.render["image_size"])))
    angles = {"located fingertips, model": located[METRIC]["model"]}
    for name, v in true[METRIC].items():
        angles[f"true fingertips, {name}"] = v
    return {"angles": angles, "median_error": {"located fingertips": located["median_error"],
                                               "true fingertips": true["median_error"]}}


def _cells(v: dict) -> str:
    return " | ".join(f"{v[f]:.2f}" for f in FINGERS)


def markdown(res: dict) -> str:
    lines = ["The simulator's geometry of the photo test split composed into the label through "
             "crops around the simulator's fingertips, no model, no locator "
             "(`pinch_prior.composed`); median angle to the cone mean:", "",
             "| geometry composed into the label | index | thumb |", "|---|---|---|"]
    lines += [f"| {name} | {_cells(v)} |" for name, v in res["prior"].items()]
    if res["locator"] is None:
        lines += ["", "The located fingertips: not measured yet (no fingertip table cached)."]
    else:
        lines += ["", "The located fingertips of the photo test split against the simulator's "
                  "as drawn:", "", "| finger | tip median (px) | tip 90th pct (px) | within "
                  "2 px and 3 deg (%) | not found |", "|---|---|---|---|---|"]
        lines += [f"| {f} | {e['tip_px_median']:.2f} | {e['tip_px_p90']:.2f} | "
                  f"{e['within_2px_3deg_pct']:.1f} | {e['not_found']} |"
                  for f, e in res["locator"].items()]
    if "evaluate" not in res:
        return "\n".join([*lines, "", f"Not measured yet: {res['pending']}"])
    ev = res["evaluate"]
    lines += ["", "Default recipe trained on `photo` renders, now with the contact targets; "
             "median angle to the cone mean over the held-out test configurations "
             f"({ev['photo renders']['n_configs']} each), `vistac evaluate` (mirrored view "
             "averaged in):", "",
             "| scored on | with contact targets: index | thumb | without (issue 30): index "
             "| thumb |", "|---|---|---|---|---|"]
    for name, e in ev.items():
        m = {f: e["metrics"][f][METRIC] for f in FINGERS}
        before = next((_cells(v) for k, v in BEFORE.items() if name.startswith(k)), "- | -")
        lines.append(f"| {name} | {_cells(m)} | {before} |")
    refs = ev["photo renders"].get("references") or {}
    for key, r in refs.items():
        lines.append(f"| photo renders, {LABELS.get(key, key)} | "
                     f"{_cells({f: r['metrics'][f][METRIC] for f in FINGERS})} | | |")
    floor = " / ".join(f"{CLEAN_DEFAULT[f]:.2f}" for f in FINGERS)
    lines += ["", f"(The clean-trained default on clean renders: {floor}.)", "",
              "Where the rest goes on the photo renders (best checkpoint, no mirrored view): "
              "the label composed from", "",
              "| geometry | index | thumb |", "|---|---|---|"]
    for name, v in res["rest"]["angles"].items():
        lines.append(f"| {name} | {_cells(v)} |")
    err = res["rest"]["median_error"]
    lines += ["", "Median errors of the model's parts (contact point in crop half-sides, tilt "
              "and normal in degrees):", "", "| crops around | finger | p | phi | normal |",
              "|---|---|---|---|---|"]
    for where, per in err.items():
        for f in FINGERS:
            e = per[f]
            lines.append(f"| {where} | {f} | {e['p_half_sides']:.3f} | {e['phi_deg']:.2f} | "
                         f"{e['normal_deg']:.2f} |")
    if res.get("training"):
        tr = res["training"]
        lines += ["", f"Training (this session): {tr['wall_s']:.0f} s wall, {tr['cpu_s']:.0f} "
                  "CPU s."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Command-line entry."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--photo-data", type=Path, required=True, help="the training data")
    ap.add_argument("--run", type=Path, required=True)
    ap.add_argument("--score", action="append", default=[], metavar="NAME=DATA",
                    help="also score on DATA's test split, as NAME (e.g. 'clean renders=D')")
    ap.add_argument("--no-train", action="store_true",
                    help="do not train: write what needs no finished run")
    ap.add_argument("--results", type=Path, default=Path(__file__).parent / "results")
    ap.add_argument("--name", default="photo_aux")
    a = ap.parse_args(argv)
    photo = ensure_dataset(a.photo_data, headline_data(3000, 21, "photo"))
    data = {"photo renders": photo} | {k: Path(v) for k, _, v in
                                       (s.partition("=") for s in a.score)}
    found = cached_tips(photo)
    res = {"run": str(a.run), "before": BEFORE, "prior": prior(photo),
           "locator": locator_errors(photo, found) if found is not None else None}
    if a.no_train and not finished(a.run):
        res["pending"] = (f"{a.run} is not trained to the end; the same command without "
                          "--no-train trains it (resuming) and scores it")
        save(a.results, a.name, res, markdown(res), datasets=[photo])
        return 0
    res |= {"training": trained(photo, a.run),
            "evaluate": {k: scored(a.run, d, f"test-{slug(k)}") for k, d in data.items()},
            "rest": split_of_the_rest(a.run, photo)}
    for k, ev in res["evaluate"].items():
        ev.pop("table", None)
        ev["dataset"] = str(data[k])
    save(a.results, a.name, res, markdown(res), datasets=list(data.values()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
